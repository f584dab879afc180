// Every simulated bench in config/ characterizes with default options, and what it
// reports as determined is within 3 sd of the simulator's truth. The sensors, simulated in-process
// over several seeds:
//   sim-paper-daq acc1 (the paper's plan at 1 kHz: a table mounting and a three-orientation shaker
//   mounting turned 1.155 deg about n_i by its case misalignment, which algorithm 1 cannot see:
//   with the twist held at the nominal frame the cross terms missed the truth by 14-33 sd in
//   every seed; PipelineOptions::batch_relative_twist; sim-paper itself is the same plan at
//   10 kHz, scored by reproduce-paper),
//   sim-rotation-table acc1 (multipoint + rate series) and fog1 (a gyroscope, eq. 5),
//   sim-shaker acc-a and acc-b (three separate one-axis shaker mountings, no alignment reference),
//   sim-thermal acc1 (two static poses through thermal steps), sim-tumble mems1 (six poses with a
//   random placement error each), sim-gyro-thermal fog1 (a gyroscope on a rate table in the
//   thermal fixture: eq. 5's temperature terms c_T and epsilon_T), sim-imu ax and gx (a unit's
//   accelerometer and gyroscope on a tumble and a rate table in one dividing head, then in a cube
//   on a shaker that takes the dividing head's bias: the gyroscope's tilts each rest on one spin
//   case, whose placement its sd carries, procedure/placement.hpp).
// A term the truth does not have counts against 0. Misalignment: each aligned mounting's angles
// about p and o against the true M_C^S relative to its nominal case frame.
// The seeds here are what CI time allows (INERTIA_SCENARIO_SEEDS raises them, e.g. to 20).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "analyzer/ident/statistics.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "common/config/bench_config.hpp"
#include "common/units.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/sensor_truth.hpp"
#include "hal/sim/simulate.hpp"

