#pragma once
// The kind of a test case, shared by the bench file's test plan (common/config) and the dataset
// contract (common/dataset, docs/design.md "dataset.toml": kind = rotation_table | shaker | thermal |
// static): one enum, so a case keeps its kind from the plan through the log to the analyzer.
#include <optional>
#include <string_view>

namespace inertia {

enum class CaseKind { RotationTable, Shaker, Thermal, Static };

/// "rotation_table", "shaker", "thermal", "static" (the contract's spelling).
constexpr const char* to_string(CaseKind kind) noexcept {
  switch (kind) {
    case CaseKind::RotationTable: return "rotation_table";
    case CaseKind::Shaker: return "shaker";
    case CaseKind::Thermal: return "thermal";
    case CaseKind::Static: return "static";
  }
  return "?";
}

constexpr std::optional<CaseKind> case_kind_from_string(std::string_view text) noexcept {
  for (CaseKind k : {CaseKind::RotationTable, CaseKind::Shaker, CaseKind::Thermal, CaseKind::Static}) {
    if (text == to_string(k)) return k;
  }
  return std::nullopt;
}

}  // namespace inertia
