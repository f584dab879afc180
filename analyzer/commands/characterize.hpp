#pragma once
// `inertia-analyze characterize --dataset DIR|--log FILE --out DIR`: the paper's Fig. 1 procedure on a
// dataset folder or an event log (fused into the same dataset, analyzer/fusion/log_dataset.hpp); writes model.toml (docs/design.md "Model file"), report.md and plots.
#include <filesystem>
#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/pipeline.hpp"

namespace inertia::commands {

struct CharacterizeOptions {
  std::filesystem::path dataset;
  std::filesystem::path event_log;      // instead of dataset: an inertia-daqd event log (--log)
  std::string sensor;                   // with event_log: the sensor under test (empty: the only one)
  std::filesystem::path dataset_out;    // with event_log: also write the converted dataset folder here
  std::filesystem::path out;
  int order = 0;                        // r of the batch candidates (block 11); the squares get eq. 12's high pass
  int misalignment_order = 0;           // r of the algorithm-2 candidates (blocks 5-6)
  int noise_lags = -1;                  // MA lags of the batch fit; -1: equal to order
  std::vector<std::string> fixed_model; // non-empty: block 10 with these F_S terms
  std::vector<std::string> misalignment_model;  // non-empty: blocks 5-6 fixed on these F_E-and-F_S terms
  std::map<std::string, double> weights;
  double alpha = ident::SelectionOptions{}.alpha;
  double mounting_tolerance_deg = 1.0;  // a held mounting angle is within this (1 sd)
  bool plots = true;
  std::string record_db;                // non-empty: append the characterization to this record (file or URL)
  std::string serial, part;             // the sensor's serial and part; checked against the bench's where it states them
  std::string operator_name;            // with record_db
};

/// Pipeline options from the command-line choices (shared with reproduce-paper).
procedure::PipelineOptions pipeline_options(const CharacterizeOptions& options);

/// The model file characterize writes for `result`: the batch's terms with their sd, M_C^S, the
/// innovation's sd and the free run's (from `verification`, procedure::batch_verification), the
/// squares' corner, and the sensor's noise terms from the plan's static stretches (their analysis
/// in `noise_analysis`; when there is none, `why_no_noise` says why).
model::ModelFile characterized_model(const procedure::PipelineResult& result, const dataset::Dataset& data,
                                     const procedure::BatchVerification& verification,
                                     std::optional<noise::NoiseAnalysis>& noise_analysis, std::string& why_no_noise,
                                     const std::string& source = {});

int run_characterize(const CharacterizeOptions& options, std::ostream& out);

}  // namespace inertia::commands
