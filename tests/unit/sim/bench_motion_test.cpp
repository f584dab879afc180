// Table and shaker motion in F_E, gravity projections for hand-built attitudes, and the
// orientation chain against hand-built rotations.
#include <gtest/gtest.h>

#include <cmath>

#include "common/frames.hpp"
#include "common/units.hpp"
#include "hal/sim/bench_motion.hpp"
#include "hal/sim/orientation.hpp"
#include "sim_test_util.hpp"

namespace {

using inertia::kPi;
using inertia::kStandardGravity;
using namespace inertia::sim;
using inertia::sim::test::bench_from;

const char* const kTable = R"([bench]
name = "t"
sample_rate_hz = 100.0
[[sensor]]
name = "acc"
type = "accelerometer"
[[case]]
name = "table"
kind = "rotation_table"
m_ec = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
start_attitude = { axis = [1, 0, 0], angle_deg = 90.0 }
[[case.phase]]
kind = "dwell"
duration_s = 1.0
[[case.phase]]
kind = "rotation"
axis = [0, 0, 1]
angle_deg = 90.0
duration_s = 2.0
[[case.phase]]
kind = "dwell"
duration_s = 1.0
[[case.phase]]
kind = "rotation"
axis = [0, 1, 0]
rate_deg_s = 30.0
duration_s = 3.0
)";

TEST(TableMotion, GravityFollowsTheTableAngle) {
  const auto bench = bench_from(kTable);
  ThermalModel thermal(bench.thermal, bench.sample_rate_hz);
  const CaseMotion m = simulate_motion(bench, 0, thermal);
  ASSERT_EQ(m.size(), 700u);
  const double g = kStandardGravity;
  // Start: F_E turned +90 deg about x: y_E now points up, so the gravity reaction is +g on y_E.
  EXPECT_LT((m.f_e.row(0).transpose() - Eigen::Vector3d(0, g, 0)).norm(), 1e-12);
  // After +90 deg about z_E: the frame's x axis is where y was (up): +g on x_E.
  EXPECT_LT((m.f_e.row(350).transpose() - Eigen::Vector3d(g, 0, 0)).norm(), 1e-12);
  EXPECT_EQ(m.w_e.row(350).norm(), 0.0);
  // Smooth angle profile: mid-rotation (t = 1 s of 2) the angle is 45 deg and the rate is at its
  // peak, 2 * angle / D = 90 deg/s, about z.
  const Eigen::Index mid = 200;
  EXPECT_NEAR(m.table_angle_rad[mid], kPi / 4, 1e-12);
  EXPECT_LT((m.w_e.row(mid).transpose() - Eigen::Vector3d(0, 0, inertia::deg_to_rad(90.0))).norm(), 1e-12);
  EXPECT_LT((m.f_e.row(mid).transpose() - g * Eigen::Vector3d(std::sqrt(0.5), std::sqrt(0.5), 0)).norm(), 1e-12);
  // Constant rate about y_E from x_E up: after 1 s (30 deg) gravity has turned by 30 deg in the
  // x-z plane; by the right-hand rule the frame's x axis moves away from "up" towards -z.
  const Eigen::Index k = 400 + 100;
  const double th = inertia::deg_to_rad(30.0);
  EXPECT_LT((m.f_e.row(k).transpose() - g * Eigen::Vector3d(std::cos(th), 0, std::sin(th))).norm(), 1e-12);
  EXPECT_LT((m.w_e.row(k).transpose() - Eigen::Vector3d(0, th, 0)).norm(), 1e-12);
  // Gravity keeps its magnitude throughout; labels follow the phases.
  for (Eigen::Index r = 0; r < m.f_e.rows(); ++r) ASSERT_NEAR(m.f_e.row(r).norm(), g, 1e-12);
  ASSERT_EQ(m.phase_names.size(), 2u);
  EXPECT_EQ(m.phase_names[m.phase[0]], "static");
  EXPECT_EQ(m.phase_names[m.phase[150]], "rotation");
}

