#include "common/config/toml_reader.hpp"

#include <cmath>
#include <sstream>
#include <utility>

namespace inertia::config {

namespace {

std::string type_name(const toml::node& n) {
  std::ostringstream s;
  s << n.type();   // toml++ streams node types as "string", "floating-point", "table", ...
  return s.str();
}

}  // namespace

SourcePosition position_of(const toml::node& node, const std::string& fallback_file) {
  const toml::source_region& src = node.source();
  SourcePosition p;
  p.file = src.path ? *src.path : fallback_file;
  p.line = src.begin.line;
  p.column = src.begin.column;
  return p;
}

toml::table parse_toml_file(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) {
    throw InputError(SourcePosition{path.string(), 0, 0}, "file not found");
  }
  try {
    return toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    const toml::source_region& src = e.source();
    SourcePosition p{src.path ? *src.path : path.string(), src.begin.line, src.begin.column};
    throw InputError(p, "TOML syntax error: " + std::string(e.description()));
  }
}

toml::table parse_toml_text(std::string_view text, const std::string& path) {
  try {
    return toml::parse(text, std::string_view{path});
  } catch (const toml::parse_error& e) {
    const toml::source_region& src = e.source();
    SourcePosition p{src.path ? *src.path : path, src.begin.line, src.begin.column};
    throw InputError(p, "TOML syntax error: " + std::string(e.description()));
  }
}

TableReader::TableReader(const toml::table& table, std::string context, std::string file)
    : table_(&table), context_(std::move(context)), file_(std::move(file)),
      used_(std::make_shared<std::set<std::string, std::less<>>>()) {}

std::string TableReader::key_name(std::string_view key) const {
  return context_.empty() ? std::string(key) : context_ + "." + std::string(key);
}

SourcePosition TableReader::where(std::string_view key) const {
  if (const toml::node* n = table_->get(key)) return position_of(*n, file_);
  return where();
}

void TableReader::fail(const toml::node& at, const std::string& message) const {
  throw InputError(position_of(at, file_), message);
}

void TableReader::fail_key(std::string_view key, const std::string& message) const {
  throw InputError(where(key), key_name(key) + ": " + message);
}

void TableReader::fail_here(const std::string& message) const {
  throw InputError(where(), (context_.empty() ? std::string("top level") : context_) + ": " + message);
}

bool TableReader::has(std::string_view key) const { return table_->contains(key); }

const toml::node* TableReader::node(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (n != nullptr) used_->emplace(key);
  return n;
}

const toml::node& TableReader::required(std::string_view key, const char* expected) const {
  const toml::node* n = node(key);
  if (n == nullptr) {
    // A missing key has no node of its own: point at the table that should hold it.
    fail_here("missing key '" + std::string(key) + "' (expected " + expected + ")");
  }
  return *n;
}

double TableReader::as_number(const toml::node& n, std::string_view key) const {
  if (const auto d = n.value_exact<double>()) {
    if (!std::isfinite(*d)) fail(n, key_name(key) + " must be a finite number");
    return *d;
  }
  if (const auto i = n.value_exact<std::int64_t>()) return static_cast<double>(*i);
  fail(n, key_name(key) + " must be a number, got " + type_name(n));
}

double TableReader::number(std::string_view key) const {
  return as_number(required(key, "a number"), key);
}

double TableReader::number_or(std::string_view key, double fallback) const {
  const toml::node* n = node(key);
  return n == nullptr ? fallback : as_number(*n, key);
}

double TableReader::number_in(std::string_view key, double fallback, double lo, double hi) const {
  const double v = number_or(key, fallback);
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << key_name(key) << " = " << v << " is outside [" << lo << ", " << hi << "]";
    throw InputError(where(key), s.str());
  }
  return v;
}

double TableReader::positive(std::string_view key) const {
  const double v = number(key);
  if (!(v > 0.0)) {
    std::ostringstream s;
    s << key_name(key) << " = " << v << " must be greater than 0";
    throw InputError(where(key), s.str());
  }
  return v;
}

double TableReader::positive_or(std::string_view key, double fallback) const {
  return has(key) ? positive(key) : fallback;
}

std::int64_t TableReader::integer(std::string_view key) const {
  const toml::node& n = required(key, "an integer");
  if (const auto i = n.value_exact<std::int64_t>()) return *i;
  fail(n, key_name(key) + " must be an integer, got " + type_name(n));
}

