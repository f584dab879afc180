#pragma once
// The report of `characterize`: report.md with the selected terms, coefficients (standard
// deviation, t, p, physical name), misalignment per case, residual statistics per case and phase
// (RMS, mean test, whiteness and independence from the input with 95% bands), verification error
// per case (the paper's Fig. 7) and, when the dataset carries truth.toml, every estimate scored
// against truth. Plots are PNGs drawn by gnuplot from data files written beside them; without
// gnuplot the data files and scripts stay for the user and the report says so.
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "analyzer/ident/static_gain.hpp"
#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "analyzer/report/gnuplot.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::report {

struct TruthForReport {
  std::map<std::string, double> terms;          // canonical term -> coefficient
  std::map<std::string, frames::Dcm> m_es;      // case name -> true M_E^S
};

struct ReportInputs {
  const dataset::Dataset* data = nullptr;
  const procedure::PipelineResult* result = nullptr;
  const procedure::BatchVerification* verification = nullptr;   // procedure::batch_verification of result
  std::optional<TruthForReport> truth;
  std::string dataset_label;
  bool plots = true;
};

/// The batch model's static gains (ident::static_gains) as the report and the summary show them:
/// without the squares when they pass eq. 12's high pass, whose columns carry no static part.
std::vector<ident::StaticGain> sensor_static_gains(const procedure::PipelineResult& result);

/// report.md as written, and its plots while gnuplot draws them.
struct WrittenReport {
  std::filesystem::path file;
  std::unique_ptr<GnuplotRuns> plots;   // none: no plots asked for
};

/// Writes report.md into `out`, and plots/ with the plots' data and scripts, which gnuplot starts
/// drawing: the caller appends to the report while they draw, then finish_report_plots.
WrittenReport write_characterization_report(const ReportInputs& in, const std::filesystem::path& out);

/// Waits for the report's plots and appends its Plots section: the images, or why there are none.
void finish_report_plots(WrittenReport& report);

}  // namespace inertia::report
