#pragma once
// A file written whole or not at all: a reader, or a run killed part way, sees the old file or
// the new one, never a part.
#include <filesystem>
#include <string_view>

namespace inertia {

/// Writes `text` into a temporary file beside `file` (".partial-<pid>"), flushes it to the disk,
/// then renames it over `file`. Throws std::system_error on I/O failure, after removing the
/// temporary file.
void write_file_atomically(const std::filesystem::path& file, std::string_view text);

}  // namespace inertia
