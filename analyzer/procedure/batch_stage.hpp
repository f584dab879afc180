#pragma once
// Blocks 7-11: every case's references mapped to F_S with the M_E^S its mounting gives, the
// cases concatenated (optionally weighted, section 3.4) and whitened, the aligned mountings'
// relative twists, the batch model fixed or selected (section 2.7.2), and the inference after
// selection with what the searched and the held angles add to it.
#include <Eigen/Dense>
#include <string_view>
#include <vector>

#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// The batch model's innovation: its residual, through its AR noise model where the rows were kept
/// unfiltered (PipelineResult::rows_filtered), stacked case by case as `cases` say (the
/// dataset's case, its first sample), and its variance (on the residual's dof).
struct BatchInnovation {
  Eigen::VectorXd values;
  std::vector<CaseRows> cases;
  double variance = 0.0;
};

BatchInnovation batch_innovation(const PipelineResult& result);

/// The paper's verification error (Fig. 7) of one case: the batch model run free on the case's
/// references in its M_E^S (noise terms zero, squares through their high pass) minus the
/// measured output, from the model's first usable row. What the model leaves of the output:
/// every colour of the noise, and any misfit.
Eigen::VectorXd free_run_error(const dataset::Dataset& data, const CaseOutcome& outcome, const PipelineResult& result,
                               std::string_view dataset_label = {});

/// What the batch model leaves of each case, computed once for the model file and the report:
/// the innovation (batch_innovation) and each case's free-run error (free_run_error), in the
/// order of result.cases.
struct BatchVerification {
  BatchInnovation innovation;
  std::vector<Eigen::VectorXd> free_run;
};
BatchVerification batch_verification(const dataset::Dataset& data, const PipelineResult& result, std::string_view dataset_label = {});

/// The batch model of `data` on the mountings of `mounted` (blocks 5-6: its mountings, the cases'
/// M_E^S, M_C^S and the notes so far), which it returns completed.
PipelineResult identify_batch(PipelineResult mounted, const dataset::Dataset& data, const PipelineOptions& options,
                              std::string_view dataset_label);

}  // namespace inertia::procedure
