#include "common/atomic_file.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>

namespace inertia {

AtomicFileWriter::AtomicFileWriter(std::filesystem::path file)
    : file_(std::move(file)), temporary_(file_), stream_(nullptr, &std::fclose) {
  temporary_ += fmt::format(".partial-{}", ::getpid());
  stream_.reset(std::fopen(temporary_.c_str(), "wb"));
  if (!stream_) throw std::system_error(errno, std::generic_category(), "cannot open " + temporary_.string() + " for writing");
}

AtomicFileWriter::~AtomicFileWriter() {
  if (committed_) return;
  stream_.reset();
  std::error_code ignored;
  std::filesystem::remove(temporary_, ignored);
}

void AtomicFileWriter::append(std::string_view text) {
  if (std::fwrite(text.data(), 1, text.size(), stream_.get()) != text.size())
    throw std::system_error(errno, std::generic_category(), "cannot write " + temporary_.string());
}

void AtomicFileWriter::commit() {
  if (std::fflush(stream_.get()) != 0 || ::fsync(::fileno(stream_.get())) != 0)
    throw std::system_error(errno, std::generic_category(), "cannot write " + temporary_.string());
  if (std::fclose(stream_.release()) != 0) throw std::system_error(errno, std::generic_category(), "cannot write " + temporary_.string());
  std::error_code error;
  std::filesystem::rename(temporary_, file_, error);
  if (error) throw std::system_error(error, "cannot rename " + temporary_.string() + " to " + file_.string());
  committed_ = true;
}

void write_file_atomically(const std::filesystem::path& file, std::string_view text) {
  AtomicFileWriter writer(file);
  writer.append(text);
  writer.commit();
}

}  // namespace inertia
