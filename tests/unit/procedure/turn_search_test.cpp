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
using inertia::procedure::kTurnSettled;
using inertia::procedure::TurnedBatch;
using inertia::procedure::TwistHeld;
using inertia::procedure::TurnParameter;
using inertia::procedure::TurnStep;

/// Residual sum sum_p (x_p - best_p)^2 / sd_p^2 over every (mounting, axis): Newton's step is
/// best - x, exact, and the information is diag(1 / sd^2). `gain` < 1 takes only part of the step,
/// as a search that needs several steps; `gain` above 1 overshoots, and above 2 wanders off. A
/// parameter listed in `sd_beyond` has that sd once it is more than `beyond` from the nominal frame.
class QuadraticBatch final : public TurnedBatch {
 public:
  std::map<std::pair<std::size_t, int>, double> best, sd, at, sd_beyond;
  double beyond = 0.0;
  double gain = 1.0;
  int steps = 0;
  std::vector<std::vector<TurnParameter>> asked;
  std::vector<std::pair<std::size_t, double>> held;   // (mounting, twist sd at the nominal frame)
  std::vector<TwistHeld> why;                          // ... and why, in the same order
  std::vector<std::size_t> restored;

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
      const double sd_here = sd_beyond.contains(key) && std::abs(at[key]) > beyond ? sd_beyond[key] : sd[key];
      s.information(i, i) = 1.0 / (sd_here * sd_here);
    }
    return s;
  }
  void turn(std::span<const TurnParameter> parameters, const Eigen::VectorXd& delta, const Eigen::MatrixXd&) override {
    for (std::size_t i = 0; i < parameters.size(); ++i) at[{parameters[i].mounting, parameters[i].axis}] += delta(static_cast<Eigen::Index>(i));
  }
  void restore(std::span<const std::size_t> mountings) override {
    for (const std::size_t k : mountings) {
      restored.push_back(k);
      for (int axis = 0; axis < 3; ++axis) at[{k, axis}] = 0.0;
    }
  }
  void hold(std::span<const TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd&, const TwistHeld& w) override {
    held.emplace_back(parameters[twist].mounting, w.sd_rad);
    why.push_back(w);
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
  EXPECT_EQ(b.why[0].reason, TwistHeld::Reason::SdAboveTolerance);
  EXPECT_TRUE(b.restored.empty()) << "nothing was turned before the hold";
  // The first step asked for both mountings, every later one for mounting 1 alone.
  ASSERT_GE(b.asked.size(), 2U);
  EXPECT_EQ(b.asked[0].size(), 6U);
  for (std::size_t s = 1; s < b.asked.size(); ++s)
    for (const TurnParameter& p : b.asked[s]) EXPECT_EQ(p.mounting, 1U);
  for (int axis = 0; axis < 3; ++axis) EXPECT_EQ((b.at[{2, axis}]), 0.0) << "mounting 2 stays at the nominal frame";
  EXPECT_NEAR((b.at[{1, 2}]), (b.best[{1, 2}]), 1e-12);
}

TEST(TurnSearch, ASearchThatDoesNotSettleIsUndoneAndItsTwistsHeld) {
  // Each step overshoots the least residual by 0.75 of the distance: after kTurnMaxSteps the
  // last step is still 1.75 * 0.75^11 = 0.074 of the 6e-3 start, far above kTurnSettled sd.
  QuadraticBatch b = two_mountings(1e-4);
  b.gain = 1.75;
  const std::vector<std::array<bool, 2>> tilts(3, {true, true});
  EXPECT_TRUE(search_turns(b, {1, 2}, tilts, kTolerance).empty());
  EXPECT_EQ(b.steps, kTurnMaxSteps);
  EXPECT_EQ(b.restored, (std::vector<std::size_t>{1, 2}));
  for (const auto& [key, value] : b.at) EXPECT_EQ(value, 0.0) << key.first << "/" << key.second << " back at the nominal frame";
  ASSERT_EQ(b.held.size(), 2U);
  for (std::size_t h = 0; h < 2; ++h) {
    const std::size_t k = h + 1;
    EXPECT_EQ(b.held[h].first, k);
    EXPECT_EQ(b.why[h].reason, TwistHeld::Reason::SearchDidNotSettle);
    EXPECT_DOUBLE_EQ(b.why[h].sd_rad, 1e-4);
    // Where the search stopped: the start's distance times (1 - (1 - gain)^steps).
    const double distance = b.best[{k, 2}];
    EXPECT_NEAR(b.why[h].found_rad, distance * (1.0 - std::pow(1.0 - b.gain, kTurnMaxSteps)), 1e-15);
  }
  // The same search with steps that shrink within kTurnSettled sd keeps where it stopped.
  QuadraticBatch slow = two_mountings(1e-4);
  slow.gain = 0.5;
  ASSERT_LT(0.5 * 6e-3 * std::pow(0.5, kTurnMaxSteps - 1), kTurnSettled * 1e-4);
  EXPECT_EQ(search_turns(slow, {1, 2}, tilts, kTolerance), (std::vector<std::size_t>{1, 2}));
  EXPECT_TRUE(slow.held.empty());
}

