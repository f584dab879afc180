#include "analyzer/commands/sheet.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "analyzer/report/parameter_sheet.hpp"
#include "common/atomic_file.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {

report::ParameterSheet write_sheet(const model::ModelFile& model, const std::filesystem::path& dir) {
  const report::ParameterSheet sheet = report::parameter_sheet(model);
  std::filesystem::create_directories(dir);
  write_file_atomically(dir / "sheet.md", report::sheet_markdown(sheet));
  write_file_atomically(dir / "sheet.html", report::sheet_html(sheet));
  write_file_atomically(dir / "sheet.json", report::sheet_json(sheet).dump(2) + "\n");
  return sheet;
}

int run_sheet(const std::filesystem::path& model_file, const std::filesystem::path& out, std::ostream& summary) {
  const model::ModelFile model = model::read_model(model_file);
  const report::ParameterSheet sheet = write_sheet(model, out);
  for (const report::SheetEntry& e : sheet.entries) {
    if (e.status == report::SheetEntry::Status::Determined)
      fmt::print(summary, "  {:<48} {:>12.4g} +- {:<10.3g} {}\n", e.name, e.value, e.expanded_uncertainty, e.unit);
    else
      fmt::print(summary, "  {:<48} {}\n", e.name, e.reason);
  }
  fmt::print(summary, "wrote {0}/sheet.md, {0}/sheet.html, {0}/sheet.json (U: k = 2)\n", out.string());
  return kExitOk;
}

}  // namespace inertia::commands
