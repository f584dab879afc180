#pragma once
// Honest inference after a selection, whose t-tests take every sample as independent. The
// cases' contiguous phases are clusters; offsets between them that the noise model does not
// explain (a pose's placement, drift, 1/f noise below the AR model's reach, a model error that
// repeats per phase) are a variance component (ident::cluster_offsets), and every coefficient's
// covariance includes what they do to it. A term that varies within the phases is determined
// there and tested on the samples' dof; a term constant within each phase (a square in static
// poses, the bias) is determined only by the phases' means and is tested on the between-phase
// dof, less the parameters found by a search on the same data (mounting angles, the squares'
// corner). When the model has as many phase-level parameters as phases the offsets cannot be
// told from it: the weakest removable phase-level term leaves first. Then, one at a time, the
// term whose test falls below the threshold leaves and the model is refitted.
#include <Eigen/Dense>
#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/statistics.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// One id per stacked row: the contiguous runs of one phase label within a case of the plan (the
/// whole case when it has no phase column). A phase cut by lost samples into two pieces of its
/// case (CaseData::piece_of) is one run. The clusters of the inference.
std::vector<int> phase_clusters(const StackedRegression& s, const dataset::Dataset& data);

/// The stacked rows of each case of the plan: its pieces (CaseData::piece_of) are consecutive in
/// the stack, and one noise process runs through them (a few lost samples do not restart it).
std::vector<CaseRows> plan_case_rows(const StackedRegression& s, const dataset::Dataset& data);

/// Per row of a whitened stacked problem: a_p^2 + a_o^2 (gyros w_p^2 + w_o^2) unfiltered, the
/// reach of a small tilt of the input axis (the loading of placement offsets, cluster_offsets).
/// `cases`: every dataset case's M_E^S; `candidates`: the terms the problem was stacked with.
Eigen::VectorXd cross_axis_loading(const StackedRegression& whitened, std::span<const ident::Term> candidates,
                                   const dataset::Dataset& data, const std::vector<CaseOutcome>& cases,
                                   std::string_view label);

/// The derivative of a fit's prediction with respect to a parameter its regression was built
/// with, by a central difference, as a whitened column: `stack_at(terms, offset)` rebuilds the
/// regression of the fit's terms with the parameter moved by `offset`, before whitening. The
/// whitener is linear and acts case by case, so the difference of the two predictions is whitened
/// once instead of every column of both regressions. The column is on the whitened rows `layout`
/// (the fit's stack's cases); `stack_at` may build only the cases the parameter moves, and the
/// others' rows are zero.
Eigen::VectorXd prediction_derivative(const ident::UlsResult& fit, double step, const ArWhitener& whitener,
                                      const std::vector<CaseRows>& layout,
                                      const std::function<StackedRegression(std::span<const ident::Term>, double)>& stack_at);

/// Parameters the fit's columns depend on that were estimated by a search on the same data (the
/// squares' corner, the mountings' angles): the derivative of the fitted prediction with respect
/// to each, one whitened column per parameter, and which parameter each column is (the caller's
/// ids). They join the covariance as columns of the Jacobian, so what their own uncertainty
/// moves is in the coefficients' sd.
struct SearchedColumns {
  Eigen::MatrixXd derivatives;
  std::vector<std::size_t> ids;
};

/// The noise spectrum of one run of a fit's residual (one noise process): the residual's own
/// (noise::fitted_spectrum) where its rows are whitened (`ar` empty), or, where they are kept
/// unfiltered (filters_rows), the AR noise model `ar` over the fitted spectrum of the innovation
/// it leaves (noise::fitted_spectrum_through_ar). `below_record`: as fitted_spectrum's.
noise::SegmentSpectrum residual_spectrum(const Eigen::Ref<const Eigen::VectorXd>& run, const Eigen::VectorXd& ar,
                                         const std::function<double(double)>& below_record = {});

