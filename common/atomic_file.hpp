#pragma once
// A file written whole or not at all: a reader, or a run killed part way, sees the old file or
// the new one, never a part.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string_view>

namespace inertia {

/// A file written piece by piece into a temporary file beside it (".partial-<pid>"), flushed to
/// the disk and renamed over the file by commit(). Not committed (an exception, a return), the
/// temporary file is removed; a run killed part way leaves only the temporary file. For outputs
/// that grow with the record, so that they never sit in memory whole.
class AtomicFileWriter {
 public:
  /// Throws std::system_error when the temporary file cannot be created.
  explicit AtomicFileWriter(std::filesystem::path file);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  /// Throws std::system_error on a write error (a full disk).
  void append(std::string_view text);
  /// Flushes to the disk and renames into place. Throws std::system_error on failure.
  void commit();

 private:
  std::filesystem::path file_, temporary_;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> stream_;
  bool committed_ = false;
};

/// Writes `text` whole with an AtomicFileWriter.
void write_file_atomically(const std::filesystem::path& file, std::string_view text);

}  // namespace inertia
