#pragma once
// Generalized least squares for coloured noise by autoregressive prewhitening (iterated
// Cochrane-Orcutt). A sensor's noise is rarely white: the paper's simulated accelerometer carries
// pink (1/f) noise fifteen times stronger than its white noise. Ordinary least squares then stays
// unbiased but wastes most of the data (the 1/f power sits exactly where slow test motions
// are), and its classical covariance is far too small, so t-tests pass spurious terms and AIC
// prefers large models. Fitting A(q) to the residuals and filtering the output and every column,
//     A(q) y = A(q) Phi theta + white,
// gives the efficient estimate with honest standard deviations. This is the noise model of the
// paper's eqs. 2 and 4 (v(k) coloured) in its autoregressive form; the MA form stays available in
// ULS (noise lags) for models that need it.
#include <Eigen/Dense>
#include <algorithm>
#include <utility>
#include <vector>

#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::procedure {

class ArWhitener {
 public:
  /// The identity (no filtering).
  ArWhitener() = default;

  /// A(q) of the coefficients a_1..a_m (a model fitted before, as PipelineResult::whitening).
  static ArWhitener of(Eigen::VectorXd coefficients) {
    ArWhitener w;
    w.a_ = std::move(coefficients);
    return w;
  }

  /// Fits A(q) = 1 - a_1 q^-1 - ... - a_m q^-m to `residuals` (the stacked rows of `layout`;
  /// autocovariances are summed within cases only) by Levinson-Durbin, with the order chosen by
  /// AIC among 0..max_order. Order 0 (white residuals) gives the identity.
  static ArWhitener fit(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout, int max_order);

  [[nodiscard]] int order() const { return static_cast<int>(a_.size()); }
  [[nodiscard]] const Eigen::VectorXd& coefficients() const { return a_; }
  /// Innovation variance / residual variance: the share of the residual power left after whitening.
  [[nodiscard]] double variance_ratio() const { return variance_ratio_; }

  /// Filters y and every column in place, case by case; each case loses its first order() rows
  /// (their filtered values would need samples from before the case). Updates s.cases.
  void apply(StackedRegression& s) const;

  /// The same filter on the columns of x alone, rows laid out as `cases` (a stacked regression's):
  /// x keeps the rows apply() keeps, in the same order.
  void apply_to_columns(Eigen::MatrixXd& x, const std::vector<CaseRows>& cases) const;

 private:
  Eigen::VectorXd a_;
  double variance_ratio_ = 1.0;
};

/// Whether a model's rows go through its AR noise model. ULS's correction for output-multiplied
/// terms (the y* columns of eq. 5) is derived for a white equation error, and filtering such a
/// column breaks it: the estimate is biased by more than its spread. A model with such terms keeps
/// its rows unfiltered, and the same noise model enters its covariance instead (the batch: the
/// sandwich under the noise's spectrum; live and diagnose: unfiltered_long_run_ratio). The batch and the live
/// estimator both ask here.
inline bool filters_rows(bool output_multiplied_terms) { return !output_multiplied_terms; }

/// One column of the filter below: out[r] = x[r + m] - sum_j a_j x[r + m - j] for r < n (m =
/// a.size(); x holds n + m values). Rows are taken 16 at a time with their sums held in registers
/// over every lag, one load per lag instead of a load and a store of the partial sums: the filter
/// is the hot loop of the offline procedure (orders up to 120). Per row the operations are those
/// of the scalar loop, in the same order.
void ar_filter_column(const Eigen::VectorXd& a, const double* x, double* out, Eigen::Index n);

/// A(q) = 1 - sum a_j q^-j on the rows of `x` whose m = a.size() predecessors are in `x` too: row
/// r of `out` (x.rows() - m rows, resized when it can be) is x(r + m) - sum_j a_j x(r + m - j),
/// column by column. ArWhitener filters the stacked rows by it and the live estimator
/// (online/information.hpp) its segments, chunk by chunk.
template <class In, class Out>
void ar_filter(const Eigen::VectorXd& a, const Eigen::DenseBase<In>& x, Out&& out) {
  const Eigen::Index n = x.rows() - a.size();
  out.derived().resize(n, x.cols());
  for (Eigen::Index c = 0; c < x.cols(); ++c) {
    const Eigen::Ref<const Eigen::VectorXd> in = x.derived().col(c);
    Eigen::Ref<Eigen::VectorXd> to = out.derived().col(c);
    ar_filter_column(a, in.data(), to.data(), n);
  }
}

/// Levinson-Durbin on autocovariances acov(0..M) pooled over n samples, the AR order chosen by
/// AIC among 0..M: a_1..a_m of A(q) = 1 - sum a_j q^-j (empty: white, also when n < 10 M or
/// acov(0) <= 0). innovation_variance (optional) receives the chosen order's innovation variance.
/// ArWhitener::fit uses it on residuals; diagnose on autocovariances of quadratic forms.
Eigen::VectorXd ar_from_autocovariance(const Eigen::VectorXd& acov, double n, double* innovation_variance = nullptr);

}  // namespace inertia::procedure