/// For rows kept unfiltered under the AR noise model `ar`: what the residual's noise
/// (residual_spectrum of each of `runs`) makes of the least-squares variance of a column constant
/// within each run (a bias, a rate phase's rate, a pose's input), sum_r 1'R_r 1 / sum_r e_r'e_r:
/// the sandwich of infer_after_selection for such a column. At least 1. The live estimator, which
/// keeps statistics and no rows, scales its variances by it.
double unfiltered_long_run_ratio(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& runs, const Eigen::VectorXd& ar);

/// How a stacked problem's rows fall into the phases and noise processes of the plan.
struct PhaseLayout {
  std::vector<int> clusters;                // phase_clusters
  std::vector<CaseRows> noise_runs;         // one noise process each (plan_case_rows)
  Eigen::VectorXd loading;                  // cross_axis_loading
};

/// The layout of the whitened problem `s` stacked over `candidates` with the cases' M_E^S `cases`.
PhaseLayout phase_layout(const StackedRegression& s, std::span<const ident::Term> candidates, const dataset::Dataset& data,
                         const std::vector<CaseOutcome>& cases, std::string_view label);

struct InferenceProblem {
  const StackedRegression* s = nullptr;     // whitened
  const PhaseLayout* layout = nullptr;      // of s
  double threshold = 0.01;                  // a term whose test's p-value is above it leaves
  bool may_remove = true;
  dataset::SensorKind sensor = dataset::SensorKind::Accelerometer;   // its sensitivities and the bias never leave
  std::function<bool(const std::string&)> protect;     // further terms that never leave
  std::function<SearchedColumns(const ident::UlsResult&)> searched;   // empty: none
  /// What angles held at the nominal frame add to the coefficients' covariance (the fit's
  /// response to each turned by the mounting tolerance); empty: none held.
  std::function<Eigen::MatrixXd(const ident::UlsResult&)> held_covariance;
  /// The cases' stated placements (dataset::CaseData::placement_sd_rad) as a known part of the
  /// residual's covariance R: what a turn of each case by its sd about each axis moves the fit's
  /// prediction, one whitened column of s's rows each (BatchRegression::placement_columns). A
  /// placement shared by several phases of a case is what their scatter cannot show; the offsets
  /// between phases are then what the noise and the placements do not explain. Empty: none.
  std::function<Eigen::MatrixXd(const ident::UlsResult&)> placements;
  /// The whitened residual's density below one cycle per case (StaticNoiseLaw::below_record);
  /// empty: its white part alone.
  std::function<double(double)> below_record;
  /// Rows kept unfiltered (filters_rows): their AR noise model, through which each run's residual
  /// is whitened for its spectrum's fit (noise::fitted_spectrum_through_ar); empty: the rows are
  /// whitened already.
  Eigen::VectorXd unfiltered_rows_ar;
};

/// A selected term the inference took out, and why.
struct PrunedTerm {
  std::string term;
  /// As many parameters at the level of the phases' means as there are phases: the weakest of
  /// them by its classical t, since the offsets between the phases cannot be told from it.
  bool saturated = false;
  double t = 0.0;
  double dof = 0.0;                         // of its test
  int phases = 0;
  bool with_held_angles = false;            // the held angles were in its covariance
};

/// What the user reads about a pruned term of `model` ("batch model", "mounting's model").
std::string pruned_reason(const PrunedTerm& pruned, std::string_view model);

struct InferenceOutcome {
  std::vector<Eigen::Index> columns;        // of s, after the pruning
  ident::UlsResult fit;                     // with the inference's covariance and sd
  ident::ClusterOffsets offsets;
  Eigen::VectorXd dof;                      // each process term's test dof
  Eigen::MatrixXd searched_covariance;      // the searched parameters' block of the joint covariance
  std::vector<std::size_t> searched_ids;    // which parameter each row of it is (SearchedColumns::ids)
  Eigen::MatrixXd held_covariance;          // what the held angles added (empty: none)
  std::vector<PrunedTerm> pruned;           // in the order they left
};

/// The inference on the fit `fit` of `columns` of problem.s, pruning as described above (the
/// refits through fit_identifiable with `uls`).
InferenceOutcome infer_after_selection(const InferenceProblem& problem, std::vector<Eigen::Index> columns,
                                       ident::UlsResult fit, const ident::UlsOptions& uls);

}  // namespace inertia::procedure