namespace {

using inertia::procedure::PipelineResult;

/// z against Student's t on the estimate's dof (normal for many): "within 3 sd" is the two-sided
/// 99.73 % quantile, "covered" the 95 % one.
struct Scores {
  int within = 0, total = 0;
  int covered = 0;
  std::vector<std::string> misses;
  /// Per parameter (`what` without its "seed N "): |z| and whether the 95 % interval covered.
  std::map<std::string, std::vector<std::pair<double, bool>>> by_parameter;
  void add(const std::string& what, double z, double dof) {
    ++total;
    const double p = inertia::ident::student_t_two_sided_p(z, std::isfinite(dof) ? dof : 1e9);
    if (p >= 0.0027) ++within;
    if (p >= 0.05) ++covered;
    if (p < 0.0027) misses.push_back(what + " z " + std::to_string(z) + " dof " + std::to_string(dof));
    const std::size_t space = what.rfind("seed ", 0) == 0 ? what.find(' ', 5) : std::string::npos;
    by_parameter[space == std::string::npos ? what : what.substr(space + 1)].emplace_back(std::abs(z), p >= 0.05);
  }
};

int seeds_from_environment(int fallback) {
  const char* text = std::getenv("INERTIA_SCENARIO_SEEDS");
  return text != nullptr ? std::max(1, std::atoi(text)) : fallback;
}

/// As if the bench file said `seed = <seed>` (the loader derives the sensors' seeds from it).
inertia::config::BenchConfig with_seed(inertia::config::BenchConfig bench, std::uint64_t seed) {
  inertia::config::reseed(bench, seed);
  return bench;
}

/// A mounting's estimated M_C^S against the truth of its first case (the sensor's M_C^S with the
/// case's mounting rotation), about n_i (rad): what its twist misses.
double twist_against_truth(const inertia::procedure::MountingResult& m, const inertia::sim::BenchSimulation& sim) {
  const auto& c = sim.cases.at(m.cases.front()).sensors.at(0);
  const Eigen::AngleAxisd error(Eigen::Matrix3d(m.m_cs * (c.m_cs * c.mounting.case_rotation).transpose()));
  return error.angle() * error.axis()(0);
}

std::map<std::string, double> truth_terms(const inertia::sim::BenchSimulation& sim, std::size_t sensor) {
  const toml::table t = std::visit([](const auto& p) { return inertia::sim::model_terms(p, nullptr); }, sim.params.at(sensor));
  std::map<std::string, double> out;
  for (const auto& [key, node] : t) out[std::string(key.str())] = node.value<double>().value_or(0.0);
  return out;
}

/// The term with every lag taken off ("T[k-1]" -> "T").
std::string unlagged(const std::string& label) {
  std::vector<inertia::ident::Factor> factors = inertia::ident::parse_term(label).factors();
  for (inertia::ident::Factor& f : factors) f.lag = 0;
  return inertia::ident::Term::from_factors(std::move(factors)).to_string();
}

/// Scores one characterization against the truth of the simulation it came from. A term that is
/// the only one of its lags in the model (T[k-1] without T: a temperature that moves over minutes
/// makes T(k) and T(k-1) one column) stands for their static gain, the truth's sum over its lags.
void score(const PipelineResult& r, const inertia::sim::BenchSimulation& sim, std::size_t sensor,
           const std::map<std::string, double>& truth, std::uint64_t seed, Scores& s) {
  for (Eigen::Index j = 0; j < r.fit.process_terms; ++j) {
    const std::string& term = r.fit.labels[static_cast<std::size_t>(j)];
    const std::string base = unlagged(term);
    int lags_in_model = 0;
    for (Eigen::Index k = 0; k < r.fit.process_terms; ++k) lags_in_model += unlagged(r.fit.labels[static_cast<std::size_t>(k)]) == base ? 1 : 0;
    double want = 0.0;
    for (const auto& [name, value] : truth)
      if (lags_in_model == 1 ? unlagged(name) == base : name == term) want += value;
    const double dof = j < r.test_dof.size() ? r.test_dof(j) : 1e9;
    s.add("seed " + std::to_string(seed) + " " + term, (r.fit.theta(j) - want) / r.fit.std_dev(j), dof);
  }
  for (const auto& m : r.mountings) {
    if (!m.aligned) continue;
    const auto& c = sim.cases.at(m.cases.front()).sensors.at(sensor);
    // The mounting's truth: the sensor in its case turned by the case misalignment (without a
    // case's own fixture or placement error, which differ between the cases of one mounting), in
    // algorithm 1's convention: the true input axis in the nominal case frame, turned onto by the
    // smallest rotation (a twist about n_i is not a single-axis sensor's to see).
    const inertia::frames::Dcm true_m_cs = c.m_cs * c.mounting.case_rotation;
    const Eigen::Vector3d truth_angles = inertia::procedure::rotation_vector(inertia::procedure::misalignment_from_sensitivities(
        true_m_cs.row(0).transpose(), inertia::frames::Dcm::Identity()));
    for (int a = 1; a < 3; ++a) {
      if (!(m.angles_sd(a) > 0.0)) continue;   // held
      s.add("seed " + std::to_string(seed) + " mounting " + m.mounting + (a == 1 ? " about p" : " about o"),
            (m.angles(a) - truth_angles(a)) / m.angles_sd(a), m.angles_dof);
    }
  }
}

struct Bench {
  const char* file;
  std::size_t sensor;
  /// The target: at least this share of the estimates within 3 sd of the truth.
  double required = 0.95;
};

class EveryBench : public ::testing::TestWithParam<Bench> {};

TEST_P(EveryBench, DefaultCharacterizeReportsOnlyWhatItDeterminesWithinThreeSd) {
  const Bench b = GetParam();
  const inertia::config::BenchConfig file =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / b.file);
  Scores s;
  const int seeds = seeds_from_environment(4);
  for (int k = 0; k < seeds; ++k) {
    const std::uint64_t seed = 101 + static_cast<std::uint64_t>(k);
    const inertia::config::BenchConfig bench = with_seed(file, seed);
    const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
    const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, b.sensor);
    PipelineResult r;
    ASSERT_NO_THROW(r = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, b.file)) << "seed " << seed;
    ASSERT_GE(r.fit.process_terms, 1) << "seed " << seed;
    score(r, sim, b.sensor, truth_terms(sim, b.sensor), seed, s);
  }
  std::printf("%s sensor %zu: %d of %d estimates within 3 sd of truth, %d within 1.96 sd\n", b.file, b.sensor, s.within,
              s.total, s.covered);
  for (const std::string& m : s.misses) std::printf("  outside: %s\n", m.c_str());
  // At most (1 - required) of the estimates outside, rounded up.
  EXPECT_LE(s.total - s.within, static_cast<int>(std::ceil((1.0 - b.required) * static_cast<double>(s.total) - 1e-9)));
}