std::int64_t TableReader::integer_in(std::string_view key, std::int64_t fallback, std::int64_t lo,
                                     std::int64_t hi) const {
  if (!has(key) && (fallback < lo || fallback > hi)) {
    // No valid default: the key is required.
    fail_here("missing key '" + std::string(key) + "' (expected an integer in [" + std::to_string(lo) +
              ", " + std::to_string(hi) + "])");
  }
  const std::int64_t v = has(key) ? integer(key) : fallback;
  if (v < lo || v > hi) {
    throw InputError(where(key), key_name(key) + " = " + std::to_string(v) + " is outside [" +
                                     std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return v;
}

bool TableReader::boolean_or(std::string_view key, bool fallback) const {
  const toml::node* n = node(key);
  if (n == nullptr) return fallback;
  if (const auto b = n->value_exact<bool>()) return *b;
  fail(*n, key_name(key) + " must be true or false, got " + type_name(*n));
}

std::string TableReader::string(std::string_view key) const {
  const toml::node& n = required(key, "a string");
  if (const auto s = n.value_exact<std::string>()) return *s;
  fail(n, key_name(key) + " must be a string, got " + type_name(n));
}

std::string TableReader::string_or(std::string_view key, std::string fallback) const {
  return has(key) ? string(key) : std::move(fallback);
}

std::size_t TableReader::choice(std::string_view key, const std::vector<std::string_view>& choices) const {
  const std::string v = string(key);
  for (std::size_t i = 0; i < choices.size(); ++i) {
    if (choices[i] == v) return i;
  }
  std::string list;
  for (const auto c : choices) list += (list.empty() ? "" : ", ") + std::string(c);
  throw InputError(where(key), key_name(key) + " = \"" + v + "\" is not one of: " + list);
}

std::size_t TableReader::choice_or(std::string_view key, const std::vector<std::string_view>& choices,
                                   std::size_t fallback) const {
  return has(key) ? choice(key, choices) : fallback;
}

std::vector<double> TableReader::numbers(std::string_view key) const {
  const toml::node& n = required(key, "an array of numbers");
  const toml::array* a = n.as_array();
  if (a == nullptr) fail(n, key_name(key) + " must be an array of numbers, got " + type_name(n));
  std::vector<double> out;
  out.reserve(a->size());
  for (const toml::node& e : *a) out.push_back(as_number(e, key));
  return out;
}

Eigen::Vector3d TableReader::vec3(std::string_view key) const {
  const std::vector<double> v = numbers(key);
  if (v.size() != 3) {
    fail_key(key, "expected an array of 3 numbers, got " + std::to_string(v.size()));
  }
  return {v[0], v[1], v[2]};
}

Eigen::Vector3d TableReader::vec3_or(std::string_view key, const Eigen::Vector3d& fallback) const {
  return has(key) ? vec3(key) : fallback;
}

Eigen::Vector3d TableReader::nonzero_vec3(std::string_view key) const {
  const Eigen::Vector3d v = vec3(key);
  if (v.norm() == 0.0) fail_key(key, "an axis must not be [0, 0, 0]");
  return v;
}

Eigen::Matrix3d TableReader::mat3(std::string_view key) const {
  const toml::node& n = required(key, "a 3x3 array of numbers");
  const toml::array* rows = n.as_array();
  if (rows == nullptr || rows->size() != 3) {
    fail(n, key_name(key) + " must be a 3x3 array [[r0], [r1], [r2]]");
  }
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r) {
    const toml::node& row_node = *rows->get(static_cast<std::size_t>(r));
    const toml::array* row = row_node.as_array();
    if (row == nullptr || row->size() != 3) fail(row_node, key_name(key) + ": each row must hold 3 numbers");
    for (int c = 0; c < 3; ++c) m(r, c) = as_number(*row->get(static_cast<std::size_t>(c)), key);
  }
  return m;
}

TableReader TableReader::table(std::string_view key) const {
  const toml::node& n = required(key, "a table");
  const toml::table* t = n.as_table();
  if (t == nullptr) fail(n, key_name(key) + " must be a table, got " + type_name(n));
  return TableReader(*t, key_name(key), file_);
}

std::optional<TableReader> TableReader::optional_table(std::string_view key) const {
  if (!has(key)) return std::nullopt;
  return table(key);
}

std::vector<TableReader> TableReader::tables(std::string_view key) const {
  std::vector<TableReader> out;
  const toml::node* n = node(key);
  if (n == nullptr) return out;
  const toml::array* a = n->as_array();
  if (a == nullptr || !a->is_array_of_tables()) {
    fail(*n, key_name(key) + " must be an array of tables ([[" + std::string(key) + "]])");
  }
  for (std::size_t i = 0; i < a->size(); ++i) {
    out.emplace_back(*a->get(i)->as_table(), key_name(key) + "[" + std::to_string(i) + "]", file_);
  }
  return out;
}

std::vector<std::pair<std::string, const toml::node*>> TableReader::entries() const {
  std::vector<std::pair<std::string, const toml::node*>> out;
  for (const auto& [k, v] : *table_) {
    used_->emplace(k.str());
    out.emplace_back(std::string(k.str()), &v);
  }
  return out;
}

void TableReader::finish() const {
  for (const auto& [k, v] : *table_) {
    if (used_->find(k.str()) == used_->end()) {
      // Point at the key itself (the key's source), not at its value.
      SourcePosition p{k.source().path ? *k.source().path : file_, k.source().begin.line,
                       k.source().begin.column};
      if (p.line == 0) p = position_of(v, file_);
      throw InputError(p, "unknown key '" + key_name(k.str()) + "'");
    }
  }
}

}  // namespace inertia::config
