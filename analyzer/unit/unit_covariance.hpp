#pragma once
// The covariance of every matrix and vector a unit's files state: imucal's K, R, b, K_ga
// (triad_frame.hpp) and Kalibr's M_a, C, M_g, A, C_gyro_i (kalibr_intrinsics.hpp). All of them are
// functions of the members' sensitivity vectors s_k and g-sensitivities, whose covariance each
// member's model gives (TriadAxis::joint_covariance; the members independent, as triad_frame takes
// them), so one delta method (model/coefficient_uncertainty.hpp) carries it to each. A matrix's
// covariance is over its elements row by row (9 x 9); a vector's is 3 x 3; a rotation's is over
// the small rotation vector d of C' = exp([d]x) C (rad^2). The biases do not depend on the
// sensitivities: theirs is the diagonal of their sd squared.
#include <Eigen/Dense>

#include <string>
#include <vector>

#include "analyzer/unit/unit_files.hpp"

namespace inertia::unit {

struct UnitParameter {
  std::string name;            // K_a R_a K_g R_g K_ga, Kalibr's M_a C M_g A C_gyro_i, then b_a b_g
  Eigen::MatrixXd value;       // 3 x 3, or 3 x 1 for a vector
  Eigen::MatrixXd covariance;  // 9 x 9 or 3 x 3 (a rotation: of its rotation vector)
  bool rotation = false;
  /// The standard uncertainty of each element (a rotation: of its rotation vector), value's shape.
  [[nodiscard]] Eigen::MatrixXd sd() const;
};

/// Every parameter of the triads given, in the order above; Kalibr's only where
/// kalibr_intrinsics expresses them.
std::vector<UnitParameter> unit_parameters(const Triads& triads);

}  // namespace inertia::unit
