#pragma once
// `inertia-analyze sheet --model M.toml --out DIR`: the model's parameter sheet in the standards'
// names (report/parameter_sheet.hpp) as sheet.md, sheet.html and sheet.json
// (tests/schema/sheet.schema.json). characterize writes the same three beside model.toml.
#include <filesystem>
#include <iosfwd>

#include "analyzer/model/model_file.hpp"
#include "analyzer/report/parameter_sheet.hpp"

namespace inertia::commands {

/// Writes DIR/sheet.md, sheet.html and sheet.json of `model`, each whole or not at all; returns
/// the sheet (for the summary and the record).
report::ParameterSheet write_sheet(const model::ModelFile& model, const std::filesystem::path& dir);

int run_sheet(const std::filesystem::path& model_file, const std::filesystem::path& out, std::ostream& summary);

}  // namespace inertia::commands
