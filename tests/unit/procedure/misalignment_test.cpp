// Algorithm 1 against hand-built rotations.
#include "analyzer/procedure/misalignment.hpp"

#include <gtest/gtest.h>

#include "common/units.hpp"

namespace inertia::procedure {
namespace {

using frames::Dcm;

// Active rotation matrix written out by hand (Rodrigues), independent of frames.hpp.
Eigen::Matrix3d rodrigues(Eigen::Vector3d k, double angle) {
  k.normalize();
  Eigen::Matrix3d kx;
  kx << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
  return Eigen::Matrix3d::Identity() + std::sin(angle) * kx + (1 - std::cos(angle)) * kx * kx;
}

TEST(Misalignment, IdentityWhenSensitivitiesAlongIra) {
  const Dcm m_ec = Dcm::Identity();
  const Dcm m_es = misalignment_from_sensitivities(Eigen::Vector3d(0.87, 0, 0), m_ec);
  EXPECT_TRUE(m_es.isApprox(Dcm::Identity(), 1e-15));
}

TEST(Misalignment, RecoversRotationAboutAxisPerpendicularToIra) {
  // The case is turned 2 deg about its Y axis (the paper's rotation-table case misalignment):
  // the smallest rotation carrying IRA onto n_i is that very rotation, so all axes are recovered.
  const double angle = deg_to_rad(2.0);
  const Eigen::Matrix3d turn = rodrigues(Eigen::Vector3d::UnitY(), angle);
  Dcm m_es_true;
  for (int r = 0; r < 3; ++r) m_es_true.row(r) = (turn * Eigen::Vector3d::Unit(r)).transpose();
  const double scale = 0.86;
  const Eigen::Vector3d theta = scale * m_es_true.row(0).transpose();
  const Dcm m_es = misalignment_from_sensitivities(theta, Dcm::Identity());
  EXPECT_LT((m_es - m_es_true).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(full_dcm_error(m_es_true, m_es), 0.0, 1e-7);
}

TEST(Misalignment, InputAxisExactAndResultOrthonormalForGeneralRotation) {
  const Eigen::Matrix3d turn = rodrigues(Eigen::Vector3d(1, 1, 1), deg_to_rad(2.0));
  // Nominal mounting: a shaker orientation with IRA 25 deg off the vibration axis.
  const double a = deg_to_rad(25.0);
  Dcm m_ec;
  m_ec << std::cos(a), std::sin(a), 0, -std::sin(a), std::cos(a), 0, 0, 0, 1;
  Dcm m_es_true;
  for (int r = 0; r < 3; ++r) m_es_true.row(r) = (turn * m_ec.row(r).transpose()).transpose();
  const Dcm m_es = misalignment_from_sensitivities(3.0 * m_es_true.row(0).transpose(), m_ec);
  EXPECT_NEAR(input_axis_error(m_es_true, m_es), 0.0, 1e-12);
  EXPECT_TRUE(frames::is_rotation(m_es, 1e-12));
  // n_p, n_o differ from the truth only by a twist about n_i, smaller than the total rotation.
  EXPECT_LT(full_dcm_error(m_es_true, m_es), deg_to_rad(2.0));
  // The estimated frame is the nominal frame turned about IRA x n_i.
  const Eigen::Vector3d n_r = m_ec.row(0).transpose().cross(m_es.row(0).transpose());
  const double delta = std::asin(n_r.norm());
  const Eigen::Matrix3d expected_turn = rodrigues(n_r, delta);
  EXPECT_LT((m_es.row(1).transpose() - expected_turn * m_ec.row(1).transpose()).norm(), 1e-12);
  EXPECT_LT((m_es.row(2).transpose() - expected_turn * m_ec.row(2).transpose()).norm(), 1e-12);
}

TEST(Misalignment, RejectsZeroSensitivity) {
  EXPECT_THROW(misalignment_from_sensitivities(Eigen::Vector3d::Zero(), Dcm::Identity()), std::invalid_argument);
  EXPECT_THROW(misalignment_from_sensitivities(Eigen::Vector3d(NAN, 0, 0), Dcm::Identity()), std::invalid_argument);
}

TEST(Misalignment, GyroMisalignmentComposesCaseToSensorWithMounting) {
  const Dcm m_cs = frames::frame_rotation(Eigen::Vector3d::UnitZ(), 1e-3);
  const Dcm m_ec = frames::frame_rotation(Eigen::Vector3d::UnitX(), deg_to_rad(90.0));
  const Dcm m_es = gyro_test_misalignment(m_cs, m_ec);
  EXPECT_TRUE(case_to_sensor(m_es, m_ec).isApprox(m_cs, 1e-14));
}

// A static pose reads K cos(theta) along its input axis: a held tilt's first-order effect
// vanishes, and the response is the second-order shift K (cos(tolerance) - 1), one-sided.
TEST(HeldAngleResponse, IsTheRefitTurnedByTheToleranceLessTheFit) {
  const double k = 0.0877, tolerance = deg_to_rad(1.0);
  const Eigen::VectorXd theta = Eigen::Vector2d(3e-3, k);
  int turned_component = -1;
  const auto refit = [&](const Eigen::Vector3d& turn) -> std::optional<Eigen::VectorXd> {
    for (int c = 0; c < 3; ++c)
      if (turn(c) != 0.0) turned_component = c;
    return Eigen::VectorXd(Eigen::Vector2d(3e-3, k * std::cos(turn.norm())));
  };
  const std::optional<Eigen::VectorXd> d = held_angle_response(theta, 1, tolerance, refit);   // about p
  ASSERT_TRUE(d);
  EXPECT_EQ(turned_component, 1);
  EXPECT_EQ(angle_of_turn(turned_component), 1);
  EXPECT_DOUBLE_EQ((*d)(0), 0.0);
  EXPECT_NEAR((*d)(1), k * (std::cos(tolerance) - 1.0), 1e-15 * k);   // k cos - k against k (cos - 1): rounding of k
  (void)held_angle_response(theta, 2, tolerance, refit);   // about o: turned()'s first component
  EXPECT_EQ(turned_component, 0);
  (void)held_angle_response(theta, 0, tolerance, refit);   // about i: the twist, the third
  EXPECT_EQ(turned_component, 2);
  EXPECT_FALSE(held_angle_response(theta, 1, tolerance, [](const Eigen::Vector3d&) { return std::optional<Eigen::VectorXd>(); }));
}

}  // namespace
}  // namespace inertia::procedure