INSTANTIATE_TEST_SUITE_P(Configs, EveryBench,
                         ::testing::Values(Bench{"sim-paper-daq.toml", 0}, Bench{"sim-rotation-table.toml", 0}, Bench{"sim-rotation-table.toml", 1},
                                           Bench{"sim-shaker.toml", 0}, Bench{"sim-shaker.toml", 1},
                                           Bench{"sim-thermal.toml", 0}, Bench{"sim-tumble.toml", 0}, Bench{"sim-gyro-thermal.toml", 0},
                                           Bench{"sim-imu.toml", 0}, Bench{"sim-imu.toml", 3}),
                         [](const ::testing::TestParamInfo<Bench>& info) {
                           std::string name = std::string(info.param.file) + "_" + std::to_string(info.param.sensor);
                           for (char& ch : name)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return name;
                         });

// The paper's plan with a quiet sensor (white 1e-5 g, no pink noise), where its data determine the
// shaker mounting's twist about n_i against the table (PipelineOptions::batch_relative_twist): the
// shaker's case misalignment, 2 deg about case [1,1,1], holds 1.155 deg of it, which algorithm 1
// cannot see. Over 4 seeds the batch finds it (not held), the shaker's M_C^S then differs from the
// truth about n_i by at most 3 of the twist's sd, and every estimate is within 3 sd of the truth.
// Held, the cross terms were 100 sd off on such data (-6.3, +3.0, +3.3 %). Measured 2026-11-27:
// 1.146 to 1.161 deg, 0.002 to 0.009 deg from the truth, sd 0.10 to 0.11 deg: conservative here,
// where the offsets between phases the sd includes are the references' and the model's own small
// errors, the same in every seed, rather than noise.
TEST(RelativeTwist, TheBatchFindsTheShakersTurnAboutTheInputAxisAgainstTheTable) {
  inertia::config::BenchConfig file =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper-daq.toml");
  for (inertia::config::TruthValue& v : file.sensors.at(0).truth) {
    if (v.name == "white_sd_g") v.values = {1e-5};
    if (v.name == "pink_sd_g") v.values = {0.0};
  }
  Scores s;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const inertia::config::BenchConfig bench = with_seed(file, seed);
    const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
    const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
    const PipelineResult r = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, "quiet paper");
    ASSERT_EQ(r.mountings.size(), 2u);
    const inertia::procedure::MountingResult& shaker = r.mountings[1];
    ASSERT_EQ(shaker.twist_reference, r.mountings[0].mounting) << "seed " << seed;
    ASSERT_GT(shaker.angles_sd(0), 0.0) << "seed " << seed << ": the twist was held";
    const double twist_error = twist_against_truth(shaker, sim);
    std::printf("seed %u: shaker turned %+.4f +- %.4f deg about n_i; against the truth %+.5f deg\n",
                static_cast<unsigned>(seed), inertia::rad_to_deg(shaker.angles(0)), inertia::rad_to_deg(shaker.angles_sd(0)),
                inertia::rad_to_deg(twist_error));
    EXPECT_LE(std::abs(twist_error), 3.0 * shaker.angles_sd(0)) << "seed " << seed;
    score(r, sim, 0, truth_terms(sim, 0), seed, s);
  }
  std::printf("quiet paper: %d of %d estimates within 3 sd of truth\n", s.within, s.total);
  for (const std::string& m : s.misses) std::printf("  outside: %s\n", m.c_str());
  EXPECT_EQ(s.within, s.total);
}

