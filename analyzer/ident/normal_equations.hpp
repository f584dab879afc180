#pragma once
// The normal equations of a regression y = Phi theta + e, and the rules that decide what its data
// determine, written once for the offline procedure, the live estimator and diagnose.
//
// NormalEquations holds what a least-squares rule needs of the data: the augmented Gram matrix
// [Phi y]'[Phi y] (y last), the number of rows, the columns' names and, for output-multiplied
// columns, the sums of their factors that ULS's correction needs (uls_batch.hpp). The offline
// procedure and diagnose build it from rows (from_rows); the live estimator from the information
// matrices it accumulates (the constructor), without a pass over samples.
//
// The rules on it:
//  - rank_identifiable: the sensor's own sensitivities first, then the bias, then the caller's
//    nuisance columns, the rest by ERR (eq. 8, relative to the energy the forced columns leave);
//    a column the data cannot separate from those before it is not ranked but named.
//  - fit_identifiable: the fit of ranked columns that, when ULS names a near-dependence, lets go
//    the named column ranked last that is not a sensitivity, records it and fits again. The
//    caller's solver decides what a fit is (ULS on rows with residuals offline, ULS on these
//    statistics live): the rule does not.
#include <Eigen/Dense>

#include <algorithm>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::ident {

/// Whether `label` is one of `sensor`'s own sensitivities (scale-factor terms): a_x a_y a_z a_i of
/// an accelerometer, w_x w_y w_z w_i of a gyroscope. A gyroscope's a_* are g-sensitivities, ranked
/// and tested like any other term. Every fit ranks the sensitivities first and never lets them
/// go: a model without its scale factor is no model.
[[nodiscard]] bool is_sensitivity_label(std::string_view label, dataset::SensorKind sensor);

/// Whether a term is never pruned from `sensor`'s model: its sensitivities and the bias.
[[nodiscard]] inline bool never_pruned(std::string_view label, dataset::SensorKind sensor) {
  return label == "1" || is_sensitivity_label(label, sensor);
}

/// The columns every fit of `sensor`'s model ranks first: its sensitivities among `labels`, in
/// column order, then the bias ("1").
[[nodiscard]] std::vector<Index> sensitivities_then_bias(const std::vector<std::string>& labels,
                                                         dataset::SensorKind sensor);

class NormalEquations {
 public:
  /// `augmented`: [Phi y]'[Phi y], (p+1) x (p+1), y last, over `samples` rows. For the
  /// output-multiplied columns (positions into 0..p-1): `factor_gram` = sum p_b p_b' and
  /// `factor_sum` = sum p_b, in the order of `output_multiplied` (UlsStatistics::from_gram).
  NormalEquations(Eigen::MatrixXd augmented, Index samples, std::vector<std::string> labels,
                  std::vector<Index> output_multiplied = {}, Eigen::MatrixXd factor_gram = Eigen::MatrixXd(),
                  Eigen::VectorXd factor_sum = Eigen::VectorXd());
  /// From rows: one O(N p^2) pass. The factors of output-multiplied columns are rational.factors,
  /// or c_j / y when not given (denominator_factors).
  static NormalEquations from_rows(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                                   std::vector<std::string> labels, const OutputMultiplied& rational = OutputMultiplied());

  [[nodiscard]] Index columns() const { return static_cast<Index>(labels_.size()); }
  [[nodiscard]] Index samples() const { return samples_; }
  [[nodiscard]] const std::vector<std::string>& labels() const { return labels_; }
  [[nodiscard]] const Eigen::MatrixXd& augmented() const { return augmented_; }
  [[nodiscard]] const std::vector<Index>& output_multiplied() const { return output_multiplied_; }
  /// sum p_b p_b' and sum p_b of the output-multiplied columns' factors, in output_multiplied()'s order.
  [[nodiscard]] const Eigen::MatrixXd& factor_gram() const { return factor_gram_; }
  [[nodiscard]] const Eigen::VectorXd& factor_sum() const { return factor_sum_; }

