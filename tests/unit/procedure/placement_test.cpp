// What the fixture's placement adds to a mounting's sensitivities (procedure/placement.hpp): the
// first-order covariance against the spread of least-squares fits over drawn placements, for a
// gyroscope's spin cases and for a six-position tumble's poses, and the rule that a case without
// a stated accuracy adds nothing. The placements' columns of R (placement_columns)
// against their closed form: the odd part of a turn by +-s about e_k is sin(s) e_k x.
#include "analyzer/procedure/placement.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "analyzer/ident/term.hpp"

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

/// The covariance of the sensitivities a least-squares fit (with a bias) reads from `cases` when
/// each case is turned by its own drawn placement (sd per axis): y = theta . a_true + bias,
/// fitted on the nominal inputs, over 4000 draws.
Eigen::Matrix3d drawn_covariance(const std::vector<Eigen::MatrixX3d>& cases, const Eigen::Vector3d& theta, double sd, double bias) {
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
  return centered.transpose() * centered / (kDraws - 1.0);
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
  for (const Eigen::MatrixX3d& x : cases) placements.push_back({gram_of(x), sd});
  const Eigen::Matrix3d predicted = placement_covariance(theta, placements, true);

  const Eigen::Matrix3d drawn = drawn_covariance(cases, theta, sd, bias);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(std::sqrt(predicted(a, a)) / std::sqrt(drawn(a, a)), 1.0, 0.05) << a;
  // The two cross-axis sensitivities move by the scale times the placement; the scale factor only
  // by the cross-axis ones times it (a turn moves the axis, not its length).
  for (int a = 1; a < 3; ++a) EXPECT_NEAR(std::sqrt(predicted(a, a)), theta(0) * sd, 0.02 * theta(0) * sd) << a;
  EXPECT_LE(std::sqrt(predicted(0, 0)), 1.01 * theta.tail(2).norm() * sd);
}

TEST(Placement, ASixPositionTumblesPosesEachAddTheirPlacement) {
  // An accelerometer's six poses, +-g along each case axis, one cluster each, placed within 3 mrad
  // (sim-tumble's): a pose's tilt moves the fit's sensitivities (the cross-axis ones by the scale
  // times the tilt), which the offsets between six pose means on 2 dof cannot show. The first
  // order against 4000 drawn placements, within 5 % (4.5 of an sd's scatter over the draws).
  const double g = 9.80665, sd = 3e-3, bias = 2.5e-3;
  std::vector<Eigen::MatrixX3d> poses;
  for (int axis = 0; axis < 3; ++axis)
    for (const double sign : {1.0, -1.0}) poses.push_back(spin(Eigen::Vector3d::Unit(axis), {sign * g}, 30));
  const Eigen::Vector3d theta(0.102, 6e-5, -7e-5);
  std::vector<CasePlacement> placements;
  for (const Eigen::MatrixX3d& x : poses) placements.push_back({gram_of(x), sd});
  const Eigen::Matrix3d predicted = placement_covariance(theta, placements, true);
  const Eigen::Matrix3d drawn = drawn_covariance(poses, theta, sd, bias);
  // The cross-axis sensitivities, which the angles are read from: each from its own up and down
  // poses, the scale times the two poses' tilts about the third axis averaged (k sd / sqrt(2)).
  for (int a = 1; a < 3; ++a) {
    EXPECT_NEAR(std::sqrt(predicted(a, a)) / std::sqrt(drawn(a, a)), 1.0, 0.05) << a;
    EXPECT_NEAR(std::sqrt(predicted(a, a)), theta(0) * sd / std::sqrt(2.0), 0.02 * theta(0) * sd) << a;
  }
  // The scale factor: a vertical pose's tilt shortens its input by 1 - cos, second order, which
  // the first order leaves out; both are below 1e-5 of the scale here (the noise's share on a
  // bench is larger).
  EXPECT_LT(std::sqrt(drawn(0, 0)), 1e-5 * theta(0));
  EXPECT_LT(std::sqrt(predicted(0, 0)), std::sqrt(drawn(0, 0)));
}

TEST(Placement, ACaseWithoutAStatedSdAddsNothing) {
  const std::vector<double> rates = {0.52, -0.52};
  const Eigen::Matrix4d g = gram_of(spin(Eigen::Vector3d::UnitY(), rates, 20));
  const Eigen::Vector3d theta(1.0, 0.0, 0.0);
  const std::vector<CasePlacement> exact = {{g, 0.0}};
  EXPECT_TRUE(placement_covariance(theta, exact, true).isZero());
  const std::vector<CasePlacement> placed = {{g, 1e-3}};
  EXPECT_FALSE(placement_covariance(theta, placed, true).isZero());
}

