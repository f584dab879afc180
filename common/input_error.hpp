#pragma once
// Bad input (a config, dataset or model file, a command-line value) is reported by throwing
// InputError; every verb's main turns it into a message on stderr and exit status 2.
#include <cstddef>
#include <stdexcept>
#include <string>

namespace inertia {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;

/// Where in a text file something is wrong. line and column are 1-based; 0 means unknown.
struct SourcePosition {
  std::string file;
  std::size_t line = 0;
  std::size_t column = 0;
};

class InputError : public std::runtime_error {
 public:
  /// what() reads "file:line:column: message" (parts that are unknown are left out).
  InputError(const SourcePosition& where, const std::string& message)
      : std::runtime_error(format(where, message)), where_(where) {}
  explicit InputError(const std::string& message) : std::runtime_error(message) {}

  [[nodiscard]] const SourcePosition& where() const noexcept { return where_; }

 private:
  static std::string format(const SourcePosition& where, const std::string& message) {
    std::string s = where.file;
    if (where.line > 0) s += ":" + std::to_string(where.line);
    if (where.line > 0 && where.column > 0) s += ":" + std::to_string(where.column);
    return s.empty() ? message : s + ": " + message;
  }
  SourcePosition where_;
};

}  // namespace inertia
