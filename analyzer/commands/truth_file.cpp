#include "analyzer/commands/truth_file.hpp"

#include <toml++/toml.h>

#include "analyzer/ident/term.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {
namespace {

frames::Dcm read_dcm(const toml::node* node, const std::string& file, const std::string& what) {
  const toml::array* rows = node != nullptr ? node->as_array() : nullptr;
  frames::Dcm m;
  if (rows == nullptr || rows->size() != 3) throw InputError(SourcePosition{file, 0, 0}, what + " must be a 3x3 array");
  for (std::size_t r = 0; r < 3; ++r) {
    const toml::array* row = (*rows)[r].as_array();
    if (row == nullptr || row->size() != 3) throw InputError(SourcePosition{file, 0, 0}, what + " must be a 3x3 array");
    for (std::size_t c = 0; c < 3; ++c) {
      const auto v = (*row)[c].value<double>();
      if (!v) throw InputError(SourcePosition{file, 0, 0}, what + " holds a non-number");
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = *v;
    }
  }
  return m;
}

}  // namespace

std::optional<Truth> read_truth(const std::filesystem::path& dataset_dir) {
  const std::filesystem::path path = dataset_dir / "truth.toml";
  if (!std::filesystem::exists(path)) return std::nullopt;
  const std::string file = path.string();
  toml::table root;
  try {
    root = toml::parse_file(file);
  } catch (const toml::parse_error& e) {
    throw InputError(SourcePosition{file, e.source().begin.line, e.source().begin.column}, std::string(e.description()));
  }
  Truth truth;
  if (const toml::table* terms = root["terms"].as_table()) {
    for (const auto& [key, value] : *terms) {
      const auto v = value.value<double>();
      if (!v) throw InputError(SourcePosition{file, 0, 0}, "truth term '" + std::string(key.str()) + "' is not a number");
      truth.terms[ident::parse_term(key.str()).to_string()] = *v;
    }
  }
  if (const toml::table* params = root["params"].as_table()) {
    for (const auto& [key, value] : *params) {
      if (const auto v = value.value<double>()) truth.params[std::string(key.str())] = *v;
    }
  }
  if (root.contains("m_cs")) truth.m_cs = read_dcm(root.get("m_cs"), file, "m_cs");
  if (const toml::array* cases = root["case"].as_array()) {
    for (const toml::node& node : *cases) {
      const toml::table* c = node.as_table();
      if (c == nullptr) continue;
      const auto name = c->get("name") != nullptr ? c->get("name")->value<std::string>() : std::nullopt;
      if (name && c->contains("m_es_true")) truth.m_es[*name] = read_dcm(c->get("m_es_true"), file, "m_es_true");
    }
  }
  return truth;
}

}  // namespace inertia::commands
