#include "common/frames.hpp"

#include <algorithm>
#include <cmath>

namespace inertia::frames {

Dcm frame_rotation(const Eigen::Vector3d& axis, double angle_rad) {
  const double n = axis.norm();
  if (n == 0.0 || angle_rad == 0.0) return Dcm::Identity();
  // The active rotation R moves vectors; the rotated frame's axes are the columns of R written in
  // the reference frame, so the DCM (rows = new axes) is R^T.
  return Eigen::AngleAxisd(angle_rad, axis / n).toRotationMatrix().transpose();
}

double angle_between(const Dcm& a, const Dcm& b) {
  // acos of the trace loses precision near 0; use the rotation's axis-angle instead.
  return Eigen::AngleAxisd(Dcm(a.transpose() * b)).angle();
}

double axis_angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

bool is_rotation(const Dcm& m, double tol) {
  return (m * m.transpose() - Dcm::Identity()).cwiseAbs().maxCoeff() < tol && std::abs(m.determinant() - 1.0) < tol;
}

}  // namespace inertia::frames
