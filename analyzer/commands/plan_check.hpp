#pragma once
// `inertia-analyze plan-check --bench CONFIG`: before anything runs, what the bench's test plan
// will determine about the sensor under test and how well.
//
// The prediction is the procedure's own: the plan is simulated once with the sensor's expected
// parameters and noise ([sensor.truth]: what a datasheet gives), and characterize's pipeline runs
// on it with the same options. What a mounting's excitation cannot determine (excitation.hpp), the
// terms the plan leaves undetermined and why, and each determined parameter's sd: the inverse of
// the plan's Fisher information (the prewhitened regressors of the plan's motion, scaled by the
// noise's innovation variance), with the offsets between phases and the held mounting angles
// included as characterize includes them. One seed suffices for that: the regressors come from
// the motion, and the noise enters through its variance and colour, which 10^4 samples pin to a
// few per cent.
//
// `--seeds N` checks the prediction the way it would be checked on the bench: N more simulated
// runs of the plan (seeds after the bench's), the same model fitted to each, and the spread of
// every coefficient beside its predicted sd, with the spread's chi-square interval.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace inertia::commands {

struct PlanCheckOptions {
  std::filesystem::path bench;
  std::string sensor;                    // empty: the bench's first sensor under test
  std::vector<std::string> fixed_model;  // empty: the model characterize selects on the simulated run
  int seeds = 0;                         // > 0: check the predicted sd against the spread over seeds
  double alpha = 0.01;                   // characterize's selection level
};

/// One parameter the plan determines: its value on the simulated run, the predicted sd, and with
/// --seeds the spread over the runs and the 95 % interval of spread / sd for that many runs.
struct PlannedParameter {
  std::string name;                      // a batch term, or "mounting M about p (deg)"
  double value = 0.0;
  double predicted_sd = 0.0;              // as characterize reports it
  double held_sd = 0.0;                  // its part from the held angles' tolerance (the same every run)
  int runs = 0;                          // runs of the check that reported it (0: no check)
  double spread = 0.0;                   // sd over those runs
  double ratio_low = 0.0, ratio_high = 0.0;
  /// The noise's part of the predicted sd: what the spread over seeds measures.
  [[nodiscard]] double noise_sd() const { return std::sqrt(std::max(0.0, predicted_sd * predicted_sd - held_sd * held_sd)); }
  [[nodiscard]] double ratio() const { return spread / noise_sd(); }
  [[nodiscard]] bool consistent() const { return runs >= 2 && ratio() >= ratio_low && ratio() <= ratio_high; }
};

/// The check's findings, then run_plan_check prints them. Throws InputError for a bench it cannot
/// predict (not simulated, no [sensor.truth], unknown sensor) and for a plan that determines no
/// model (exit 2 with the pipeline's reason).
std::vector<PlannedParameter> plan_check(const PlanCheckOptions& options, std::ostream& out);

int run_plan_check(const PlanCheckOptions& options, std::ostream& out);

}  // namespace inertia::commands
