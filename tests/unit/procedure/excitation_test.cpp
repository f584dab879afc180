// What a mounting's excitation determines (procedure/excitation.hpp): the shares against a
// hand-worked four-sample example and against a least-squares projection on the samples, the
// verdicts on plans that do and do not excite an axis, the threshold, and the held angles' notes.
#include "analyzer/procedure/excitation.hpp"

#include <gtest/gtest.h>

#include <random>

namespace inertia::procedure {
namespace {

using Eigen::Index;

/// [a_IRA a_XRA a_YRA 1]'[a_IRA a_XRA a_YRA 1] summed sample by sample.
Eigen::Matrix4d gram_of(const Eigen::MatrixX3d& inputs) {
  Eigen::Matrix4d g = Eigen::Matrix4d::Zero();
  for (Index k = 0; k < inputs.rows(); ++k) {
    const Eigen::Vector4d r(inputs(k, 0), inputs(k, 1), inputs(k, 2), 1.0);
    g += r * r.transpose();
  }
  return g;
}

TEST(AxisExcitation, FourSamplesByHand) {
  // a_IRA = 2 0 2 0, a_XRA = 1 1 -1 -1, a_YRA = 0 0 1 1: total energy 8 + 4 + 2 = 14.
  Eigen::MatrixX3d a(4, 3);
  a << 2, 1, 0,
       0, 1, 0,
       2, -1, 1,
       0, -1, 1;
  const Eigen::Matrix4d g = gram_of(a);
  // With the bias: IRA about its mean is 1 -1 1 -1 (energy 4); XRA about its mean is orthogonal
  // to it (energy 4); YRA about its mean is -1/2 XRA's: nothing of its own.
  const AxisExcitation with = axis_excitation(g, true);
  EXPECT_NEAR(with.share[0], 4.0 / 14.0, 1e-15);
  EXPECT_NEAR(with.share[1], 4.0 / 14.0, 1e-15);
  EXPECT_NEAR(with.share[2], 0.0, 1e-15);
  EXPECT_TRUE(with.determined[0]);
  EXPECT_TRUE(with.determined[1]);
  EXPECT_FALSE(with.determined[2]);
  EXPECT_TRUE(with.aligns());
  EXPECT_FALSE(with.all_determined());
  // Without it: IRA whole (8); XRA . IRA = 0 (4); YRA less its projections 2/8 IRA and -2/4 XRA
  // is 0 1/2 0 1/2 (energy 1/2).
  const AxisExcitation without = axis_excitation(g, false);
  EXPECT_NEAR(without.share[0], 8.0 / 14.0, 1e-15);
  EXPECT_NEAR(without.share[1], 4.0 / 14.0, 1e-15);
  EXPECT_NEAR(without.share[2], 0.5 / 14.0, 1e-15);
  EXPECT_TRUE(without.all_determined());
}

/// The share of each axis by projection on the samples: the axis's residual after a QR
/// least-squares fit on the bias (when asked) and the determined axes before it.
std::array<double, 3> projected_shares(const Eigen::MatrixX3d& a, bool with_bias) {
  const double total = a.squaredNorm();
  std::array<double, 3> out{};
  Eigen::MatrixXd kept(a.rows(), 0);
  if (with_bias) kept = Eigen::MatrixXd::Ones(a.rows(), 1);
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::VectorXd r = a.col(axis);
    if (kept.cols() > 0) r -= kept * kept.colPivHouseholderQr().solve(r);
    out[static_cast<std::size_t>(axis)] = r.squaredNorm() / total;
    if (out[static_cast<std::size_t>(axis)] >= kMinExcitationShare) {
      kept.conservativeResize(Eigen::NoChange, kept.cols() + 1);
      kept.col(kept.cols() - 1) = a.col(axis);
    }
  }
  return out;
}

TEST(AxisExcitation, SharesAreTheProjectionsOnTheSamples) {
  std::mt19937_64 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixX3d a(2000, 3);
  // Correlated axes about a mean (a tilted table sweep): every axis has some energy of its own.
  for (Index k = 0; k < a.rows(); ++k) {
    const double u = g(rng), v = g(rng), w = g(rng);
    a.row(k) << 3.0 + u, 0.5 * u + v, -1.0 + 0.2 * u - 0.3 * v + 0.1 * w;
  }
  for (const bool with_bias : {true, false}) {
    const AxisExcitation e = axis_excitation(gram_of(a), with_bias);
    const std::array<double, 3> expected = projected_shares(a, with_bias);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_NEAR(e.share[i], expected[i], 1e-10 * expected[i]) << "axis " << i << " bias " << with_bias;
      EXPECT_TRUE(e.determined[i]);
    }
  }
}

