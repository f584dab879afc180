#pragma once
// What the libFuzzer targets of tests/fuzz share: splitting one input into several texts, and a
// private scratch folder for the readers that take paths.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace inertia::fuzz {

/// The input cut at each NUL byte: a target that reads several files gets them from one input
/// (the seeds are the files joined with NULs, so the fuzzer mutates each and their number).
inline std::vector<std::string_view> split_at_nul(const std::uint8_t* data, std::size_t size, std::size_t max_parts) {
  std::vector<std::string_view> parts;
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  std::size_t start = 0;
  while (parts.size() + 1 < max_parts) {
    const std::size_t nul = all.find('\0', start);
    if (nul == std::string_view::npos) break;
    parts.push_back(all.substr(start, nul - start));
    start = nul + 1;
  }
  parts.push_back(all.substr(start));
  return parts;
}

/// A folder of this process's own under $TMPDIR (or /tmp), made once and reused by every input:
/// readers of paths (dataset folders, event logs) get their bytes written there.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path d = std::filesystem::path(tmp != nullptr ? tmp : "/tmp") /
                              ("inertia-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

inline void write_file(const std::filesystem::path& file, std::string_view bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Removes the scratch folder when the fuzzer exits normally (-runs=N, -max_total_time).
struct ScratchCleanup {
  ~ScratchCleanup() {
    std::error_code ec;
    std::filesystem::remove_all(scratch_dir(), ec);
  }
};

}  // namespace inertia::fuzz
