#pragma once
// Block 9 of the paper's Fig. 1: the regressions of several test cases, each built in its own
// frame and over its own samples (lags never reach across a case boundary), stacked into one
// batch, with optional per-case weights (section 3.4: weight the operational conditions).
#include <Eigen/Dense>
#include <span>
#include <string>
#include <vector>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// Where one case's rows sit in the stack.
struct CaseRows {
  std::size_t case_index = 0;     // into the dataset's cases
  Eigen::Index begin = 0;         // first row in the stack
  Eigen::Index rows = 0;
  Eigen::Index first_sample = 0;  // the case sample of the first row (its largest lag)
};

struct StackedRegression {
  Eigen::MatrixXd phi;            // rows of every case, weighted by sqrt(weight)
  Eigen::VectorXd y;
  std::vector<CaseRows> cases;
  std::vector<std::string> labels;   // canonical term names, one per column
  /// Output-multiplied columns (y*w_i, y*T: rational denominator terms, fitted by ULS with its
  /// bias correction) with their factors p_b per row, unweighted and never filtered: the noise
  /// the correction allows for is the one on y, whatever filter the rows pass (uls_batch.hpp).
  ident::OutputMultiplied rational;
};

/// One case of the stack: its data, the M_E^S that maps its references into F_S, its weight.
struct StackInput {
  std::size_t case_index = 0;
  const dataset::CaseData* data = nullptr;
  Eigen::Matrix3d m_es = Eigen::Matrix3d::Identity();
  double weight = 1.0;
  ident::CaseReading reading;   // the external variables' frame and the output's offset
};

/// Builds each case's regression over `terms` and stacks them. `min_first_row` aligns every case
/// on the same first sample whatever the terms' lags (so models of different orders are compared
/// on the same rows, as AIC requires). Throws InputError when a case lacks a column a term needs.
StackedRegression stack_regressions(std::span<const ident::Term> terms, std::span<const StackInput> inputs,
                                    double t_ref, std::string_view dataset_label, Eigen::Index min_first_row = 0);

/// The first row of each case after the first: where the stack's contiguous stretches start
/// (ident::SelectionProblem::stretch_starts).
[[nodiscard]] std::vector<Eigen::Index> stretch_starts(std::span<const CaseRows> cases);

/// The rows stack_regressions gives each of `inputs` (a case too short for the terms' lags has
/// none and no entry), without building them.
std::vector<CaseRows> stack_layout(std::span<const ident::Term> terms, std::span<const StackInput> inputs,
                                   Eigen::Index min_first_row = 0);

}  // namespace inertia::procedure
