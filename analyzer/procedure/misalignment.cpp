#include "analyzer/procedure/misalignment.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace inertia::procedure {

frames::Dcm misalignment_from_sensitivities(const Eigen::Vector3d& theta, const frames::Dcm& m_ec_nominal) {
  const double theta_i = theta.norm();                                  // step 1
  if (!std::isfinite(theta_i) || theta_i == 0.0) {
    throw std::invalid_argument("misalignment: the F_E sensitivities theta_x, theta_y, theta_z are zero or not finite");
  }
  const Eigen::Vector3d n_i = theta / theta_i;                          // steps 2-5
  const Eigen::Vector3d n_ira = m_ec_nominal.row(0).transpose();        // step 6
  const Eigen::Vector3d n_r = n_ira.cross(n_i);                         // step 7
  const double delta = std::atan2(n_r.norm(), n_ira.dot(n_i));          // step 8 (acos, robust near 0)
  // Steps 9-11: R(n_R, delta) is a frame rotation (DCM); its transpose turns vectors, carrying
  // IRA onto n_i, and carries XRA and YRA along with it.
  const frames::Dcm turn = frames::frame_rotation(n_r, delta).transpose();
  frames::Dcm m_es;
  m_es.row(0) = n_i.transpose();                                        // step 12
  m_es.row(1) = (turn * m_ec_nominal.row(1).transpose()).transpose();
  m_es.row(2) = (turn * m_ec_nominal.row(2).transpose()).transpose();
  return m_es;
}

frames::Dcm with_twist(const frames::Dcm& m, double psi) {
  if (psi == 0.0) return m;
  frames::Dcm r = m;
  const double c = std::cos(psi), s = std::sin(psi);
  r.row(1) = c * m.row(1) + s * m.row(2);
  r.row(2) = -s * m.row(1) + c * m.row(2);
  return r;
}

frames::Dcm turned(const frames::Dcm& m_cs, const Eigen::Vector3d& turn) {
  return with_twist(frames::about_second_axis(-turn(1)) * frames::about_third_axis(turn(0)) * m_cs, turn(2));
}

Eigen::Vector3d rotation_vector(const frames::Dcm& m_cs) {
  // frames::frame_rotation(axis, angle) is the transpose of the active rotation.
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(m_cs.transpose()));
  return aa.angle() * aa.axis();
}

MisalignmentAngles misalignment_angles(const Eigen::Vector3d& theta, const Eigen::Matrix3d& theta_covariance) {
  MisalignmentAngles out;
  const frames::Dcm identity = frames::Dcm::Identity();
  out.angles = rotation_vector(misalignment_from_sensitivities(theta, identity));
  Eigen::Matrix3d& jacobian = out.jacobian;
  for (int a = 0; a < 3; ++a) {
    const double h = 1e-6 * theta.norm();
    Eigen::Vector3d up = theta, down = theta;
    up(a) += h;
    down(a) -= h;
    jacobian.col(a) = (rotation_vector(misalignment_from_sensitivities(up, identity)) -
                       rotation_vector(misalignment_from_sensitivities(down, identity))) /
                      (2.0 * h);
  }
  out.covariance = jacobian * theta_covariance * jacobian.transpose();
  out.sd = out.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  out.angles(0) = std::nan("");
  out.sd(0) = std::nan("");
  return out;
}

double input_axis_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated) {
  return frames::axis_angle_between(m_es_true.row(0).transpose(), m_es_estimated.row(0).transpose());
}

double full_dcm_error(const frames::Dcm& m_es_true, const frames::Dcm& m_es_estimated) {
  return frames::angle_between(m_es_true, m_es_estimated);
}

bool uses_cross_axes(std::span<const ident::Term> terms) {
  return std::any_of(terms.begin(), terms.end(),
                     [](const ident::Term& t) { return t.uses(ident::Variable::Ap) || t.uses(ident::Variable::Ao); });
}

}  // namespace inertia::procedure
