#include "analyzer/unit/unit_model.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <array>

#include "common/input_error.hpp"

namespace inertia::unit {

bool UnitModel::has(dataset::SensorKind kind) const {
  return std::any_of(members.begin(), members.end(), [&](const model::ModelFile& m) { return m.sensor == kind; });
}

std::string member_file_name(const std::string& sensor) { return "member-" + sensor + ".toml"; }

bool is_unit_model(const std::filesystem::path& file) {
  try {
    const toml::table root = toml::parse_file(file.string());
    return root.contains("unit") && !root.contains("terms");
  } catch (const toml::parse_error&) {
    return false;
  }
}

UnitModel read_unit_model(const std::filesystem::path& file) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw InputError(SourcePosition{file.string(), e.source().begin.line, e.source().begin.column},
                     std::string(e.description()));
  }
  UnitModel u;
  u.file = file;
  u.unit = root["unit"].value_or(std::string());
  u.serial = root["serial"].value_or(std::string());
  if (u.unit.empty()) throw InputError(SourcePosition{file.string(), 0, 0}, "missing key 'unit' (the unit's name)");
  for (const dataset::SensorKind kind : {dataset::SensorKind::Accelerometer, dataset::SensorKind::Gyroscope}) {
    const std::string table = dataset::to_string(kind);
    if (!root.contains(table)) continue;
    for (int axis = 0; axis < 3; ++axis) {
      const std::string key = fmt::format("{}.axis.{}", table, static_cast<char>('x' + axis));
      const toml::node_view<const toml::node> entry = std::as_const(root).at_path(key + ".model");
      const std::optional<std::string> name = entry.value<std::string>();
      if (!name) {
        throw InputError(SourcePosition{file.string(), 0, 0},
                         fmt::format("[{}] names no member model file (model = \"...\"): a unit.toml written before units carried "
                                     "their members; run `inertia-analyze unit` again",
                                     key));
      }
      const std::filesystem::path member = file.parent_path() / *name;
      model::ModelFile m = model::read_model(member);
      if (m.sensor != kind || m.unit != u.unit || m.unit_axis != axis) {
        throw InputError(SourcePosition{member.string(), 0, 0},
                         fmt::format("is not the {} of unit '{}' along {} that {} names (it states {} of unit '{}', axis {})", table,
                                     u.unit, static_cast<char>('x' + axis), file.string(), dataset::to_string(m.sensor), m.unit,
                                     m.unit_axis < 0 ? '-' : static_cast<char>('x' + m.unit_axis)));
      }
      u.members.push_back(std::move(m));
    }
  }
  if (u.members.empty())
    throw InputError(SourcePosition{file.string(), 0, 0}, "neither an [accelerometer] nor a [gyroscope] triad");
  return u;
}

}  // namespace inertia::unit
