#pragma once
// Frames and direction cosine matrices (docs/design.md, "Units and frames").
// A DCM M_A^B maps coordinates from F_A to F_B (v_B = M_A^B v_A); its rows are the axes of F_B
// written in F_A. Frames: F_E external (table/shaker), F_C sensor case (IRA, XRA, YRA),
// F_S sensor (i input, p pendulous, o output).
#include <Eigen/Dense>

namespace inertia::frames {

using Dcm = Eigen::Matrix3d;

/// DCM of a frame obtained by rotating the reference frame by `angle_rad` about `axis`
/// (right-hand rule; axis in reference coordinates, need not be unit length).
/// It maps reference coordinates into the rotated frame: v_rotated = frame_rotation(...) * v_ref.
Dcm frame_rotation(const Eigen::Vector3d& axis, double angle_rad);

/// The paper's R_PA(alpha_p), R_OA(alpha_o): frame rotations about the second and third axis.
inline Dcm about_second_axis(double angle_rad) { return frame_rotation(Eigen::Vector3d::UnitY(), angle_rad); }
inline Dcm about_third_axis(double angle_rad) { return frame_rotation(Eigen::Vector3d::UnitZ(), angle_rad); }

/// Angle between two DCMs (the rotation angle of a^T b), in radians.
double angle_between(const Dcm& a, const Dcm& b);

/// Angle between two axes (unit or not), in radians.
double axis_angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// True when m is a proper rotation (orthonormal, det +1) to within `tol`.
bool is_rotation(const Dcm& m, double tol = 1e-9);

}  // namespace inertia::frames
