// Issue 12, "excitation check before the test": inertia-analyze plan-check predicts from the bench
// file alone what the plan determines and each parameter's sd, and with --seeds checks that
// prediction against the spread over simulated runs, as the bench would.
#include <gtest/gtest.h>

#include <boost/math/distributions/chi_squared.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "analyzer/commands/plan_check.hpp"
#include "common/input_error.hpp"

namespace {

namespace fs = std::filesystem;
using inertia::commands::PlanCheckOptions;
using inertia::commands::PlannedParameter;

fs::path config_path(const std::string& name) { return fs::path(INERTIA_SOURCE_DIR) / "config" / name; }

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The ratio's two-sided interval at `level` for a sample sd over `runs` runs: sqrt(chi2(n-1)/(n-1)).
std::pair<double, double> ratio_interval(int runs, double level) {
  const double dof = runs - 1.0;
  const boost::math::chi_squared chi(dof);
  return {std::sqrt(boost::math::quantile(chi, (1.0 - level) / 2.0) / dof),
          std::sqrt(boost::math::quantile(chi, 1.0 - (1.0 - level) / 2.0) / dof)};
}

// The sim-paper-daq plan (a table mounting, a three-orientation shaker mounting): every parameter
// characterize reports is in the prediction and varies over the check's runs by the sensor's noise
// (each run reseeds the sensor too: with the bench seed alone the table's angles came out identical
// to 1e-15 over the runs), and its predicted sd is within the 99 % interval of the spread over 20
// seeds. Three are not, over 60 seeds (`plan-check --seeds 60`, 2026-11-26): the bias spreads 1.59
// times its sd, a_o^2 and a_p*a_o 1.40 and 1.43 (20 seeds: 1.40, 1.56, 1.62).
//  - The bias: each case's noise is taken as independent of the next case's, and the bench's 1/f
//    noise is not (probably; not shown).
//  - a_o^2 and a_p*a_o: the shaker mounting's turn about n_i (1.15 deg of its 2 deg about
//    [1,1,1]) is held at the nominal frame, since algorithm 1 cannot see it, and the frame error it
//    leaves moves these two by an amount that depends on each run's random vibration. With the turn
//    estimated (PipelineOptions::estimate_twist) they came out at 1.00 and 1.02 while the turn's own
//    wander spoiled the rest (measured once, with a variant of this covariance that also carried
//    the sensor's 1/f law down to the whole plan; not repeated).
// They are asserted below 2, so that they cannot get worse unseen; the closing note says issue 12's
// 25 % is not met for them.
TEST(PlanCheck, ThePaperPlansPredictionAgainstTheSpreadOverSeeds) {
  PlanCheckOptions options;
  options.bench = config_path("sim-paper-daq.toml");
  options.seeds = 20;
  std::ostringstream out;
  const std::vector<PlannedParameter> planned = inertia::commands::plan_check(options, out);
  std::cout << out.str();
  const auto [low, high] = ratio_interval(options.seeds, 0.99);
  for (const std::string term : {"1", "a_i", "a_i*a_p", "a_i*a_o", "a_p*a_o", "a_i^2", "a_p^2", "a_o^2"})
    EXPECT_TRUE(std::any_of(planned.begin(), planned.end(), [&](const PlannedParameter& p) { return p.name == term; })) << term;
  int angles = 0;
  for (const PlannedParameter& p : planned) {
    EXPECT_EQ(p.runs, options.seeds) << p.name;
    EXPECT_GT(p.predicted_sd, 0.0) << p.name;
    angles += p.name.rfind("mounting ", 0) == 0 ? 1 : 0;
    EXPECT_GE(p.ratio(), low) << p.name;
    const bool known_excess = p.name == "1" || p.name == "a_o^2" || p.name == "a_p*a_o";
    EXPECT_LE(p.ratio(), known_excess ? 2.0 : high) << p.name;
  }
  EXPECT_EQ(angles, 4);
}

TEST(PlanCheck, WhatItCannotPredictFromExitsTwoSayingWhy) {
  PlanCheckOptions real;
  real.bench = config_path("bench-template.toml");
  std::ostringstream sink;
  try {
    (void)inertia::commands::plan_check(real, sink);
    ADD_FAILURE() << "a real bench was predicted";
  } catch (const inertia::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("[sensor.truth]"), std::string::npos) << e.what();
  }

  PlanCheckOptions unknown;
  unknown.bench = config_path("sim-rotation-table.toml");
  unknown.sensor = "acc9";
  try {
    (void)inertia::commands::plan_check(unknown, sink);
    ADD_FAILURE() << "an unknown sensor was predicted";
  } catch (const inertia::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("acc1, fog1"), std::string::npos) << e.what();
  }

  // One static pose determines nothing: the message names the case and the excitation missing.
  const fs::path one_pose = fs::temp_directory_path() / "plan-check-one-pose.toml";
  {
    const std::string tumble = read_text(config_path("sim-tumble.toml"));
    const std::size_t second_case = tumble.find("[[case]]", tumble.find("[[case]]") + 1);
    std::ofstream(one_pose) << tumble.substr(0, second_case);
  }
  PlanCheckOptions nothing;
  nothing.bench = one_pose;
  try {
    (void)inertia::commands::plan_check(nothing, sink);
    ADD_FAILURE() << "one pose was predicted";
  } catch (const inertia::InputError& e) {
    const std::string why = e.what();
    EXPECT_NE(why.find("determines nothing"), std::string::npos) << why;
    EXPECT_NE(why.find("ira-up"), std::string::npos) << why;
  }
  fs::remove(one_pose);
}

// Every shipped simulated bench gets a prediction with default options (what characterize would
// determine there, and what not): the gyro on the rate table, the shaker-only and thermal plans.
TEST(PlanCheck, EveryShippedSimulatedBenchGetsAPrediction) {
  for (const std::string name :
       {"sim-rotation-table.toml", "sim-shaker.toml", "sim-thermal.toml", "sim-tumble.toml", "sim-gyro-thermal.toml"}) {
    PlanCheckOptions options;
    options.bench = config_path(name);
    std::ostringstream out;
    const std::vector<PlannedParameter> planned = inertia::commands::plan_check(options, out);
    std::cout << "[ figures ] " << name << ": " << planned.size() << " parameter(s) determined\n";
    EXPECT_FALSE(planned.empty()) << name << "\n" << out.str();
    EXPECT_NE(out.str().find("determined by this plan"), std::string::npos) << name;
  }
  PlanCheckOptions gyro;
  gyro.bench = config_path("sim-rotation-table.toml");
  gyro.sensor = "fog1";
  std::ostringstream out;
  EXPECT_FALSE(inertia::commands::plan_check(gyro, out).empty()) << out.str();
  std::cout << out.str();
}

}  // namespace
