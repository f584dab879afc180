#pragma once
// What tests that run the real binaries read back: a file's whole text, and where the build put
// the analyzer.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace inertia::testing {

/// The whole text of `file` (empty when it cannot be read).
inline std::string text_of(const std::filesystem::path& file) {
  std::ifstream in(file);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

#ifdef INERTIA_BINARY_DIR
/// The inertia-analyze this build made.
inline std::string analyze_binary() { return (std::filesystem::path(INERTIA_BINARY_DIR) / "bin" / "inertia-analyze").string(); }
#endif

}  // namespace inertia::testing
