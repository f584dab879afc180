#pragma once
// `inertia-analyze noise --dataset DIR | --log FILE [--sensor S] [--case NAME] [--tau-max S] --out DIR`:
// the sensor's noise from the static stretches of a dataset or an event log (noise/noise_analysis.hpp):
// Allan and modified Allan deviation with 95 % intervals, the fit of Q, N, B, K, R with their
// intervals and tau ranges, the Welch PSD with the fitted model. Writes noise.toml (its [noise]
// table is a model file's, docs/design.md "Model file"), report.md and plots/ (adev.png, psd.png).
#include <filesystem>
#include <iosfwd>
#include <string>

#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/noise_analysis.hpp"

namespace inertia::commands {

struct NoiseCommandOptions {
  std::filesystem::path dataset;
  std::filesystem::path event_log;
  std::string sensor;        // with --log
  std::string case_name;     // only this case (all its rows)
  double tau_max_s = 0.0;    // > 0: fit up to this tau
  std::filesystem::path out;
  bool plots = true;
};

int run_noise(const NoiseCommandOptions& options, std::ostream& out);

/// The noise section of a report on `md` (its headline lines on `out` too): the stretches, the
/// fit's table, the Allan table, the method; plots into `plots_dir` (none when empty), linked as
/// plots/ from the report's folder. `noise` and `characterize` write the same section.
void write_noise_section(std::ostream& md, std::ostream& out, const noise::NoiseAnalysis& a, const std::string& unit,
                         const std::string& source, const std::filesystem::path& plots_dir);

/// The analysis's determined terms into a model file's [noise] (Q, N, B, K, R), with their sd in [noise.std].
void noise_terms_into(const noise::NoiseAnalysis& a, model::ModelFile& model);

}  // namespace inertia::commands