// The paper's plan (sim-paper, 10 kHz, table 1's 1/f noise) with every dwell 64 s instead of 1 s:
// long rests whose means the flicker moves far more than the whitened residual's white part says.
// Counted as white, those means made the shaker mounting's twist about n_i look determined within
// the 1 deg tolerance on this seed, and the batch estimated it degrees off with the cross terms
// and the scale factor many sd from the truth. The search's sd under each case's fitted residual
// spectrum (relative_twists.cpp) says the rests do not determine it: it is held, and every
// estimate is within 3 sd of the truth. One seed (5.5 M rows); the figures, and those over more
// seeds, in docs/validation.md, 'Long rests'.
TEST(RelativeTwist, LongRestsLeaveTheTwistToWhatTheirMeansCanCarry) {
  inertia::config::BenchConfig file =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper.toml");
  for (inertia::config::TestCase& c : file.cases)
    for (inertia::config::Phase& phase : c.phases)
      if (phase.kind == inertia::config::PhaseKind::Dwell) phase.duration_s *= 64.0;
  constexpr std::uint64_t kSeed = 101;
  const inertia::config::BenchConfig bench = with_seed(file, kSeed);
  const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
  const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
  const PipelineResult r = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, "paper, long rests");
  ASSERT_EQ(r.mountings.size(), 2u);
  const inertia::procedure::MountingResult& shaker = r.mountings[1];
  const double twist_error = twist_against_truth(shaker, sim);
  std::printf("long rests: shaker twist %+.4f +- %.4f deg (sd 0: held); against the truth %+.4f deg\n",
              inertia::rad_to_deg(shaker.angles(0)), inertia::rad_to_deg(shaker.angles_sd(0)), inertia::rad_to_deg(twist_error));
  if (shaker.angles_sd(0) > 0.0) {
    EXPECT_LE(std::abs(twist_error), 3.0 * shaker.angles_sd(0)) << "an estimated twist";
  }
  Scores s;
  score(r, sim, 0, truth_terms(sim, 0), kSeed, s);
  std::printf("long rests: %d of %d estimates within 3 sd of truth\n", s.within, s.total);
  for (const std::string& m : s.misses) std::printf("  outside: %s\n", m.c_str());
  EXPECT_EQ(s.within, s.total);
}

