#include "hal/sim/sensors/stationary_state.hpp"

#include <cmath>
#include <stdexcept>

namespace inertia::sim {

Eigen::MatrixXd stationary_covariance(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::MatrixXd p = b * b.transpose();
  Eigen::MatrixXd ak = a;
  for (int j = 0; j < 64; ++j) {
    // Converged once the remaining terms A^k P A'^k (k >= 2^j) no longer change P in double.
    if (ak.cwiseAbs().maxCoeff() < 1e-18) return p;
    p += ak * p * ak.transpose();
    ak = ak * ak;
    if (!ak.allFinite()) break;
  }
  throw std::invalid_argument("stationary_covariance: the state matrix is not stable");
}

Eigen::VectorXd draw_gaussian(const Eigen::MatrixXd& p, GaussianSource& gauss) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(p);
  Eigen::VectorXd z(p.rows());
  for (Eigen::Index i = 0; i < z.size(); ++i) z(i) = gauss.next() * std::sqrt(std::max(eig.eigenvalues()(i), 0.0));
  return eig.eigenvectors() * z;
}

}  // namespace inertia::sim
