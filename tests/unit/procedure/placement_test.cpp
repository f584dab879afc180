// What the fixture's placement adds to a mounting's sensitivities (procedure/placement.hpp): the
// first-order covariance against the spread of least-squares fits over drawn placements, and the
// rule that a case of one cluster adds nothing.
#include "analyzer/procedure/placement.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "common/frames.hpp"

namespace inertia::procedure {
namespace {

/// A case's inputs in its nominal frame: `n` samples of the rate `rate` (rad/s, case coordinates)
/// scaled by each of `levels` in turn, as a spin case's phases.
Eigen::MatrixX3d spin(const Eigen::Vector3d& axis, const std::vector<double>& levels, int n) {
  Eigen::MatrixX3d x(static_cast<Eigen::Index>(levels.size()) * n, 3);
  for (std::size_t l = 0; l < levels.size(); ++l)
    for (int k = 0; k < n; ++k) x.row(static_cast<Eigen::Index>(l) * n + k) = levels[l] * axis.transpose();
  return x;
}

Eigen::Matrix4d gram_of(const Eigen::MatrixX3d& x) {
  Eigen::MatrixXd r(x.rows(), 4);
  r.leftCols(3) = x;
  r.col(3).setOnes();
  return r.transpose() * r;
}

TEST(Placement, FirstOrderCovarianceIsTheSpreadOfTheFitOverDrawnPlacements) {
  // A gyroscope's mounting: three spin cases, one per case axis, each at four rates (four
  // clusters), placed within 0.2 mrad each. Its output y = theta . w_true + b is fitted on the
  // nominal rates with a bias: over 4000 drawn placements the fits' covariance against the first
  // order one. An sd from N draws scatters by 1 / sqrt(2 N) (1.1 %): 5 % is 4.5 of those.
  const std::vector<double> rates = {0.52, -0.52, 1.57, -1.57};
  const std::vector<Eigen::MatrixX3d> cases = {spin(Eigen::Vector3d::UnitX(), rates, 50), spin(Eigen::Vector3d::UnitY(), rates, 50),
                                               spin(Eigen::Vector3d::UnitZ(), rates, 50)};
  const Eigen::Vector3d theta(1.01, 2e-3, -1.5e-3);
  const double sd = 2e-4, bias = 3e-3;
  std::vector<CasePlacement> placements;
  for (const Eigen::MatrixX3d& x : cases) placements.push_back({gram_of(x), sd, rates.size()});
  const Eigen::Matrix3d predicted = placement_covariance(theta, placements, true);

  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  constexpr int kDraws = 4000;
  Eigen::MatrixXd fits(kDraws, 3);
  for (int d = 0; d < kDraws; ++d) {
    Eigen::MatrixXd r(0, 4);
    Eigen::VectorXd y(0);
    for (const Eigen::MatrixX3d& x : cases) {
      const Eigen::Vector3d delta(sd * normal(rng), sd * normal(rng), sd * normal(rng));
      const Eigen::Matrix3d turn = frames::frame_rotation(delta.normalized(), delta.norm());
      const Eigen::Index at = r.rows();
      r.conservativeResize(at + x.rows(), 4);
      y.conservativeResize(at + x.rows());
      r.block(at, 0, x.rows(), 3) = x;
      r.block(at, 3, x.rows(), 1).setOnes();
      y.segment(at, x.rows()) = (x * turn.transpose()) * theta + Eigen::VectorXd::Constant(x.rows(), bias);
    }
    fits.row(d) = r.colPivHouseholderQr().solve(y).head(3).transpose();
  }
  const Eigen::MatrixXd centered = fits.rowwise() - fits.colwise().mean();
  const Eigen::MatrixXd drawn = centered.transpose() * centered / (kDraws - 1.0);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(std::sqrt(predicted(a, a)) / std::sqrt(drawn(a, a)), 1.0, 0.05) << a;
  // The two cross-axis sensitivities move by the scale times the placement; the scale factor only
  // by the cross-axis ones times it (a turn moves the axis, not its length).
  for (int a = 1; a < 3; ++a) EXPECT_NEAR(std::sqrt(predicted(a, a)), theta(0) * sd, 0.02 * theta(0) * sd) << a;
  EXPECT_LE(std::sqrt(predicted(0, 0)), 1.01 * theta.tail(2).norm() * sd);
}

TEST(Placement, ACaseOfOneClusterOrWithoutAStatedSdAddsNothing) {
  const std::vector<double> rates = {0.52, -0.52};
  const Eigen::Matrix4d g = gram_of(spin(Eigen::Vector3d::UnitY(), rates, 20));
  const Eigen::Vector3d theta(1.0, 0.0, 0.0);
  const std::vector<CasePlacement> one_cluster = {{g, 1e-3, 1}};
  EXPECT_TRUE(placement_covariance(theta, one_cluster, true).isZero());
  const std::vector<CasePlacement> exact = {{g, 0.0, 2}};
  EXPECT_TRUE(placement_covariance(theta, exact, true).isZero());
  const std::vector<CasePlacement> placed = {{g, 1e-3, 2}};
  EXPECT_FALSE(placement_covariance(theta, placed, true).isZero());
}

}  // namespace
}  // namespace inertia::procedure
