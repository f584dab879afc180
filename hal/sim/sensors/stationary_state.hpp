#pragma once
// Stationary start of a linear noise filter. A coloured-noise filter started from zero state
// has less variance than its stationary output for several time constants (for 1/f noise down to
// 0.01 Hz, minutes): the first minutes of a simulated test would be quieter than the rest. We
// draw the initial state from the stationary distribution instead, so every sample has the
// requested statistics.
#include <Eigen/Dense>

#include "hal/sim/sensors/gaussian_source.hpp"

namespace inertia::sim {

/// P = sum_k A^k B B' A'^k, the solution of P = A P A' + B B' for s(k+1) = A s(k) + B w(k) with
/// w white of unit variance. Doubling (Smith's) iteration: after j steps the sum holds 2^j terms,
/// so poles within 1e-6 of the unit circle need only ~25 iterations. Throws
/// std::invalid_argument when A is not stable (the sum does not converge within 64 doublings).
Eigen::MatrixXd stationary_covariance(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

/// One draw of N(0, P) (P symmetric positive semi-definite; eigen-decomposition rather than
/// Cholesky because P is often singular, e.g. for a filter with fewer inputs than states).
Eigen::VectorXd draw_gaussian(const Eigen::MatrixXd& p, GaussianSource& gauss);

}  // namespace inertia::sim