TEST(AxisExcitation, OneStaticPoseIsABias) {
  // Gravity along IRA, the references' noise on every axis (sd 1e-4 g): with the bias estimated
  // nothing varies on its own; with a known bias the constant is the scale factor's input.
  constexpr double kG = 9.80665;
  std::mt19937_64 rng(22);
  std::normal_distribution<double> noise(0.0, 1e-4 * kG);
  Eigen::MatrixX3d a(3000, 3);
  for (Index k = 0; k < a.rows(); ++k) a.row(k) << kG + noise(rng), noise(rng), noise(rng);
  const AxisExcitation with = axis_excitation(gram_of(a), true);
  EXPECT_FALSE(with.scale_determined());
  EXPECT_FALSE(with.aligns());
  EXPECT_LT(with.share[0], 1e-6);
  const AxisExcitation without = axis_excitation(gram_of(a), false);
  EXPECT_TRUE(without.scale_determined());
  EXPECT_NEAR(without.share[0], 1.0, 1e-6);
  EXPECT_FALSE(without.determined[1]) << "noise of 1e-4 g is 1e-8 of the energy";
  EXPECT_FALSE(without.determined[2]);
  EXPECT_FALSE(without.aligns());
}

TEST(AxisExcitation, OneAxisShakerExcitesOneAxis) {
  // Vibration along IRA and YRA together (the shaker's one axis between them), gravity along XRA.
  std::mt19937_64 rng(23);
  std::normal_distribution<double> v(0.0, 30.0);
  Eigen::MatrixX3d a(3000, 3);
  for (Index k = 0; k < a.rows(); ++k) {
    const double s = v(rng);
    a.row(k) << s, 9.80665, 0.5 * s;
  }
  const AxisExcitation e = axis_excitation(gram_of(a), true);
  EXPECT_TRUE(e.determined[0]);
  EXPECT_FALSE(e.determined[1]) << "a constant is the bias's";
  EXPECT_FALSE(e.determined[2]) << "the same vibration as IRA";
  EXPECT_FALSE(e.aligns());
  EXPECT_LT(e.share[1], 1e-12);
  EXPECT_LT(e.share[2], 1e-12);
}

TEST(AxisExcitation, ThresholdIsTheShareOfTheEnergy) {
  // diag(1, s, 0) without the bias: XRA's share is s / (1 + s).
  const auto verdict = [](double share) {
    const double s = share / (1.0 - share);
    Eigen::Matrix4d g = Eigen::Matrix4d::Zero();
    g(0, 0) = 1.0;
    g(1, 1) = s;
    g(3, 3) = 10.0;
    return axis_excitation(g, false);
  };
  EXPECT_TRUE(verdict(1.01 * kMinExcitationShare).determined[1]);
  EXPECT_FALSE(verdict(0.99 * kMinExcitationShare).determined[1]);
  EXPECT_NEAR(verdict(0.5).share[1], 0.5, 1e-15);
  const AxisExcitation none = axis_excitation(Eigen::Matrix4d::Zero(), true);
  EXPECT_FALSE(none.determined[0] || none.determined[1] || none.determined[2]) << "no input at all";
}

TEST(HeldAngleNotes, OneNotePerHeldAngle) {
  AxisExcitation e;
  e.determined = {true, true, true};
  EXPECT_TRUE(held_angle_notes(e, false, true).empty());

  e.determined = {true, true, false};   // aligned, YRA held: the angle about p
  std::vector<std::string> notes = held_angle_notes(e, false, true);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("angle about p"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find(missing_excitation(2, false)), std::string::npos) << notes[0];

  e.determined = {true, false, false};   // no tilt: both angles held
  notes = held_angle_notes(e, true, true);
  ASSERT_EQ(notes.size(), 2u);
  EXPECT_NE(notes[0].find(missing_excitation(1, true)), std::string::npos) << notes[0];
  EXPECT_NE(notes[1].find(missing_excitation(2, true)), std::string::npos) << notes[1];

  e.determined = {false, true, true};   // no scale factor: the whole M_C^S held, one note
  notes = held_angle_notes(e, false, true);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("a constant input is a bias"), std::string::npos) << notes[0];
  EXPECT_EQ(held_angle_notes(e, false, false)[0].find("a constant input is a bias"), std::string::npos);
}

TEST(MissingExcitation, NamesTheAxisAndTheInput) {
  EXPECT_NE(missing_excitation(1, false).find("specific force along XRA"), std::string::npos);
  EXPECT_NE(missing_excitation(2, false).find("specific force along YRA"), std::string::npos);
  EXPECT_NE(missing_excitation(1, true).find("rate about XRA"), std::string::npos);
  EXPECT_NE(missing_excitation(2, true).find("rate about YRA"), std::string::npos);
}

TEST(FrameFree, TermsThatHoldInAnyFrameNearTheSensors) {
  for (const char* t : {"1", "a_i", "w_i", "T", "a_i*T", "T^2", "a_i[k-1]", "y[k-1]", "y*a_i", "y*T", "e[k-1]"})
    EXPECT_TRUE(frame_free(ident::parse_term(t))) << t;
  for (const char* t : {"a_p", "a_o", "a_i^2", "a_i*a_p", "abs(a_i)", "sign(a_i)", "a_x", "w_p*T"})
    EXPECT_FALSE(frame_free(ident::parse_term(t))) << t;
}

}  // namespace
}  // namespace inertia::procedure
