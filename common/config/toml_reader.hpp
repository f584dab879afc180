#pragma once
// Strict reading of one TOML table: every access names the key, every failure throws InputError
// at the node's own file:line:column (toml++ source()), and finish() rejects keys nobody read,
// so a typo in a config file is an error instead of a silently used default.
// Not real-time: used once, at startup, at the edge.
#include <toml++/toml.h>

#include <Eigen/Dense>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/input_error.hpp"

namespace inertia::config {

/// file:line:column of a toml++ node (the file is taken from the node, or `fallback_file`).
SourcePosition position_of(const toml::node& node, const std::string& fallback_file);

/// Parses a TOML file; a syntax error becomes InputError at the parser's position, a missing file
/// InputError naming the file.
toml::table parse_toml_file(const std::filesystem::path& path);

/// Parses TOML text that came from `path` (positions in errors and in nodes name that path), for
/// files carried in memory (the bench file on INERTIA_BENCH).
toml::table parse_toml_text(std::string_view text, const std::string& path);

class TableReader {
 public:
  /// `context` names the table in messages ("case[2].phase[1]"); empty for the root.
  TableReader(const toml::table& table, std::string context, std::string file);

  [[nodiscard]] bool has(std::string_view key) const;

  double number(std::string_view key) const;                         // required; integer accepted
  double number_or(std::string_view key, double fallback) const;
  /// A number with a lower/upper bound check (inclusive unless `open`).
  double number_in(std::string_view key, double fallback, double lo, double hi) const;
  double positive(std::string_view key) const;                       // required, > 0
  double positive_or(std::string_view key, double fallback) const;   // > 0
  std::int64_t integer(std::string_view key) const;
  std::int64_t integer_in(std::string_view key, std::int64_t fallback, std::int64_t lo, std::int64_t hi) const;
  bool boolean_or(std::string_view key, bool fallback) const;
  std::string string(std::string_view key) const;
  std::string string_or(std::string_view key, std::string fallback) const;
  /// One of `choices`; returns its index.
  std::size_t choice(std::string_view key, const std::vector<std::string_view>& choices) const;
  std::size_t choice_or(std::string_view key, const std::vector<std::string_view>& choices,
                        std::size_t fallback) const;
  Eigen::Vector3d vec3(std::string_view key) const;                  // [x, y, z]
  Eigen::Vector3d vec3_or(std::string_view key, const Eigen::Vector3d& fallback) const;
  Eigen::Vector3d nonzero_vec3(std::string_view key) const;          // axis: norm > 0
  Eigen::Matrix3d mat3(std::string_view key) const;                  // [[row], [row], [row]]
  std::vector<double> numbers(std::string_view key) const;           // [a, b, ...]

  TableReader table(std::string_view key) const;                     // required sub-table
  std::optional<TableReader> optional_table(std::string_view key) const;
  /// An array of tables ([[key]]); empty when the key is absent.
  std::vector<TableReader> tables(std::string_view key) const;
  /// Every key of the table, marking all as read (for open-ended tables such as [sensor.truth]).
  std::vector<std::pair<std::string, const toml::node*>> entries() const;

  /// The node of `key` (marks it read); nullptr when absent.
  const toml::node* node(std::string_view key) const;
  /// Throws InputError on the first key that no accessor has read.
  void finish() const;

  [[noreturn]] void fail(const toml::node& at, const std::string& message) const;
  [[noreturn]] void fail_key(std::string_view key, const std::string& message) const;
  [[noreturn]] void fail_here(const std::string& message) const;

  [[nodiscard]] SourcePosition where() const { return position_of(*table_, file_); }
  [[nodiscard]] SourcePosition where(std::string_view key) const;
  [[nodiscard]] const std::string& file() const { return file_; }
  [[nodiscard]] std::string key_name(std::string_view key) const;
  [[nodiscard]] const toml::table& raw() const { return *table_; }

 private:
  const toml::node& required(std::string_view key, const char* expected) const;
  double as_number(const toml::node& n, std::string_view key) const;

  const toml::table* table_;
  std::string context_;
  std::string file_;
  // Shared so that copies of a reader (returned by value) still report into one set.
  std::shared_ptr<std::set<std::string, std::less<>>> used_;
};

}  // namespace inertia::config
