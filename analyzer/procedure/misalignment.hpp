#pragma once
// Misalignment estimation, the paper's section 2.5 and algorithm 1.
#include <Eigen/Dense>
#include <optional>
#include <span>

#include "analyzer/ident/term.hpp"

#include "common/frames.hpp"

namespace inertia::procedure {

/// Algorithm 1. From the F_E sensitivities theta = [theta_x, theta_y, theta_z] (coefficients of
/// a_x, a_y, a_z in a model identified in F_E, equation 7) and the nominal M_E^C, returns M_E^S.
/// n_i is theta normalized; n_p and n_o are the case axes XRA and YRA turned by the smallest
/// rotation that takes IRA onto n_i (about IRA x n_i), which keeps the choice of n_p, n_o
/// consistent between test cases. Throws std::invalid_argument when theta is zero or not finite.
frames::Dcm misalignment_from_sensitivities(const Eigen::Vector3d& theta, const frames::Dcm& m_ec_nominal);

/// Gyroscopes (section 2.2): the vibration sensitivity is not tied to a sensor frame, so
/// M_E^S = M_C^S M_E^C with M_C^S from the rate test and M_E^C known accurately.
inline frames::Dcm gyro_test_misalignment(const frames::Dcm& m_cs, const frames::Dcm& m_ec) { return m_cs * m_ec; }

/// M_C^S implied by a test's M_E^S and its nominal M_E^C (M_C^S = M_E^S (M_E^C)^T).
inline frames::Dcm case_to_sensor(const frames::Dcm& m_es, const frames::Dcm& m_ec) { return m_es * m_ec.transpose(); }

/// `m` turned about its first row (n_i) by `psi`: n_p, n_o rotated in their plane.
frames::Dcm with_twist(const frames::Dcm& m, double psi);

/// `m_cs` turned in its own frame by `turn` = (a, b, psi): +a about o tilts n_i toward p, -b
/// about p tilts it toward o, psi about n_i twists n_p and n_o (the turns a mounting's angles are
/// refined or held by).
frames::Dcm turned(const frames::Dcm& m_cs, const Eigen::Vector3d& turn);

/// Whether a model uses the cross axes (a_p or a_o): only then does the twist about n_i, which
/// algorithm 1 fixes by convention, change its columns.
bool uses_cross_axes(std::span<const ident::Term> terms);

/// A turn (a, b, psi) of turned() as the angles about i, p, o it makes (psi, -b, a), and back: the
/// map is its own inverse. To first order, for the small turns of a misalignment's uncertainty.
inline Eigen::Matrix3d turn_angles() { return (Eigen::Matrix3d() << 0, 0, 1, 0, -1, 0, 1, 0, 0).finished(); }
/// The angle (0 about i, 1 about p, 2 about o) that component `c` of a turn of turned() moves.
constexpr int angle_of_turn(int c) { return 2 - c; }
/// What an angle held at the nominal frame does to a fit's coefficients, by the rule the batch
/// (batch_stage) and the live estimate (online::LiveSolver::add_misalignment_uncertainty) share:
/// the refit with the mounting turned by `tolerance` about the rotation vector's component `angle`
/// (0 about i, 1 about p, 2 about o), less `theta`; its outer product joins the covariance. One
/// sided: where the angle's first-order effect vanishes (a static pose's scale factor goes as its
/// cosine) the shift is the second-order one, which a symmetric difference would miss.
/// `refit(turn)`: the coefficients with the mounting turned by `turn` (turned()'s parameters),
/// none when that fit fails.
template <class Refit>
std::optional<Eigen::VectorXd> held_angle_response(const Eigen::VectorXd& theta, int angle, double tolerance, Refit&& refit) {
  Eigen::Vector3d turn = Eigen::Vector3d::Zero();
  turn(2 - angle) = tolerance;   // the component of turned() that moves `angle` (angle_of_turn)
  const std::optional<Eigen::VectorXd> moved = refit(turn);
  if (!moved) return std::nullopt;
  return Eigen::VectorXd(*moved - theta);
}

/// The rotation vector of M_C^S (rad, case axes): M_C^S = frame_rotation(v / |v|, |v|). Its
/// components are the angles of F_S from the nominal case frame about IRA, XRA, YRA (i, p, o).
Eigen::Vector3d rotation_vector(const frames::Dcm& m_cs);

/// Angles of the M_C^S algorithm 1 makes of the case-frame sensitivities theta (IRA, XRA, YRA),
/// with their covariance by the delta method from theta's. The turn about i does not change a
/// single-axis output's linear part (algorithm 1 fixes it by convention): it is NaN.
struct MisalignmentAngles {
  Eigen::Vector3d angles = Eigen::Vector3d::Zero();
  Eigen::Matrix3d jacobian = Eigen::Matrix3d::Zero();   // d angles / d theta: another covariance's share
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d sd = Eigen::Vector3d::Zero();
};
MisalignmentAngles misalignment_angles(const Eigen::Vector3d& theta, const Eigen::Matrix3d& theta_covariance);

/// The error figure of the paper's table 2: the angle, in radians, between the true and the
/// estimated input axis n_i (the first rows). The twist about n_i is not observable from a
/// single-axis sensor's F_E sensitivities, so it is reported separately by full_dcm_error.
double input_axis_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated);
double full_dcm_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated);

}  // namespace inertia::procedure