  /// The successive differences' augmented Gram matrix [dPhi dy]'[dPhi dy], each row less the row
  /// before it within a stretch of contiguous rows, over `pairs` differenced rows: what step 12's
  /// lag-1 correlation reads of the residual of any coefficients (statistics.hpp). Held only when
  /// given (pairs 0: not held).
  void set_successive_differences(Eigen::MatrixXd augmented, Index pairs);
  /// The same from rows: `stretch_starts` the first row of each stretch after the first (empty: one).
  void set_successive_differences(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                                  std::span<const Index> stretch_starts = {});
  [[nodiscard]] const Eigen::MatrixXd& difference_augmented() const { return difference_augmented_; }
  [[nodiscard]] Index difference_pairs() const { return difference_pairs_; }

  /// The augmented Gram matrix of the columns `positions` (any order), y last.
  [[nodiscard]] Eigen::MatrixXd augmented(std::span<const Index> positions) const;
  /// ULS's sufficient statistics of the columns `positions` (ascending), factor sums included.
  [[nodiscard]] UlsStatistics statistics(std::span<const Index> positions) const;

 private:
  Eigen::MatrixXd augmented_;
  Index samples_ = 0;
  std::vector<std::string> labels_;
  std::vector<Index> output_multiplied_;
  Eigen::MatrixXd factor_gram_;
  Eigen::VectorXd factor_sum_;
  Eigen::MatrixXd difference_augmented_;
  Index difference_pairs_ = 0;
};

struct IdentifiableRanking {
  std::vector<Index> order;       ///< columns, forced ones first, then by ERR
  std::vector<Index> dependent;   ///< columns the data cannot separate from those ranked before them
};

/// The ranking described above. `base` gives the ERR options but the forced columns, the
/// reference and the preferred columns, which this rule sets: a temperature term at a lag
/// (T[k-1]) ranks before its unlagged form (T) only when it explains more of the output by the
/// chi-square(1) quantile at `kLagTieLevel` times the noise variance (the F test of their
/// difference, sigma^2 from the residual of every candidate), and is not ranked at all when, once
/// its unlagged form is selected, it explains less than that. A temperature moves slowly against
/// the sample rate: the two columns are nearly one, and the data's noise would otherwise pick one
/// at random. Motion inputs' lags are the model's dynamics and rank by ERR alone.
inline constexpr double kLagTieLevel = 0.01;

[[nodiscard]] IdentifiableRanking rank_identifiable(const NormalEquations& equations, dataset::SensorKind sensor,
                                                    const ErrOptions& base = ErrOptions(),
                                                    std::span<const Index> nuisance = {});

/// The fit of `ranked` (columns in ranked order) by `solve(columns)` (columns ascending, as ULS
/// takes them): when it throws IdentifiabilityError, the named column ranked last that is not one
/// of `sensor`'s sensitivities leaves `ranked` and is appended to `left`, and the fit is repeated.
/// Rethrows when the error names sensitivities only.
template <class Solve>
auto fit_identifiable(std::vector<Index>& ranked, const std::vector<std::string>& labels, dataset::SensorKind sensor,
                      std::vector<Index>& left, Solve&& solve) {
  for (;;) {
    std::vector<Index> ascending = ranked;
    std::sort(ascending.begin(), ascending.end());
    try {
      return solve(std::span<const Index>(ascending));
    } catch (const IdentifiabilityError& e) {
      std::vector<std::string> ranked_labels;
      ranked_labels.reserve(ranked.size());
      for (const Index j : ranked) ranked_labels.push_back(labels[static_cast<std::size_t>(j)]);
      const auto leaves =
          column_to_leave(e, ranked_labels, [&](std::size_t j) { return is_sensitivity_label(ranked_labels[j], sensor); });
      if (!leaves) throw;
      const auto victim = ranked.begin() + static_cast<std::ptrdiff_t>(*leaves);
      left.push_back(*victim);
      ranked.erase(victim);
    }
  }
}

}  // namespace inertia::ident
