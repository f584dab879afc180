#include "analyzer/procedure/turn_search.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/units.hpp"

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

std::string held_twist_note(std::string_view mounting, std::string_view reference, const TwistHeld& why,
                            double tolerance_rad) {
  constexpr std::string_view kHeld = "held at the nominal frame, and what the tolerance moves is in the sd";
  switch (why.reason) {
    case TwistHeld::Reason::SearchDidNotSettle:
      return fmt::format(
          "the search for the twist about n_i of mounting '{}' against '{}' did not settle in {} steps (it was at "
          "{:+.2f} deg from the nominal frame, sd {:.2g} deg there, {:.2g} deg at the nominal frame): the residual "
          "does not single out one twist, as when a tilt the plan does not excite is held away from its truth; {}",
          mounting, reference, kTurnMaxSteps, rad_to_deg(why.found_rad), rad_to_deg(why.found_sd_rad),
          rad_to_deg(why.sd_rad), kHeld);
    case TwistHeld::Reason::SdAboveToleranceWhereFound:
      return fmt::format(
          "the twist about n_i of mounting '{}' against '{}' is not determined where the search ended ({:+.2f} deg "
          "from the nominal frame, sd {:.2g} deg with its tilts free, more than the {:.2f} deg mounting tolerance): {}",
          mounting, reference, rad_to_deg(why.found_rad), rad_to_deg(why.found_sd_rad), rad_to_deg(tolerance_rad), kHeld);
    case TwistHeld::Reason::SdAboveTolerance:
      break;
  }
  return fmt::format(
      "the twist about n_i of mounting '{}' against '{}' is not determined by this plan (sd {:.2g} deg with its "
      "tilts free, more than the {:.2f} deg mounting tolerance): {}; more cross-axis excitation (a_p, a_o) in "
      "both mountings determines it",
      mounting, reference, rad_to_deg(why.sd_rad), rad_to_deg(tolerance_rad), kHeld);
}

namespace {

/// Each turning mounting's tilts its excitation determines, then its twist.
std::vector<TurnParameter> parameters_of(const std::vector<std::size_t>& turning,
                                         std::span<const std::array<bool, 2>> tilts_determined) {
  std::vector<TurnParameter> parameters;
  for (std::size_t k : turning) {
    for (int axis = 0; axis < 2; ++axis)
      if (tilts_determined[k][static_cast<std::size_t>(axis)]) parameters.push_back({k, axis});
    parameters.push_back({k, 2});
  }
  return parameters;
}

}  // namespace

std::vector<std::size_t> search_turns(TurnedBatch& batch, std::vector<std::size_t> turning,
                                      std::span<const std::array<bool, 2>> tilts_determined, double tolerance_rad) {
  const auto determined_within = [&](double sd) { return std::isfinite(sd) && sd > 0.0 && sd <= tolerance_rad; };
  // Each pass starts from the nominal frames; a pass whose twists the data do not determine holds
  // them, and the next runs without them.
  while (!turning.empty()) {
    const std::vector<TurnParameter> parameters = parameters_of(turning, tilts_determined);
    std::optional<TurnStep> step = batch.step(parameters);
    if (!step) return {};
    const TurnStep nominal = *step;
    const Eigen::VectorXd nominal_sd = turn_sd(nominal.information);
    std::vector<std::size_t> determined;
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      if (parameters[i].axis != 2) continue;
      const double sd = nominal_sd(static_cast<Eigen::Index>(i));
      if (determined_within(sd))
        determined.push_back(parameters[i].mounting);
      else
        batch.hold(parameters, i, nominal.information, {TwistHeld::Reason::SdAboveTolerance, sd});
    }
    if (determined.size() < turning.size()) {
      turning = std::move(determined);
      continue;
    }
    Eigen::VectorXd found = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(parameters.size()));
    Eigen::VectorXd sd = nominal_sd;
    bool settled = false;
    for (int iteration = 1;; ++iteration) {
      Eigen::MatrixXd covariance;
      sd = turn_sd(step->information, &covariance);
      batch.turn(parameters, step->delta, covariance);
      found += step->delta;
      if ((step->delta.array().abs() <= kTurnConvergence * sd.array()).all()) {
        settled = true;
        break;
      }
      if (iteration == kTurnMaxSteps) {
        settled = (step->delta.array().abs() <= kTurnSettled * sd.array()).all();
        break;
      }
      step = batch.step(parameters);
      if (!step) break;
    }
    std::vector<std::size_t> undetermined;   // the twists the search found where the data do not determine them
    for (std::size_t i = 0; i < parameters.size(); ++i)
      if (parameters[i].axis == 2 && !determined_within(sd(static_cast<Eigen::Index>(i)))) undetermined.push_back(i);
    if (settled && undetermined.empty()) return turning;
    batch.restore(turning);
    determined.clear();
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      if (parameters[i].axis != 2) continue;
      const auto at = static_cast<Eigen::Index>(i);
      const bool held = !settled || std::find(undetermined.begin(), undetermined.end(), i) != undetermined.end();
      if (!held) {
        determined.push_back(parameters[i].mounting);
        continue;
      }
      batch.hold(parameters, i, nominal.information,
                 {settled ? TwistHeld::Reason::SdAboveToleranceWhereFound : TwistHeld::Reason::SearchDidNotSettle,
                  nominal_sd(at), found(at), sd(at)});
    }
    turning = std::move(determined);
  }
  return {};
}

}  // namespace inertia::procedure
