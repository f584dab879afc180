#pragma once
// The report of `diagnose`: report.md with the location table (residual RMS per case and phase
// before and after every step, with the location test), the findings, and gnuplot plots of the
// residual traces before/after and of the per-segment RMS bars.
#include <filesystem>
#include <string>

#include "analyzer/diagnose/discrepancy.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::diagnose {

/// Writes report.md (and plots/) into `out`; returns the report path. Without gnuplot the data
/// files and scripts stay in plots/ and the report says so.
std::filesystem::path write_diagnose_report(const dataset::Dataset& data, const DiagnoseResult& result,
                                            const std::string& dataset_label, const std::filesystem::path& out,
                                            bool plots = true);

}  // namespace inertia::diagnose