TEST(TurnSearch, ATwistFoundWhereItsSdExceedsTheToleranceIsHeldAndTheRestSearchedAgain) {
  // Mounting 2's twist is determined at the nominal frame (sd 1e-4) and not beyond 1e-3 of it
  // (sd twice the tolerance), where the least residual lies (6e-3).
  QuadraticBatch b = two_mountings(1e-4);
  b.sd_beyond[{2, 2}] = 2.0 * kTolerance;
  b.beyond = 1e-3;
  const std::vector<std::array<bool, 2>> tilts(3, {true, true});
  EXPECT_EQ(search_turns(b, {1, 2}, tilts, kTolerance), (std::vector<std::size_t>{1}));
  EXPECT_EQ(b.restored, (std::vector<std::size_t>{1, 2}));
  ASSERT_EQ(b.held.size(), 1U);
  EXPECT_EQ(b.held[0].first, 2U);
  EXPECT_EQ(b.why[0].reason, TwistHeld::Reason::SdAboveToleranceWhereFound);
  EXPECT_DOUBLE_EQ(b.why[0].found_rad, 6e-3);
  EXPECT_DOUBLE_EQ(b.why[0].found_sd_rad, 2.0 * kTolerance);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_EQ((b.at[{2, axis}]), 0.0) << "mounting 2 back at the nominal frame";
    EXPECT_NEAR((b.at[{1, axis}]), (b.best[{1, axis}]), 1e-12) << "mounting 1 searched again alone";
  }
  for (const TurnParameter& p : b.asked.back()) EXPECT_EQ(p.mounting, 1U);
}

TEST(TurnSearch, ABatchThatLosesItsFitOnTheWayIsUndoneAndItsTwistsHeld) {
  // The fit fails at the third step (a turned batch without a fit): the search has not settled,
  // and what it turned is undone.
  class LosesItsFit final : public TurnedBatch {
   public:
    QuadraticBatch quadratic = two_mountings(1e-4);
    std::optional<TurnStep> step(std::span<const TurnParameter> parameters) override {
      if (quadratic.steps == 2) return std::nullopt;
      return quadratic.step(parameters);
    }
    void turn(std::span<const TurnParameter> parameters, const Eigen::VectorXd& delta, const Eigen::MatrixXd& c) override {
      quadratic.turn(parameters, delta, c);
    }
    void restore(std::span<const std::size_t> mountings) override { quadratic.restore(mountings); }
    void hold(std::span<const TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd& i, const TwistHeld& w) override {
      quadratic.hold(parameters, twist, i, w);
    }
  } batch;
  batch.quadratic.gain = 0.5;
  const std::vector<std::array<bool, 2>> tilts(3, {true, true});
  EXPECT_TRUE(search_turns(batch, {1, 2}, tilts, kTolerance).empty());
  EXPECT_EQ(batch.quadratic.restored, (std::vector<std::size_t>{1, 2}));
  for (const auto& [key, value] : batch.quadratic.at) EXPECT_EQ(value, 0.0) << key.first << "/" << key.second;
  ASSERT_EQ(batch.quadratic.why.size(), 2U);
  for (const TwistHeld& w : batch.quadratic.why) {
    EXPECT_EQ(w.reason, TwistHeld::Reason::SearchDidNotSettle);
    EXPECT_GT(w.found_rad, 0.0) << "where the two steps taken left it";
  }
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
    void restore(std::span<const std::size_t>) override { ADD_FAILURE(); }
    void hold(std::span<const TurnParameter>, std::size_t, const Eigen::MatrixXd&, const TwistHeld&) override { ADD_FAILURE(); }
  } none;
  const std::vector<std::array<bool, 2>> tilts(2, {true, true});
  EXPECT_TRUE(search_turns(none, {1}, tilts, kTolerance).empty());
}

}  // namespace
