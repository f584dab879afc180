#pragma once
// JointInverse's samples where the system is affine with one Jacobian for every sample and no
// filter state (a linear unit: bias, scale, cross-axis, g-sensitivity and temperature terms):
//
//   g_m(x) = A_m x + b_m(k),   x = -A^-1 b(k),
//
// so each sample stands alone. The samples go a few at a time, side by side in one SIMD register
// (kLanes of them): b, x, each solved row's value, the coefficients' derivatives and a' C a are
// then each one register, and the whole sample's arithmetic runs from registers and the stack
// instead of streaming rows of a block through the cache. The arithmetic per sample, and its
// order, is that of JointInverse's per-sample formulas (joint_inverse.hpp): x = -A^-1 b, the
// uncertainty's a' C a from C's upper triangle, and each unknown's variances through the
// inverse's entries squared.
#include <Eigen/Core>

#include <utility>
#include <vector>

#include "analyzer/compensate/joint_inverse.hpp"

namespace inertia::compensate {

/// One equation of the affine system, as JointInverse compiled it.
struct AffineEquation {
  /// A known input read at the sample minus `factor.lag`: `column` is its samples.
  struct KnownFactor {
    ident::Factor factor;
    const double* column = nullptr;
  };
  /// A term whose known part changes from sample to sample: coefficient times the product of its
  /// factors, divided through by the output when `over_y` (eq. 5's denominator).
  struct VaryingTerm {
    Eigen::Index term = 0;
    double coefficient = 0.0;
    bool over_y = false;
    std::vector<KnownFactor> factors;
  };
  /// The range check of a solved row's value (`solved` >= 0) or of a known input's samples.
  struct Bound {
    Eigen::Index solved = -1;
    const double* column = nullptr;
    double lowest = 0.0, highest = 0.0;
  };

  const double* y = nullptr;
  double constant_b = 0.0;                  // the constant terms' share of b
  std::vector<VaryingTerm> varying;
  /// Terms c row . x: (term, solved row); their derivative by c is the row's value.
  std::vector<std::pair<Eigen::Index, Eigen::Index>> row_terms;
  std::vector<Eigen::Index> unit_terms;     // constant terms: derivative 1
  Eigen::MatrixXd rows;                     // the solved rows, one per solved input, over the unknowns
  Eigen::MatrixXd covariance;               // the coefficients', over the model's terms
  double noise_sd = 0.0;
  std::vector<Bound> bounds;
};

/// Fills rows [first_row, n) of `out` (already sized: value, u_coefficients, u_noise, flag) for
/// unknowns D in {1, 3, 6}. `inverse` is A^-1; where A is singular (`invertible` false) or a
/// sample's b is not finite, the row is NaN and flagged NotConverged; an input outside its bound,
/// OutsideRange.
template <int D>
void solve_affine_samples(const std::vector<AffineEquation>& equations, const Eigen::Matrix<double, D, D>& inverse, bool invertible,
                          Eigen::Index first_row, Eigen::Index n, JointCompensation& out);

}  // namespace inertia::compensate
