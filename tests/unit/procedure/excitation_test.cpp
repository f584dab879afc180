// What a mounting's excitation determines (procedure/excitation.hpp): the shares against a
// hand-worked four-sample example and against a least-squares projection on the samples, the
// verdicts on plans that do and do not excite an axis, the threshold, and the held angles' notes.
// What a plan's own inputs excite of a product term (procedure/plan_validation.hpp,
// TermExcitation): the shares by hand on a six-pose tumble and a rotation in the i-p plane, the
// sensor's misalignment not counted as excitation, the threshold, and which terms the rule judges.
#include "analyzer/procedure/excitation.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>

#include "analyzer/procedure/plan_validation.hpp"

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


/// A static case of `n` samples: gravity along F_E's z, the case turned by `m_ec` (rows: IRA, XRA,
/// YRA in F_E).
dataset::CaseData pose(const Eigen::Matrix3d& m_ec, Index n = 10) {
  dataset::CaseData c;
  c.name = "pose";
  c.m_ec = m_ec;
  c.sample_period_s = 0.01;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, 0.01 * static_cast<double>(n - 1));
  c.a_e = dataset::Matrix3Columns(n, 3);
  c.a_e.rowwise() = Eigen::RowVector3d(0.0, 0.0, 9.80665);
  c.y = Eigen::VectorXd::Zero(n);
  return c;
}

/// The nominal M_E^C of a pose whose case axis `up` (0 IRA, 1 XRA, 2 YRA) points along +z or -z.
Eigen::Matrix3d facing(int up, double sign) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  m(up, 2) = sign;
  m((up + 1) % 3, 0) = 1.0;
  m((up + 2) % 3, 1) = sign;
  return m;
}

std::vector<dataset::CaseData> six_poses() {
  std::vector<dataset::CaseData> cases;
  for (int up = 0; up < 3; ++up)
    for (double sign : {1.0, -1.0}) cases.push_back(pose(facing(up, sign)));
  return cases;
}

TermExcitation tally_of(const char* term, const std::vector<dataset::CaseData>& cases) {
  const std::array<ident::Term, 1> one{ident::parse_term(term)};
  std::array<TermExcitation, 1> tally{};
  for (const dataset::CaseData& c : cases) add_excitation(one, c, c.m_ec, 25.0, 0, tally);
  return tally[0];
}

TEST(TermExcitation, SeveralTermsAtOnceTallyAsEachAlone) {
  // The case's signals are built once for the union of the terms' variables: each term's tally
  // is still its own, and a term the rule does not judge gets nothing.
  const std::vector<dataset::CaseData> cases = six_poses();
  const std::vector<const char*> names = {"a_p*a_o", "a_i^2", "a_i", "a_p^2", "1"};
  std::vector<ident::Term> terms;
  for (const char* name : names) terms.push_back(ident::parse_term(name));
  std::vector<TermExcitation> together(terms.size());
  for (const dataset::CaseData& c : cases) add_excitation(terms, c, c.m_ec, 25.0, 0, together);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const TermExcitation alone = tally_of(names[i], cases);
    EXPECT_EQ(together[i].nominal, alone.nominal) << names[i];
    EXPECT_EQ(together[i].full, alone.full) << names[i];
  }
  EXPECT_EQ(together[2].full, 0.0);   // a_i: a sensitivity, not judged
  EXPECT_EQ(together[4].full, 0.0);
  EXPECT_GT(together[0].full, 0.0);
}

TEST(TermExcitation, SixPoseTumbleExcitesTheSquaresNotTheProducts) {
  const std::vector<dataset::CaseData> cases = six_poses();
  const double g4 = std::pow(9.80665, 4);
  // a_i^2: g^4 in the two poses with IRA vertical, 0 in the four others; the full energy is g^4
  // in all six: a share of 1/3.
  const TermExcitation square = tally_of("a_i^2", cases);
  EXPECT_NEAR(square.nominal, 2 * 10 * g4, 1e-9 * g4);
  EXPECT_NEAR(square.full, 6 * 10 * g4, 1e-9 * g4);
  EXPECT_TRUE(square.excited());
  EXPECT_TRUE(tally_of("a_i*abs(a_i)", cases).excited());
  // A product of two axes is zero in every pose of the plan.
  for (const char* product : {"a_i*a_p", "a_i*a_o", "a_p*a_o"}) {
    const TermExcitation t = tally_of(product, cases);
    EXPECT_EQ(t.nominal, 0.0) << product;
    EXPECT_NEAR(t.full, 6 * 10 * g4, 1e-9 * g4) << product;
    EXPECT_FALSE(t.excited()) << product;
  }
}

