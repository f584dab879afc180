#pragma once
// `inertia-analyze diagnose --model MODEL.toml --dataset DIR|--log FILE --json OUT.json [--report DIR]`:
// the discrepancy workflow (analyzer/diagnose/discrepancy.hpp) on a dataset folder; writes the
// JSON of docs/design.md ("Command line"), the augmented model file and, with --report, report.md.
#include <filesystem>
#include <iosfwd>
#include <string>

namespace inertia::commands {

struct DiagnoseCommandOptions {
  std::filesystem::path model;
  std::filesystem::path dataset;
  std::filesystem::path event_log;  // instead of dataset: an inertia-daqd event log (--log)
  std::string sensor;               // with event_log: the sensor under test (empty: the only one)
  std::filesystem::path json;
  std::filesystem::path report;   // empty: no report; the augmented model goes beside the JSON
  std::filesystem::path log;      // empty: no copy of the console summary (--summary)
  double alpha = 0.05;
  bool plots = true;
};

int run_diagnose(const DiagnoseCommandOptions& options, std::ostream& out);

}  // namespace inertia::commands
