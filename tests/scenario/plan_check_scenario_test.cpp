// The excitation check before the test: inertia-analyze plan-check predicts from the bench
// file alone what the plan determines and each parameter's sd, and with --seeds checks that
// prediction against the spread over simulated runs, as the bench would.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "analyzer/commands/plan_check.hpp"
#include "common/input_error.hpp"
#include "common/parallel.hpp"

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


// The sim-paper-daq plan (a table mounting, a three-orientation shaker mounting): every parameter
// characterize reports is in the prediction and varies over the check's runs by the sensor's noise
// (each run reseeds the sensor too: with the bench seed alone the table's angles came out identical
// to 1e-15 over the runs), and its predicted sd is within the 25 % of the spread over 60
// seeds. The prediction is the RMS of characterize's sd over 10 runs: from one run, the bias read
// 1.61 times too small (that run's sd 2.4e-4 mA; over 60 runs they ranged 2.1e-4 to 7.5e-4, RMS
// 3.85e-4 against a spread of 3.84e-4), a_o^2 1.41 and a_p*a_o 1.45. Seen (2026-11-27): 0.96 to
// 1.21. Both the spread over 60 runs (+-9 % at one sd) and an RMS over 10 sd of few dof (about as
// much) are estimates, so 25 % is about two of their combined sd.
TEST(PlanCheck, ThePaperPlansPredictionAgainstTheSpreadOverSeeds) {
  PlanCheckOptions options;
  options.bench = config_path("sim-paper-daq.toml");
  options.seeds = 60;
  std::ostringstream out;
  const std::vector<PlannedParameter> planned = inertia::commands::plan_check(options, out);
  std::cout << out.str();
  for (const std::string term : {"1", "a_i", "a_i*a_p", "a_i*a_o", "a_p*a_o", "a_i^2", "a_p^2", "a_o^2"})
    EXPECT_TRUE(std::any_of(planned.begin(), planned.end(), [&](const PlannedParameter& p) { return p.name == term; })) << term;
  int angles = 0;
  for (const PlannedParameter& p : planned) {
    EXPECT_EQ(p.runs, options.seeds) << p.name;
    EXPECT_GT(p.predicted_sd, 0.0) << p.name;
    angles += p.name.rfind("mounting ", 0) == 0 ? 1 : 0;
    EXPECT_GE(p.ratio(), 0.75) << p.name;
    EXPECT_LE(p.ratio(), 1.25) << p.name;
  }
  EXPECT_EQ(angles, 4);
}

// The six-position tumble (placements of 3 mrad per axis per pose): the check's runs fit the
// model the first selected, and weigh the poses by what their placements leave as that run does,
// so the prediction and the spread are of one estimator. While the fixed model's noise model was
// fitted on residuals holding the poses' levels, it read a near unit root (AR(42) against AR(20) on
// seed 1) that all but removed the poses' means: over 20 seeds the scale factor's predicted sd was
// 9.5 times its spread (ratio 0.10), and the bias's spread 28 times the selected model's sd. Over
// 60 runs the spread is known to +-9 % (one sd) and the RMS over 10 runs about as well: 3 sd of the
// ratio is 0.72 to 1.28.
TEST(PlanCheck, ATumblesPredictionAgainstTheSpreadOverSeeds) {
  PlanCheckOptions options;
  options.bench = config_path("sim-tumble.toml");
  options.seeds = 60;
  std::ostringstream out;
  const std::vector<PlannedParameter> planned = inertia::commands::plan_check(options, out);
  std::cout << out.str();
  int angles = 0;
  for (const PlannedParameter& p : planned) {
    EXPECT_EQ(p.runs, options.seeds) << p.name;
    angles += p.name.rfind("mounting ", 0) == 0 ? 1 : 0;
    EXPECT_GE(p.ratio(), 0.72) << p.name;
    EXPECT_LE(p.ratio(), 1.28) << p.name;
  }
  EXPECT_EQ(planned.size(), 4U);
  EXPECT_EQ(angles, 2);
}

// The runs of the prediction and of the check are independent (each reseeds the bench): with
// --jobs 2 they run side by side, each on one thread, into slots of their own. The runs then do
// the arithmetic of a one-thread run, and only the first (which sets the model, before the others)
// splits its columns over the threads: the findings agree to rounding.
TEST(PlanCheck, TheRunsSideBySideGiveTheFindingsOfOneThread) {
  PlanCheckOptions options;
  options.bench = config_path("sim-paper-daq.toml");
  options.seeds = 6;
  std::ostringstream one_out, two_out;
  inertia::parallel::set_jobs(1);
  const std::vector<PlannedParameter> one = inertia::commands::plan_check(options, one_out);
  inertia::parallel::set_jobs(2);
  const std::vector<PlannedParameter> two = inertia::commands::plan_check(options, two_out);
  inertia::parallel::set_jobs(1);
  ASSERT_EQ(one.size(), two.size());
  const auto near = [](double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)) + 1e-300; };
  for (std::size_t k = 0; k < one.size(); ++k) {
    ASSERT_EQ(one[k].name, two[k].name);
    EXPECT_TRUE(near(one[k].value, two[k].value)) << one[k].name << ": " << one[k].value << " " << two[k].value;
    EXPECT_TRUE(near(one[k].predicted_sd, two[k].predicted_sd)) << one[k].name;
    EXPECT_TRUE(near(one[k].spread, two[k].spread)) << one[k].name;
    EXPECT_EQ(one[k].runs, options.seeds) << one[k].name;
    EXPECT_EQ(two[k].runs, options.seeds) << one[k].name;
  }
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