/// A case of `rows` samples of the specific force `a` (case frame = F_E), placed within `sd`.
dataset::CaseData placed_case(const std::string& name, const Eigen::Vector3d& a, Eigen::Index rows, double sd,
                              const std::string& piece_of = "") {
  dataset::CaseData c;
  c.name = name;
  c.piece_of = piece_of;
  c.placement_sd_rad = sd;
  c.sample_period_s = 0.01;
  c.t = Eigen::VectorXd::LinSpaced(rows, 0.0, 0.01 * static_cast<double>(rows - 1));
  c.a_e = a.transpose().replicate(rows, 1);
  c.y = Eigen::VectorXd::Zero(rows);
  return c;
}

TEST(Placement, ColumnsAreWhatEachCasesTurnMovesThePredictionAndPiecesTurnTogether) {
  dataset::Dataset data;
  data.t_ref = 20.0;
  const double g = 9.80665, sd = 3e-4;
  const Eigen::Vector3d level(0.0, g, 0.0), up(g, 0.0, 0.0), tilted(0.0, 0.6 * g, 0.8 * g);
  data.cases = {placed_case("level", level, 5, sd), placed_case("fixed", up, 4, 0.0),
                placed_case("spin-1", tilted, 3, 2.0 * sd, "spin"), placed_case("spin-2", tilted, 6, 2.0 * sd, "spin")};
  const std::vector<StatedPlacement> placements = stated_placements(data);
  ASSERT_EQ(placements.size(), 2u);   // "fixed" states none; the spin's two pieces are one placement
  EXPECT_EQ(placements[1].pieces, (std::vector<std::size_t>{2, 3}));
  const std::vector<ident::Term> terms = ident::parse_terms({"a_i", "a_p", "1"});
  const Eigen::Vector3d theta(1.01, 2e-3, 0.05);
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < data.cases.size(); ++i) inputs.push_back({i, &data.cases[i], Eigen::Matrix3d::Identity(), 1.0, {}});
  const Eigen::MatrixXd p = placement_columns(terms, theta, inputs, placements, data, "test", 0, std::nullopt, ArWhitener());
  ASSERT_EQ(p.rows(), 18);
  ASSERT_EQ(p.cols(), 6);
  const Eigen::Vector3d linear(theta(0), theta(1), 0.0);   // a_i, a_p; the bias does not turn
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(axis);
    const double level_move = std::sin(sd) * linear.dot(e.cross(level));
    const double spin_move = std::sin(2.0 * sd) * linear.dot(e.cross(tilted));
    EXPECT_TRUE(p.col(axis).head(5).isApproxToConstant(level_move, 1e-9)) << axis;
    EXPECT_TRUE(p.col(axis).tail(13).isZero()) << axis;
    EXPECT_TRUE(p.col(3 + axis).head(9).isZero()) << axis;
    for (Eigen::Index r = 9; r < 18; ++r) EXPECT_NEAR(p(r, 3 + axis), spin_move, 1e-12) << axis << " row " << r;
  }
  // A turn about the input axis itself moves nothing; about o it moves a_i by the level case's g.
  EXPECT_NEAR(p(0, 0), 0.0, 1e-15);
  EXPECT_NEAR(std::abs(p(0, 2)), std::sin(sd) * theta(0) * g, 1e-12);
  // Whitened: the columns through the whitener, row for row as its stack's.
  const ArWhitener whitener = ArWhitener::of(Eigen::VectorXd::Constant(1, 0.5));
  Eigen::MatrixXd expected = p;
  whitener.apply_to_columns(expected, stack_layout(terms, inputs));
  EXPECT_TRUE(placement_columns(terms, theta, inputs, placements, data, "test", 0, std::nullopt, whitener).isApprox(expected));
  // A placement none of whose pieces the stack holds has no columns.
  const std::vector<StackInput> fixed_only = {inputs[1]};
  EXPECT_EQ(placement_columns(terms, theta, fixed_only, placements, data, "test", 0, std::nullopt, ArWhitener()).cols(), 0);
}

}  // namespace
}  // namespace inertia::procedure
