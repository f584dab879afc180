#include "analyzer/procedure/turn_search.hpp"

#include <cmath>

namespace inertia::procedure {

std::vector<Eigen::Vector3d> turns_of(std::span<const TurnParameter> parameters, const Eigen::VectorXd& x,
                                      std::size_t mountings) {
  std::vector<Eigen::Vector3d> turns(mountings, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < parameters.size(); ++i) turns[parameters[i].mounting](parameters[i].axis) = x(static_cast<Eigen::Index>(i));
  return turns;
}

Eigen::VectorXd turn_sd(const Eigen::MatrixXd& information, Eigen::MatrixXd* covariance) {
  const Eigen::MatrixXd inverse = information.ldlt().solve(Eigen::MatrixXd::Identity(information.rows(), information.cols()));
  if (covariance != nullptr) *covariance = inverse;
  return inverse.diagonal().cwiseMax(0.0).cwiseSqrt();
}

std::vector<std::size_t> search_turns(TurnedBatch& batch, std::vector<std::size_t> turning,
                                      std::span<const std::array<bool, 2>> tilts_determined, double tolerance_rad) {
  std::vector<std::size_t> turned;
  for (int iteration = 0; iteration < kTurnMaxSteps && !turning.empty(); ++iteration) {
    std::vector<TurnParameter> parameters;
    for (std::size_t k : turning) {
      for (int axis = 0; axis < 2; ++axis)
        if (tilts_determined[k][static_cast<std::size_t>(axis)]) parameters.push_back({k, axis});
      parameters.push_back({k, 2});
    }
    const std::optional<TurnStep> step = batch.step(parameters);
    if (!step) break;
    Eigen::MatrixXd covariance;
    const Eigen::VectorXd sd = turn_sd(step->information, &covariance);
    if (iteration == 0) {
      std::vector<std::size_t> determined;
      for (std::size_t i = 0; i < parameters.size(); ++i) {
        if (parameters[i].axis != 2) continue;
        const double twist_sd = sd(static_cast<Eigen::Index>(i));
        if (std::isfinite(twist_sd) && twist_sd > 0.0 && twist_sd <= tolerance_rad)
          determined.push_back(parameters[i].mounting);
        else
          batch.hold(parameters, i, step->information, twist_sd);
      }
      if (determined.size() < turning.size()) {
        turning = determined;
        continue;   // the step again, without the held twists
      }
    }
    batch.turn(parameters, step->delta, covariance);
    turned = turning;
    if ((step->delta.array().abs() <= kTurnConvergence * sd.array()).all()) break;
  }
  return turned;
}

}  // namespace inertia::procedure
