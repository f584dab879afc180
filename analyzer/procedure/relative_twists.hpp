#pragma once
// PipelineOptions::batch_relative_twist: how the aligned mountings are turned about n_i against
// one another, found in the batch. The cross-axis terms are one set for the sensor, so a mounting
// held at its nominal twist while another is not forces the batch to fit one set of terms in two
// frames.
#include <Eigen/Dense>
#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/batch_regression.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

struct RelativeTwists {
  StackedRegression batch;                  // rebuilt with the mountings turned
  std::vector<MountingResult> mountings;    // M_C^S, twist and angles of the turned ones
  std::vector<std::size_t> estimated;       // mountings whose twist (and tilts) the batch refined
  std::vector<std::size_t> held;            // mountings whose twist the plan does not determine
  /// Per mounting, an estimated twist's sd at the search's last step (every candidate term free,
  /// the residual's spectrum counted); 0 for the others.
  std::vector<double> twist_sd_rad;
  std::vector<std::string> notes;           // for the user: each held twist, and why
};

/// Each further aligned mounting's turn against the reference mounting (the first aligned), its
/// twist about n_i with the tilts its excitation determines, by Gauss-Newton steps on the
/// whitened batch `batch` of every identifiable candidate (`candidates`). The tilts join because
/// a held twist leaks into them. A twist whose sd, with the tilts free, exceeds the mounting
/// tolerance is held at the nominal frame; the rest turn their mounting's M_C^S, and the batch is
/// rebuilt with them (`batch_at`). The sd is the search's sandwich under each case's residual
/// spectrum, `below_record` (StaticNoiseLaw::below_record) below one cycle per case.
RelativeTwists relative_twists(StackedRegression batch, std::vector<MountingResult> mountings, const BatchRegression& batch_at,
                               std::span<const ident::Term> candidates, std::optional<double> square_corner,
                               const dataset::Dataset& data, const PipelineOptions& options,
                               const std::function<double(double)>& below_record = {});

}  // namespace inertia::procedure
