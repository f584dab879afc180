#pragma once
// Model selection of the paper's section 2.7: algorithm 2 (with a hook for the misalignment
// steps 6-8) and its section 2.7.2 variant without misalignment (no hook).
//
// For j = 1..p over the ERR-ranked candidates:
//   step 5   fit the first j ranked columns with ULS;
//   step 6-8 (hook) the caller may replace that problem by another one (the F_S problem built from
//            the misalignment estimated on the step-5 fit); without a hook the step-5 problem is used;
//   step 9   remove spurious parameters by Student's t-test (equation 11);
//   step 10  re-estimate; step 11 AIC (equation 9); step 12 p_res;
// then p_AIC (equation 10), fitness = p_res * p_AIC, and the model with the highest fitness wins.
#include "analyzer/ident/err.hpp"
#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/ident/uls_batch.hpp"

#include <Eigen/Dense>

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace inertia::ident {

/// The candidate regression problem. phi and y must outlive select_model (bind lvalues: a Ref to
/// an expression would hold a temporary).
struct SelectionProblem {
  SelectionProblem(const Eigen::Ref<const Eigen::MatrixXd>& phi_in,
                   const Eigen::Ref<const Eigen::VectorXd>& y_in, std::vector<std::string> labels_in,
                   OutputMultiplied rational_in = OutputMultiplied(),
                   std::vector<Index> ranking_in = std::vector<Index>())
      : phi(phi_in),
        y(y_in),
        labels(std::move(labels_in)),
        rational(std::move(rational_in)),
        ranking(std::move(ranking_in)) {}

  Eigen::Ref<const Eigen::MatrixXd> phi;  ///< N x p candidate columns
  Eigen::Ref<const Eigen::VectorXd> y;
  std::vector<std::string> labels;        ///< one per column
  OutputMultiplied rational;              ///< output-multiplied candidates (see uls_batch.hpp)
  /// Candidate columns in ranked order. Empty: the ERR ranking of phi with options.err (plain
  /// ERR; for output-multiplied candidates pass a ranking from bias_corrected_gram instead).
  std::vector<Index> ranking;
  /// Columns step 9 never removes once ranked in (the model's given terms, such as a sensor's bias
  /// and scale factor): a candidate near collinear with one of them must not take its place.
  std::vector<Index> kept;
  /// The first row of each contiguous stretch after the first (the stacked cases; empty: one
  /// stretch): step 12's lag-1 correlation pairs neighbours within a stretch (statistics.hpp).
  /// A hook's stages have the same rows, so the same stretches.
  std::vector<Index> stretch_starts;
};

/// A regression problem owned by the engine and filled by a FitHook (algorithm 2 steps 6-7).
struct StageProblem {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  std::vector<std::string> labels;
  OutputMultiplied rational;
  /// Columns step 9 never removes: nuisance parameters the transform introduced, e.g. the tilt of
  /// a misalignment estimated from the same data, so that the other terms' t-tests allow for its
  /// uncertainty. They are fitted and counted (AIC) in every model of the stage.
  std::vector<Index> kept;
  /// A stage whose columns are sums of columns held elsewhere may give, instead of phi and y, its
  /// normal equations and its residual y - Phi(:, columns) theta: the same fits, tests and scores
  /// without a copy of its rows. Linear least squares only (no output-multiplied column, no noise
  /// lags). With `equations` set, phi, y and rational are not read.
  std::optional<NormalEquations> equations;
  std::function<Eigen::VectorXd(std::span<const Index> columns, const Eigen::VectorXd& theta)> residuals;
};

/// Algorithm 2 steps 6-8 plug in here; section 2.7.2 is select_model without a hook.
/// The engine calls transform() once per j, after step 5, and owns `stage` (the same object every
/// time, so its buffers are reused). Thread: the caller's; not real-time.
class FitHook {
 public:
  virtual ~FitHook() = default;
  /// j: number of ranked candidates in `ranked_fit` (the step-5 ULS fit, labels in ranked order;
  /// its coefficients alone where the fit needs no rows for them: no residuals, no covariance).
  /// Fill `stage` with the problem whose columns are then pruned (step 9) and scored (steps 10-12)
  /// - e.g. the F_S regression built with the misalignment estimated from ranked_fit - and return
  /// true. Return false to prune and score the step-5 problem itself. Every stage must have the
  /// same number of samples (AIC compares models on the same N). Remember per-j results (the
  /// misalignment) on the hook's side; SelectionResult::best tells which j won.
  virtual bool transform(std::size_t j, const UlsResult& ranked_fit, StageProblem& stage) = 0;
};

enum class Multiplicity {
  None,        ///< each parameter tested at alpha
  /// Each parameter tested at alpha / m, m = number of ranked candidates (the search space).
  /// The j-th ranked term was picked as the best of the candidates left, so its own p-value is
  /// optimistic (the notes' §6.1 caveat); Bonferroni over the search space bounds the family-wise
  /// probability of keeping any spurious term by alpha, i.e. the exact structure is recovered in
  /// about 1 - alpha of the cases when the true terms are strong (test Selection.Recovers...).
  Bonferroni,
};

struct SelectionOptions {
  /// Family-wise t-test significance level of step 9. 1%, not 5%: the exact structure is
  /// recovered in about 1 - alpha of the cases, and at bench sample counts (1e4-1e6) real effects
  /// have t far above the Bonferroni threshold (3.9 at 60 candidates), so the stricter level costs
  /// no true term. SparseSelectionScenario measures the exact-structure rate of algorithm 2 on
  /// random sparse models (figures: docs/validation.md, 'Evidence behind choices in the code').
  double alpha = 0.01;
  /// Default Bonferroni: with a per-term alpha, 15 spurious candidates of 20 leave at least one
  /// spurious term with probability up to 1 - 0.95^15 = 54%, and a kept spurious term lowers AIC
  /// (t^2 > 2), so fitness would prefer the over-fitted model. Family-wise alpha avoids that.
  Multiplicity multiplicity = Multiplicity::Bonferroni;
  /// Remove the least significant term and refit, repeat (default), instead of removing every
  /// term above the threshold at once: correlated terms share variance, and dropping both members
  /// of a pair at once can drop a real effect.
  bool one_at_a_time = true;
  Index max_terms = -1;  ///< largest j tried (-1: every ranked candidate)
  UlsOptions uls;        ///< noise_lags > 0: ELS fits (noise terms are never pruned)
  ErrOptions err;        ///< used when the problem carries no ranking

  [[nodiscard]] bool is_valid(std::string* why) const;
};

struct CandidateModel {
  std::size_t ranked_terms = 0;      ///< j
  bool transformed = false;          ///< the hook supplied the problem that was scored
  bool ok = false;                   ///< false: `failure` says why (e.g. IdentifiabilityError)
  std::string failure;
  std::vector<Index> columns;        ///< final columns (of phi, or of the stage problem)
  std::vector<std::string> removed;  ///< pruned by the t-test, in removal order
  UlsResult fit;                     ///< step 10 fit of the final columns; fit.residuals is kept
                                     ///< for the best model only (empty otherwise: memory O(N)).
                                     ///< A j that prunes to an already scored term set copies
                                     ///< that score (no second data pass)
  ParameterTTest t_test;             ///< of fit.process_theta()
  ResidualMeanTest residual_mean;    ///< step 12
  double aic = 0.0;                  ///< equation 9 (parameters include noise terms)
  double p_aic = 0.0;                ///< equation 10
  double fitness = 0.0;              ///< p_res * p_AIC
};

struct SelectionResult {
  std::vector<Index> ranking;             ///< the ranked candidates used
  std::vector<CandidateModel> candidates; ///< index j-1 for j ranked terms
  std::size_t best = 0;                   ///< index into candidates
  [[nodiscard]] const CandidateModel& best_model() const { return candidates.at(best); }
};

/// Algorithm 2 (hook != nullptr) or section 2.7.2 (hook == nullptr). Ties in fitness go to the
/// model with fewer parameters, then to the smaller j. Throws std::invalid_argument on bad input
/// and std::runtime_error when no candidate could be fitted.
/// Cost and memory: one O(N p^2) pass builds the statistics (the ERR ranking reuses them); each
/// candidate then costs O(j^3) per pruning step and one O(N j) residual pass. Residuals are kept
/// for the running best model only, so memory is O(N + p^2) plus a few numbers per candidate,
/// whatever the number of candidate models tried. Rational or ELS fits need data passes per
/// pruning step (sandwich covariance / residual lags).
SelectionResult select_model(const SelectionProblem& problem, const SelectionOptions& options,
                             FitHook* hook = nullptr);

/// Section 2.7.2 on the normal equations alone (no rows): what the live estimator keeps. The same
/// steps and rules as above, the fits and scores from the statistics (step 12 through the bias
/// candidate's column and the successive differences' Gram matrix, N_eff as the rows' when the
/// equations hold it; selection.cpp's EquationsContext says how each differs from the rows'). The
/// models' fits have no residuals. `ranking`: as SelectionProblem::ranking (empty: plain ERR);
/// `kept`: as SelectionProblem::kept. Throws as above, and std::invalid_argument for noise lags
/// (ELS needs the residuals).
SelectionResult select_model(const NormalEquations& equations, std::vector<Index> ranking, const std::vector<Index>& kept,
                             const SelectionOptions& options);

}  // namespace inertia::ident
