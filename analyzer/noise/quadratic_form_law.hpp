#pragma once
// The distribution of a Gaussian quadratic form x'Ax, x ~ N(0, R): a weighted sum of independent
// chi-squares sum_i lambda_i chi2_1, lambda the eigenvalues of A R.
//
// Under noise whose power sits in a few slow modes (flicker across the whole band, or a short
// stretch of it) a handful of lambdas dominate. The scaled chi-square that matches the mean and
// variance alone (Satterthwaite) then puts the upper tail too light: for weights 10, 3, 1, 0.3 on
// two dof each it gives 4.9e-8 where the truth is 5.0e-7. On diagnose's pink-noise shaker
// scenario that made segments fall below the Bonferroni threshold more often than expected
// (docs/validation.md, 'Evidence behind choices in the code').
//
// Here the leading eigenvalues are kept as they are, and the rest (many and small) are one scaled
// chi-square matched on their mean and variance. The tail comes from the saddlepoint
// approximation of Lugannani and Rice (D. Kuonen, "Saddlepoint approximations for distributions
// of quadratic forms in normal variables", Biometrika 86(4), 1999), within a few percent of p far
// into the tail.
#include <Eigen/Dense>

namespace inertia::noise {

struct QuadraticFormLaw {
  Eigen::VectorXd leading;   // lambda_i > 0, kept exactly
  double rest_scale = 0.0;   // the rest: rest_scale * chi2(rest_dof)
  double rest_dof = 0.0;

  /// From the form's leading eigenvalues and the trace and sum of squares of all of them (tr(AR),
  /// tr(ARAR)): the rest matched on what the leading ones leave of both.
  static QuadraticFormLaw from(const Eigen::VectorXd& leading, double trace, double trace_of_square);

  [[nodiscard]] double mean() const;
  [[nodiscard]] double variance() const;
  /// P(x'Ax > q); 1 for q <= 0.
  [[nodiscard]] double upper_tail(double q) const;
};

}  // namespace inertia::noise
