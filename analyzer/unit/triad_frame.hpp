#pragma once
// A triad of a unit: three characterized outputs of one kind (accelerometers or gyroscopes), each
// along one axis of the unit's housing ([[unit]] in the bench file; the model file's unit and
// unit_axis), seen as one object in the unit's frame.
//
// Each output's sensitivity vector s_k = dy_k / d(input in unit coordinates) is its model's settled
// response to the three inputs (compensate::static_sensitivity of i, p, o), turned from its sensor
// frame to its case frame (M_C^S') and from there to the unit's (unit_axis_frame'). Its covariance
// has two parts: the coefficients' (the delta method with the model's covariance) and the input
// axis angles' ([misalignment] sd about p and o, which algorithm 2 estimated beside the fit).
// From the three:
//   S = [s_x; s_y; s_z] = K R   (imucal's K, R: K the diagonal scale |s_k|, R's rows the unit
//                                sensitive axes n_k = s_k / |s_k|), b the biases (settled output
//                                at zero input), so that input = R^-1 K^-1 (y - b);
//   non-orthogonality of axes j, k: asin(n_j . n_k), the angle by which they are closer than 90 deg,
//   with its 95 % interval on Student's t: each member's angle sd rests on the scatter of its
//   mounting's phases (six poses of a tumble give a few degrees of freedom), so the normal's 1.96
//   would claim more than the data hold.
// For gyroscopes, the g-sensitivity: each member's settled response to the specific force in unit
// coordinates (its a_i, a_p, a_o terms turned alike), imucal's K_ga, so that the gyroscope's offset
// is K_ga a + b_g with a the calibrated specific force.
// The outputs were characterized apart, so their estimates are taken as independent. The frame is
// the unit's housing as the test plan's m_ec states it: a rotation common to the three (the
// housing's own misalignment on the fixture) turns every n_k alike and leaves the angles between
// them, which the plan determines.
#include <Eigen/Dense>

#include <array>
#include <limits>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"

namespace inertia::unit {

struct TriadAxis {
  std::string sensor;                 // the member's name
  Eigen::Vector3d sensitivity;        // s_k, output unit per input unit (m/s^2 or rad/s), unit coordinates
  Eigen::Matrix3d covariance;         // of s_k
  Eigen::Matrix3d angles_covariance = Eigen::Matrix3d::Zero();   // its part from the input-axis angles
  double angles_dof = std::numeric_limits<double>::infinity();   // their sd's degrees of freedom
  double bias = 0.0, bias_sd = 0.0;   // settled output at zero input, output unit
  Eigen::Vector3d g_sensitivity = Eigen::Vector3d::Zero();   // gyroscopes: dy / d(specific force), unit coordinates
  /// Of (s_k, g_sensitivity) together: `covariance` is its top left block (for an accelerometer,
  /// whose g_sensitivity is zero, the only one that is not zero).
  Eigen::Matrix<double, 6, 6> joint_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  bool angles_estimated = false;      // the model's [misalignment] has both angles with their sd
};

struct TriadFrame {
  std::string unit, serial, output_unit;
  dataset::SensorKind kind = dataset::SensorKind::Accelerometer;
  std::array<TriadAxis, 3> axes;                 // along x, y, z
  Eigen::Matrix3d sensitivity;                   // S, rows s_x, s_y, s_z
  Eigen::Vector3d scale, scale_sd;               // K's diagonal
  Eigen::Matrix3d misalignment;                  // R, rows the unit sensitive axes
  Eigen::Vector3d bias, bias_sd;                 // b
  Eigen::Matrix3d g_sensitivity = Eigen::Matrix3d::Zero();   // gyroscopes: K_ga, rows x, y, z (output unit per m/s^2)
  std::array<double, 3> non_orthogonality{}, non_orthogonality_sd{};   // xy, yz, zx (rad)
  /// The degrees of freedom of each non_orthogonality_sd (Welch-Satterthwaite over the members'
  /// angle parts; the coefficients' part counts as many), and its 95 % interval's half width
  /// (Student's t on them).
  std::array<double, 3> non_orthogonality_dof{}, non_orthogonality_half_width{};
};

/// The triad of `members`: three models of one unit and kind, one along each axis. Throws
/// InputError for models of different units or kinds, an axis given twice or missing, a model
/// without unit_axis.
TriadFrame triad_frame(const std::vector<model::ModelFile>& members);

/// Pairs of the non-orthogonality arrays: "xy", "yz", "zx".
inline constexpr std::array<const char*, 3> kAxisPairs = {"xy", "yz", "zx"};

}  // namespace inertia::unit