TEST(TableMotion, LeverArmAddsCentripetalAndTangential) {
  const Eigen::Vector3d f(0, 0, kStandardGravity), w(0, 0, 2.0), dw(0, 0, 3.0), r(0.1, 0, 0);
  const Eigen::Vector3d at = specific_force_at(f, w, dw, r);
  // Centripetal -w^2 r towards the axis, tangential dw * r along +y.
  EXPECT_LT((at - Eigen::Vector3d(-0.4, 0.3, kStandardGravity)).norm(), 1e-15);
}

TEST(ShakerMotion, VibrationAlongXGravityReactionUp) {
  const auto bench = bench_from(R"([bench]
name = "t"
sample_rate_hz = 1000.0
[[sensor]]
name = "acc"
type = "accelerometer"
[[case]]
name = "s"
kind = "shaker"
orientation = "PA"
[[case.phase]]
kind = "dwell"
duration_s = 0.5
[[case.phase]]
kind = "sine"
frequency_hz = 50.0
amplitude_g = 2.0
duration_s = 1.0
)");
  ThermalModel thermal(bench.thermal, bench.sample_rate_hz);
  const CaseMotion m = simulate_motion(bench, 0, thermal);
  ASSERT_EQ(m.size(), 1500u);
  EXPECT_TRUE((m.f_e.col(2).array() == kStandardGravity).all());
  EXPECT_TRUE((m.f_e.col(1).array() == 0.0).all());
  EXPECT_TRUE((m.f_e.col(0).head(500).array() == 0.0).all());
  // Mid-plateau sample, a quarter period after a whole number of cycles: the crest.
  const Eigen::Index k = 500 + 500 + 5;   // t = 0.505 s into the phase: 25.25 cycles
  EXPECT_NEAR(m.f_e(k, 0), 2.0 * kStandardGravity, 1e-9);
  EXPECT_TRUE((m.w_e.array() == 0.0).all());
}

TEST(OrientationChain, MatchesHandBuiltRotations) {
  // Paper section 3.1: case misalignment 2 deg about the case Y axis (YRA, the third case axis),
  // nominal identity. Frame rotation about the third axis by +b: rows = new axes in old coords.
  inertia::config::TestCase tc;
  tc.case_misalignment = {Eigen::Vector3d(0, 0, 1), inertia::deg_to_rad(2.0)};
  inertia::config::SensorUnderTest sensor;
  const double b = inertia::deg_to_rad(2.0), c = std::cos(b), s = std::sin(b);
  Eigen::Matrix3d expected;
  expected << c, s, 0, -s, c, 0, 0, 0, 1;
  EXPECT_LT((mounting_truth(tc, sensor).true_m_ec - expected).cwiseAbs().maxCoeff(), 1e-15);

  // A Fig. 2 slot with a fixture misalignment about x_E and a slot fit about the case's IRA:
  // M = R_slot(IRA) R_case(YRA) M_nom R_F(x_E).
  tc.m_ec = inertia::config::slot_orientation(inertia::config::Orientation::IA, inertia::deg_to_rad(25.0));
  tc.fixture_misalignment = {Eigen::Vector3d(2, 0, 0), 0.01};
  sensor.case_misalignment = {Eigen::Vector3d(1, 0, 0), -0.02};
  Eigen::Matrix3d rf, rs;
  rf << 1, 0, 0, 0, std::cos(0.01), std::sin(0.01), 0, -std::sin(0.01), std::cos(0.01);
  rs << 1, 0, 0, 0, std::cos(-0.02), std::sin(-0.02), 0, -std::sin(-0.02), std::cos(-0.02);
  const MountingTruth m = mounting_truth(tc, sensor);
  EXPECT_LT((m.true_m_ec - rs * expected * tc.m_ec * rf).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_TRUE(inertia::frames::is_rotation(m.true_m_ec, 1e-12));
  // a_C = M a_E: the gravity reaction (up) seen by the case is the third column of M.
  const Eigen::Vector3d a_c = m.true_m_ec * Eigen::Vector3d(0, 0, kStandardGravity);
  EXPECT_LT((a_c - kStandardGravity * m.true_m_ec.col(2)).norm(), 1e-12);
}

}  // namespace
