#include "analyzer/unit/unit_inverse.hpp"

#include <array>

#include "common/config/bench_config.hpp"

namespace inertia::unit {

using ident::Variable;

UnitInverse::UnitInverse(const UnitModel& unit) {
  members_.reserve(unit.members.size());
  for (const model::ModelFile& m : unit.members) members_.emplace_back(m);
  const bool accelerometers = unit.has(dataset::SensorKind::Accelerometer);
  const bool gyroscopes = unit.has(dataset::SensorKind::Gyroscope);
  // The unknowns' columns: the specific force's x, y, z, then the rate's.
  const Eigen::Index force_column = accelerometers ? 0 : -1;
  const Eigen::Index rate_column = gyroscopes ? (accelerometers ? 3 : 0) : -1;
  if (accelerometers) unknowns_.insert(unknowns_.end(), {Variable::Ax, Variable::Ay, Variable::Az});
  if (gyroscopes) unknowns_.insert(unknowns_.end(), {Variable::Wx, Variable::Wy, Variable::Wz});
  const auto count = static_cast<Eigen::Index>(unknowns_.size());

  std::vector<compensate::JointEquation> equations;
  // Newton's fallback starts: each unknown at the middle, then the ends, of the sensed input's
  // characterized range of the member along its axis.
  std::vector<Eigen::VectorXd> starts(3, Eigen::VectorXd::Zero(count));
  for (std::size_t m = 0; m < unit.members.size(); ++m) {
    const model::ModelFile& file = unit.members[m];
    const Eigen::Matrix3d to_sensor = file.m_cs * config::unit_axis_frame(file.unit_axis);
    unit_to_sensor_.push_back(to_sensor);
    compensate::JointEquation e{&members_[m], {}};
    const auto solve = [&](Eigen::Index first_column, const std::array<Variable, 3>& inputs) {
      if (first_column < 0) return;
      for (int r = 0; r < 3; ++r) {
        Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(count);
        row.segment<3>(first_column) = to_sensor.row(r);
        e.solved.emplace_back(inputs[static_cast<std::size_t>(r)], std::move(row));
      }
    };
    solve(force_column, {Variable::Ai, Variable::Ap, Variable::Ao});
    solve(rate_column, {Variable::Wi, Variable::Wp, Variable::Wo});
    equations.push_back(std::move(e));
    const bool gyro = file.sensor == dataset::SensorKind::Gyroscope;
    const Eigen::Index at = (gyro ? rate_column : force_column) + file.unit_axis;
    const std::array<double, 3> fallback = members_[m].fallback_starts();
    for (std::size_t s = 0; s < 3; ++s) starts[s](at) = fallback[s];
  }
  joint_.emplace(std::move(equations), std::move(starts));
}

}  // namespace inertia::unit