// The six-position tumble (IEEE Std 1293) with 3 mrad placement error per axis per pose and a
// linear sensor, over 100 seeds (INERTIA_SCENARIO_SEEDS to change): a term beyond bias and scale
// factor in at most 5 % of the seeds, and the 95 % intervals (Student's t on each estimate's dof)
// of bias, scale factor and both misalignment angles cover the truth in 90 to 99 % of the cases
// (their sd are the scatter the placement error makes, not the white noise's). A binomial sd of
// the coverage of 400 intervals is 1.1 %. Each parameter's intervals cover in at least 85 %, and
// the scale factor's sd is not the poses' common offset: with that (before the placements' shape
// on few dof, ident::cluster_offsets) its median |z| was 0.024 over 200 seeds, 35 times too wide.
// Bias and scale factor are as precise as the classical six-position formulas on the same data
// ((up + down) / 2 and (up - down) / 2g): their rms errors over the seeds within 20 % of those.
// Least squares weighed the four poses a placement tilt moves like the two it hardly moves, and its
// bias missed by 1.26e-3 g on seed 1, where (up + down) / 2 missed by 2.3e-5; the random-effects
// weights (ident::random_effects_fit) take the bias and scale factor from those two.
// Measured 2026-11-27, 200 seeds: 752 of 800 cover; bias 189, scale factor 190, angles 188 and
// 185 (the placements' exact absorbed share; with G / dof they were 89 and 92 of 100); rms error /
// the classical formula's: bias 1.012, scale factor 0.932; no spurious term.
TEST(SixPositionTumble, NoSpuriousTermsAndHonestIntervalsOverSeeds) {
  const inertia::config::BenchConfig file =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-tumble.toml");
  const int seeds = seeds_from_environment(100);
  int spurious_seeds = 0;
  Scores s;
  std::map<std::string, std::pair<double, double>> square_errors;   // per term: characterize's, the classical formula's
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(seeds); ++seed) {
    const inertia::config::BenchConfig bench = with_seed(file, seed);
    const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
    const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
    const PipelineResult r = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, "tumble");
    bool spurious = false;
    for (Eigen::Index j = 0; j < r.fit.process_terms; ++j) {
      const std::string& term = r.fit.labels[static_cast<std::size_t>(j)];
      if (term != "1" && term != "a_i") spurious = true;
    }
    spurious_seeds += spurious ? 1 : 0;
    if (spurious) {
      std::string terms;
      for (Eigen::Index j = 0; j < r.fit.process_terms; ++j)
        terms += " " + r.fit.labels[static_cast<std::size_t>(j)] + " " + std::to_string(r.fit.theta(j) / r.fit.std_dev(j)) + " (t)";
      std::printf("seed %u: spurious terms in the batch model:%s\n", static_cast<unsigned>(seed), terms.c_str());
    }
    score(r, sim, 0, truth_terms(sim, 0), seed, s);
    // The classical six-position formulas on the same data: the input axis up and down.
    const auto mean_of = [&](const std::string& name) {
      for (const auto& c : data.cases)
        if (c.name == name) return std::pair{c.y.mean(), c.a_e.rowwise().norm().mean()};
      throw std::logic_error("no case " + name);
    };
    const auto [up, g_up] = mean_of("ira-up");
    const auto [down, g_down] = mean_of("ira-down");
    const std::map<std::string, double> truth = truth_terms(sim, 0);
    for (Eigen::Index j = 0; j < r.fit.process_terms; ++j) {
      const std::string& term = r.fit.labels[static_cast<std::size_t>(j)];
      if (term != "1" && term != "a_i") continue;
      const double classical = term == "1" ? (up + down) / 2.0 : (up - down) / (g_up + g_down);
      const double error = r.fit.theta(j) - truth.at(term), classical_error = classical - truth.at(term);
      square_errors[term].first += error * error;
      square_errors[term].second += classical_error * classical_error;
    }
  }
  std::printf("tumble: %d of %d seeds with spurious terms; %d of %d intervals cover the truth (95 %% nominal)\n",
              spurious_seeds, seeds, s.covered, s.total);
  for (const std::string term : {"1", "a_i"}) {
    const double ratio = std::sqrt(square_errors[term].first / square_errors[term].second);
    std::printf("  %s: rms error %.3g, the classical formula's %.3g (ratio %.3f)\n", term.c_str(),
                std::sqrt(square_errors[term].first / seeds), std::sqrt(square_errors[term].second / seeds), ratio);
    EXPECT_LT(ratio, 1.2) << term;
  }
  EXPECT_LE(spurious_seeds, std::max(1, seeds / 20));
  ASSERT_GT(s.total, 0);
  const double coverage = static_cast<double>(s.covered) / static_cast<double>(s.total);
  EXPECT_GE(coverage, 0.90);
  // Upper bounds from 100 seeds (the default) on: at 95 %, 20 intervals all cover 36 % of the time.
  const bool enough_for_upper = seeds >= 100;
  if (enough_for_upper) {
    EXPECT_LE(coverage, 0.99);
  }
  for (const std::string name : {"1", "a_i", "mounting poses about p", "mounting poses about o"}) {
    const auto& v = s.by_parameter[name];
    ASSERT_GE(v.size(), static_cast<std::size_t>(seeds) - 1) << name;
    std::vector<double> z;
    int covered = 0;
    for (const auto& [abs_z, cover] : v) {
      z.push_back(abs_z);
      covered += cover ? 1 : 0;
    }
    std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 2), z.end());
    const double median = z[z.size() / 2];
    std::printf("  %s: %d of %zu cover, median |z| %.3f\n", name.c_str(), covered, v.size(), median);
    EXPECT_GE(covered, 0.85 * static_cast<double>(v.size())) << name;
    if (enough_for_upper) {
      EXPECT_LE(covered, 0.99 * static_cast<double>(v.size())) << name;
    }
    if (name == "a_i") {
      EXPECT_GT(median, 0.3) << "the scale factor's sd is many times its spread";
    }
  }
}

