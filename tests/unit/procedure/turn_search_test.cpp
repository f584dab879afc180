// procedure::search_turns against a batch whose residual is a known quadratic in the turns: the
// parameters it asks for, the twists it holds, the point it ends at and when it stops.
#include "analyzer/procedure/turn_search.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

namespace {

using inertia::procedure::kTurnConvergence;
using inertia::procedure::kTurnMaxSteps;
using inertia::procedure::search_turns;
using inertia::procedure::TurnedBatch;
using inertia::procedure::TurnParameter;
using inertia::procedure::TurnStep;

/// Residual sum sum_p (x_p - best_p)^2 / sd_p^2 over every (mounting, axis): Newton's step is
/// best - x, exact, and the information is diag(1 / sd^2). `gain` < 1 takes only part of the step,
/// as a search that needs several steps.
class QuadraticBatch final : public TurnedBatch {
 public:
  std::map<std::pair<std::size_t, int>, double> best, sd, at;
  double gain = 1.0;
  int steps = 0;
  std::vector<std::vector<TurnParameter>> asked;
  std::vector<std::pair<std::size_t, double>> held;   // (mounting, twist sd)

  std::optional<TurnStep> step(std::span<const TurnParameter> parameters) override {
    ++steps;
    asked.emplace_back(parameters.begin(), parameters.end());
    TurnStep s;
    const auto n = static_cast<Eigen::Index>(parameters.size());
    s.delta.resize(n);
    s.information = Eigen::MatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto key = std::pair{parameters[static_cast<std::size_t>(i)].mounting, parameters[static_cast<std::size_t>(i)].axis};
      s.delta(i) = gain * (best[key] - at[key]);
      s.information(i, i) = 1.0 / (sd[key] * sd[key]);
    }
    return s;
  }
  void turn(std::span<const TurnParameter> parameters, const Eigen::VectorXd& delta, const Eigen::MatrixXd&) override {
    for (std::size_t i = 0; i < parameters.size(); ++i) at[{parameters[i].mounting, parameters[i].axis}] += delta(static_cast<Eigen::Index>(i));
  }
  void hold(std::span<const TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd&, double twist_sd) override {
    held.emplace_back(parameters[twist].mounting, twist_sd);
  }
};

constexpr double kTolerance = 0.0175;

/// Mountings 1 and 2 turning (0 is the reference): every angle's best value and sd.
QuadraticBatch two_mountings(double twist_sd_2) {
  QuadraticBatch b;
  for (std::size_t k = 1; k <= 2; ++k)
    for (int axis = 0; axis < 3; ++axis) {
      b.best[{k, axis}] = 1e-3 * static_cast<double>(k) * (axis + 1);
      b.sd[{k, axis}] = 1e-4;
      b.at[{k, axis}] = 0.0;
    }
  b.sd[{2, 2}] = twist_sd_2;
  return b;
}

TEST(TurnSearch, EndsAtTheLeastResidualAndStopsWhenTheStepIsBelowTheSd) {
  QuadraticBatch b = two_mountings(1e-4);
  b.gain = 0.5;   // each step halves the distance: from 6e-3 to 1e-6 sd of 1e-4 takes about 26
  const std::vector<std::array<bool, 2>> tilts(3, {true, true});
  const std::vector<std::size_t> turned = search_turns(b, {1, 2}, tilts, kTolerance);
  EXPECT_EQ(turned, (std::vector<std::size_t>{1, 2}));
  EXPECT_TRUE(b.held.empty());
  EXPECT_EQ(b.steps, kTurnMaxSteps) << "halving steps do not reach 1e-6 sd in " << kTurnMaxSteps;

  QuadraticBatch exact = two_mountings(1e-4);
  (void)search_turns(exact, {1, 2}, tilts, kTolerance);
  // Newton's step on a quadratic lands on its minimum; the next step is zero, and the search stops.
  EXPECT_EQ(exact.steps, 2);
  for (const auto& [key, value] : exact.best) EXPECT_NEAR(exact.at[key], value, kTurnConvergence * 1e-4) << key.first << "/" << key.second;
}

TEST(TurnSearch, ATwistTheDataDoNotDetermineIsHeldAndTheStepTakenAgainWithoutIt) {
  QuadraticBatch b = two_mountings(2.0 * kTolerance);
  const std::vector<std::array<bool, 2>> tilts(3, {true, true});
  const std::vector<std::size_t> turned = search_turns(b, {1, 2}, tilts, kTolerance);
  EXPECT_EQ(turned, (std::vector<std::size_t>{1}));
  ASSERT_EQ(b.held.size(), 1U);
  EXPECT_EQ(b.held[0].first, 2U);
  EXPECT_DOUBLE_EQ(b.held[0].second, 2.0 * kTolerance);
  // The first step asked for both mountings, every later one for mounting 1 alone.
  ASSERT_GE(b.asked.size(), 2U);
  EXPECT_EQ(b.asked[0].size(), 6U);
  for (std::size_t s = 1; s < b.asked.size(); ++s)
    for (const TurnParameter& p : b.asked[s]) EXPECT_EQ(p.mounting, 1U);
  for (int axis = 0; axis < 3; ++axis) EXPECT_EQ((b.at[{2, axis}]), 0.0) << "mounting 2 stays at the nominal frame";
  EXPECT_NEAR((b.at[{1, 2}]), (b.best[{1, 2}]), 1e-12);
}

TEST(TurnSearch, OnlyTheTiltsTheExcitationDeterminesAreSearched) {
  QuadraticBatch b = two_mountings(1e-4);
  std::vector<std::array<bool, 2>> tilts(3, {true, true});
  tilts[2] = {false, true};
  (void)search_turns(b, {1, 2}, tilts, kTolerance);
  ASSERT_FALSE(b.asked.empty());
  const std::vector<TurnParameter>& first = b.asked[0];
  ASSERT_EQ(first.size(), 5U);
  const std::vector<std::pair<std::size_t, int>> expected{{1, 0}, {1, 1}, {1, 2}, {2, 1}, {2, 2}};
  for (std::size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].mounting, expected[i].first);
    EXPECT_EQ(first[i].axis, expected[i].second);
  }
  EXPECT_EQ((b.at[{2, 0}]), 0.0) << "a tilt not searched is not moved";
}

TEST(TurnSearch, ABatchWithoutAFitEndsTheSearchWithWhatWasTurned) {
  class NoFit final : public TurnedBatch {
   public:
    std::optional<TurnStep> step(std::span<const TurnParameter>) override { return std::nullopt; }
    void turn(std::span<const TurnParameter>, const Eigen::VectorXd&, const Eigen::MatrixXd&) override { ADD_FAILURE(); }
    void hold(std::span<const TurnParameter>, std::size_t, const Eigen::MatrixXd&, double) override { ADD_FAILURE(); }
  } none;
  const std::vector<std::array<bool, 2>> tilts(2, {true, true});
  EXPECT_TRUE(search_turns(none, {1}, tilts, kTolerance).empty());
}

}  // namespace
