#pragma once
// Misalignment estimation, the paper's section 2.5 and algorithm 1.
#include <Eigen/Dense>

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

/// The error figure of the paper's table 2: the angle, in radians, between the true and the
/// estimated input axis n_i (the first rows). The twist about n_i is not observable from a
/// single-axis sensor's F_E sensitivities, so it is reported separately by full_dcm_error.
double input_axis_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated);
double full_dcm_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated);

}  // namespace inertia::procedure
