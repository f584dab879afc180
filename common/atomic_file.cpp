#include "common/atomic_file.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <memory>
#include <system_error>

namespace inertia {

void write_file_atomically(const std::filesystem::path& file, std::string_view text) {
  std::filesystem::path temporary = file;
  temporary += fmt::format(".partial-{}", ::getpid());
  {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(temporary.c_str(), "wb"), &std::fclose);
    if (!f) throw std::system_error(errno, std::generic_category(), "cannot open " + temporary.string() + " for writing");
    if (std::fwrite(text.data(), 1, text.size(), f.get()) != text.size() || std::fflush(f.get()) != 0 ||
        ::fsync(::fileno(f.get())) != 0) {
      const int error = errno;
      f.reset();
      std::filesystem::remove(temporary);
      throw std::system_error(error, std::generic_category(), "cannot write " + temporary.string());
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    std::filesystem::remove(temporary);
    throw std::system_error(error, "cannot rename " + temporary.string() + " to " + file.string());
  }
}

}  // namespace inertia