// A user who fixes the tumble's model to the terms the selection keeps (characterize
// --fixed-model 1,a_i, and plan-check's check runs) gets the selected model's estimate: on a plan
// of poses the noise model is fitted about each placed pose's level (whiten_problem), never on the
// levels the placements leave. Fitted on them it read a near unit root (AR(42) against AR(20)),
// which all but removed the poses' means: on seed 1 the bias missed by 1.23e-3 g with sd 1.19e-3 g,
// against 2.3e-5 and 3.2e-5 for the selected model.
TEST(SixPositionTumble, AFixedModelOfTheSelectedTermsGivesTheSelectedEstimate) {
  const inertia::config::BenchConfig file =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-tumble.toml");
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const inertia::config::BenchConfig bench = with_seed(file, seed);
    const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
    const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
    const PipelineResult selected = inertia::procedure::run_pipeline(data, inertia::procedure::PipelineOptions{}, "tumble");
    inertia::procedure::PipelineOptions fixed_options;
    fixed_options.batch.select = false;
    for (Eigen::Index j = 0; j < selected.fit.process_terms; ++j)
      fixed_options.batch.fixed_terms.push_back(selected.fit.labels[static_cast<std::size_t>(j)]);
    const PipelineResult fixed = inertia::procedure::run_pipeline(data, fixed_options, "tumble, fixed model");
    ASSERT_EQ(fixed.fit.process_terms, selected.fit.process_terms) << "seed " << seed;
    const std::map<std::string, double> truth = truth_terms(sim, 0);
    for (Eigen::Index j = 0; j < selected.fit.process_terms; ++j) {
      const std::string& term = selected.fit.labels[static_cast<std::size_t>(j)];
      const auto k = static_cast<Eigen::Index>(std::find(fixed.fit.labels.begin(), fixed.fit.labels.end(), term) - fixed.fit.labels.begin());
      ASSERT_LT(k, fixed.fit.process_terms) << term;
      std::printf("seed %u %s: selected %.8g (sd %.3g), fixed %.8g (sd %.3g), truth %.8g\n", static_cast<unsigned>(seed),
                  term.c_str(), selected.fit.theta(j), selected.fit.std_dev(j), fixed.fit.theta(k), fixed.fit.std_dev(k), truth.at(term));
      // One model on one noise model: the same estimate but for the order of the sums.
      EXPECT_NEAR(fixed.fit.theta(k), selected.fit.theta(j), 1e-9 * std::abs(selected.fit.theta(j)) + 1e-3 * selected.fit.std_dev(j)) << term;
      EXPECT_NEAR(fixed.fit.std_dev(k), selected.fit.std_dev(j), 1e-6 * selected.fit.std_dev(j)) << term;
      EXPECT_LE(std::abs(fixed.fit.theta(k) - truth.at(term)), 4.0 * fixed.fit.std_dev(k)) << term << ", seed " << seed;
    }
  }
}

}  // namespace
