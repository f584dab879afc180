#include "analyzer/procedure/placement.hpp"

namespace inertia::procedure {

Eigen::Matrix3d placement_covariance(const Eigen::Vector3d& theta, std::span<const CasePlacement> cases, bool with_bias) {
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  const Eigen::Index n = with_bias ? 4 : 3;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(n, n);
  bool any = false;
  for (const CasePlacement& c : cases) {
    gram += c.gram.topLeftCorner(n, n);
    any = any || (c.sd_rad > 0.0 && c.clusters > 1);
  }
  if (!any) return covariance;
  // An axis the mounting does not excite leaves G singular: the pseudo-inverse answers for the rest
  // (the held angle gets the mounting tolerance instead).
  const Eigen::MatrixXd g_inverse = gram.completeOrthogonalDecomposition().pseudoInverse();
  Eigen::Matrix3d cross;
  cross << 0.0, -theta(2), theta(1), theta(2), 0.0, -theta(0), -theta(1), theta(0), 0.0;
  for (const CasePlacement& c : cases) {
    if (!(c.sd_rad > 0.0 && c.clusters > 1)) continue;
    const Eigen::MatrixXd h = c.gram.topLeftCorner(n, 3);   // sum of r a'
    const Eigen::Matrix3d j = (g_inverse * h * cross).topRows(3);
    covariance += c.sd_rad * c.sd_rad * j * j.transpose();
  }
  return covariance;
}

}  // namespace inertia::procedure