TEST(TermExcitation, TheSensorsMisalignmentIsNotExcitation) {
  // The rule reads the references in the plan's frames, so a sensor 3 mrad off its case changes
  // nothing, and poses placed 3 mrad off (their references in F_E tilted) move a_p*a_o by a few
  // mrad of g^2: far below the share. Only a plan whose own frames put gravity between p and o
  // excites it.
  std::vector<dataset::CaseData> cases = six_poses();
  const TermExcitation before = tally_of("a_p*a_o", cases);
  const Eigen::Matrix3d tilt = frames::frame_rotation(Eigen::Vector3d(1.0, 1.0, 0.0).normalized(), 3e-3);
  for (dataset::CaseData& c : cases) c.a_e = (c.a_e * tilt.transpose()).eval();
  const TermExcitation tilted = tally_of("a_p*a_o", cases);
  EXPECT_FALSE(tilted.excited());
  EXPECT_LT(tilted.nominal, 6 * 10 * std::pow(9.80665 * 9.80665 * 3e-3, 2));   // a few mrad of g^2 at most
  EXPECT_EQ(before.nominal, 0.0);
  // A pose with gravity at 45 deg between XRA and YRA: a_p a_o = g^2 / 2 there.
  const double s = std::sqrt(0.5);
  Eigen::Matrix3d between;
  between << 1, 0, 0,
             0, s, s,
             0, -s, s;
  cases.push_back(pose(between));
  const TermExcitation with = tally_of("a_p*a_o", cases);
  const double g4 = std::pow(9.80665, 4);
  EXPECT_NEAR(with.nominal, tilted.nominal + 10 * g4 / 4.0, 1e-12 * g4);
  EXPECT_NEAR(with.full, 7 * 10 * g4, 1e-9 * g4);
  EXPECT_TRUE(with.excited());
}

TEST(TermExcitation, ARotationInTheIpPlaneExcitesItsProductAtOneEighth) {
  // Gravity turned through a whole turn in the i-p plane at 36 equal steps: a_i a_p = g^2 cos sin,
  // whose square averages 1/8 of g^4; a_o^2 is zero throughout.
  std::vector<dataset::CaseData> cases;
  for (int k = 0; k < 36; ++k) {
    const double angle = 2.0 * std::numbers::pi * k / 36.0;
    Eigen::Matrix3d m;
    m << 0, std::sin(angle), std::cos(angle),
         0, std::cos(angle), -std::sin(angle),
         1, 0, 0;
    cases.push_back(pose(m, 4));
  }
  const TermExcitation ip = tally_of("a_i*a_p", cases);
  EXPECT_NEAR(ip.nominal / ip.full, 0.125, 1e-12);
  EXPECT_TRUE(ip.excited());
  EXPECT_LT(tally_of("a_o^2", cases).nominal, 1e-20 * ip.full);
  EXPECT_FALSE(tally_of("a_o^2", cases).excited());
}

TEST(TermExcitation, TheThresholdIsTheAxesShare) {
  TermExcitation t;
  t.full = 1.0;
  t.nominal = kMinExcitationShare;
  EXPECT_TRUE(t.excited());
  t.nominal = 0.99 * kMinExcitationShare;
  EXPECT_FALSE(t.excited());
  t.scale(0.5);
  EXPECT_FALSE(t.excited());
  EXPECT_TRUE(TermExcitation{}.excited());   // nothing seen: nothing to judge
}

TEST(TermExcitation, JudgesProductsOfInertialInputsOnly) {
  for (const char* judged : {"a_i^2", "a_i*a_p", "a_p*a_o", "w_i*a_p", "a_i*a_i[k-1]", "a_i*abs(a_i)", "a_i^2*T"})
    EXPECT_TRUE(judged_by_excitation(ident::parse_term(judged))) << judged;
  for (const char* not_judged : {"1", "a_i", "a_p", "a_i[k-1]", "T", "a_i*T", "y*w_i", "y[k-1]", "e[k-1]", "w_i"})
    EXPECT_FALSE(judged_by_excitation(ident::parse_term(not_judged))) << not_judged;
}

TEST(TermExcitation, RemovesTheUnexcitedCandidatesAndSaysWhatTheyNeed) {
  std::vector<ident::Term> candidates = ident::parse_terms({"1", "a_i", "a_i^2", "a_p*a_o", "a_p"});
  const std::vector<UndeterminedTerm> out = remove_unexcited_terms(candidates, six_poses(), 25.0);
  EXPECT_EQ(candidates, ident::parse_terms({"1", "a_i", "a_i^2", "a_p"}));
  ASSERT_EQ(out.size(), 1U);
  EXPECT_EQ(out[0].term, "a_p*a_o");
  EXPECT_NE(out[0].reason.find("specific force along p and specific force along o"), std::string::npos) << out[0].reason;
}
}  // namespace
}  // namespace inertia::procedure
