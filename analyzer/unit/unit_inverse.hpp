#pragma once
// A unit's outputs compensated together: the joint inverse (compensate/joint_inverse.hpp) of its
// members' models, its unknowns the specific force (m/s^2) and the angular rate (rad/s) in the
// unit's frame. A member along unit axis j reads its inputs in its own sensor frame,
// v_S = M_C^S T_j v_U (T_j = config::unit_axis_frame(j), M_C^S its model's), for the specific
// force and the rate alike. With both triads, the gyroscopes' g-sensitivity reads the solved
// specific force and an accelerometer's rate terms the solved rate; with one triad, the other
// quantity is known, from the record's references. Temperature is always known.
#include <Eigen/Dense>

#include <optional>
#include <string>
#include <vector>

#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/compensate/joint_inverse.hpp"
#include "analyzer/unit/unit_model.hpp"

namespace inertia::unit {

class UnitInverse {
 public:
  /// Throws InputError for a member whose model cannot be inverted (inverse_model.hpp).
  explicit UnitInverse(const UnitModel& unit);
  UnitInverse(const UnitInverse&) = delete;   // the joint inverse points into members_
  UnitInverse& operator=(const UnitInverse&) = delete;

  [[nodiscard]] const compensate::JointInverse& joint() const { return *joint_; }
  /// One per UnitModel member, in its order.
  [[nodiscard]] const std::vector<compensate::InverseModel>& members() const { return members_; }
  /// The unknowns: a_x, a_y, a_z (with an accelerometer triad), then w_x, w_y, w_z (with a gyroscope triad).
  [[nodiscard]] const std::vector<ident::Variable>& unknowns() const { return unknowns_; }
  /// The sensor frame of member m seen from the unit's: v_S = M v_U.
  [[nodiscard]] const Eigen::Matrix3d& unit_to_sensor(std::size_t m) const { return unit_to_sensor_[m]; }

 private:
  std::vector<compensate::InverseModel> members_;
  std::vector<Eigen::Matrix3d> unit_to_sensor_;
  std::vector<ident::Variable> unknowns_;
  std::optional<compensate::JointInverse> joint_;
};

}  // namespace inertia::unit
