// Blocks 5-6 on the simulated paper experiment (config/sim-paper.toml: table 1's accelerometer,
// the rotation-table test and the three shaker orientations of Fig. 2), three seeds, simulated
// in-process. The figure is the paper's table 2: the angle between the true and the estimated
// input axis, with the paper's simple model (1, a_x, a_y, a_z) and its complete model (eq. 2 with
// r = 0 and without the sign/abs terms, section 3.2), both fixed.
//
// Where the thresholds come from (seeds 1-7 at the time of writing, default PipelineOptions):
//   rotation table, complete: median 0.0039 deg (seeds spread 0.0009-0.017): the pink noise of
//     table 1 at the rotation frequency and below (noise-free data gives < 1e-5 deg);
//   shaker, complete: 0.0031 deg (0.0030-0.0032): nearly all of it the model error left by the
//     twist about n_i that algorithm 1 cannot see (noise-free: 0.0031 deg; with the twist known,
//     PipelineOptions::estimate_twist, 2e-5 deg);
//   simple model: table 0.031-0.054 deg, shaker 0.064-0.098 deg (the unmodelled quadratic terms).
// The paper's targets (table 2) are 0.0043 deg (table) and 0.0130 deg (shaker) for the complete
// model. The test asserts the shaker target per seed, the table at 0.008 deg for the median of
// three seeds (2x the 7-seed median: the seeds' spread) and 0.03 deg per seed (0.030 deg was the
// median with one slow revolution per axis), and the simple model clearly worse (x2 on the
// table, x5 on the shaker). The batch (block 10, complete model, seed 1) must recover the
// quadratic coefficients of eq. 12 within 15% (observed: 2.5% for the squares, 6% for the cross
// terms, the rest is the mountings' twist) and the scale factor within 1e-3.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <map>
#include <variant>
#include <string>
#include <vector>

#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "common/config/bench_config.hpp"
#include "common/units.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/sensors/accelerometer_model.hpp"
#include "hal/sim/simulate.hpp"

namespace {

using inertia::procedure::PipelineOptions;

PipelineOptions fixed(const std::vector<std::string>& misalignment) {
  PipelineOptions p;
  p.misalignment.select = false;
  p.misalignment.fixed_terms = misalignment;
  p.batch.select = false;
  p.batch.fixed_terms = {"1", "a_i"};
  return p;
}

struct Errors {
  double table_deg = 0.0;
  double shaker_deg = 0.0;   // the worst of the three orientations (they share one mounting)
};

Errors errors(const inertia::dataset::Dataset& data, const std::vector<inertia::frames::Dcm>& truth,
              const PipelineOptions& options) {
  const auto result = inertia::procedure::run_pipeline(data, options, "paper");
  Errors e;
  for (std::size_t c = 0; c < data.cases.size(); ++c) {
    const double err = inertia::rad_to_deg(inertia::procedure::input_axis_error(truth[c], result.cases[c].m_es));
    if (data.cases[c].kind == inertia::dataset::CaseKind::RotationTable) {
      e.table_deg = std::max(e.table_deg, err);
    } else {
      e.shaker_deg = std::max(e.shaker_deg, err);
    }
  }
  return e;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

TEST(PaperMisalignment, CompleteModelReachesTheNoiseFloorAndBeatsTheSimpleOne) {
  const std::vector<std::string> simple = {"1", "a_x", "a_y", "a_z"};
  const std::vector<std::string> complete = {"1",     "a_x",     "a_y",     "a_z",     "a_i^2",
                                             "a_p^2", "a_o^2",   "a_i*a_p", "a_i*a_o", "a_p*a_o"};
  inertia::config::BenchConfig bench =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper.toml");
  std::vector<double> table_complete, table_simple;
  for (const std::uint64_t seed : {1U, 2U, 3U}) {
    inertia::config::reseed(bench, seed);   // as if the bench file said `seed = <seed>`
    const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
    const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
    std::vector<inertia::frames::Dcm> truth;
    for (const auto& c : sim.cases) truth.push_back(c.sensors.at(0).m_cs * c.sensors.at(0).mounting.true_m_ec);

    const Errors c = errors(data, truth, fixed(complete));
    const Errors s = errors(data, truth, fixed(simple));
    std::printf("seed %u: complete table %.5f shaker %.5f deg; simple table %.5f shaker %.5f deg\n",
                static_cast<unsigned>(seed), c.table_deg, c.shaker_deg, s.table_deg, s.shaker_deg);
    EXPECT_LT(c.shaker_deg, 0.0130) << "seed " << seed;
    EXPECT_LT(c.table_deg, 0.03) << "seed " << seed;
    EXPECT_GT(s.shaker_deg, 5.0 * c.shaker_deg) << "seed " << seed;
    table_complete.push_back(c.table_deg);
    table_simple.push_back(s.table_deg);
  }
  EXPECT_LT(median(table_complete), 0.008);
  EXPECT_GT(median(table_simple), 2.0 * median(table_complete));
}

TEST(PaperMisalignment, BatchRecoversTheQuadraticCoefficients) {
  inertia::config::BenchConfig bench =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper.toml");
  inertia::config::reseed(bench, 1);
  const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
  const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 0);
  const auto* truth = std::get_if<inertia::sim::AccelerometerParams>(&sim.params.at(0));
  ASSERT_NE(truth, nullptr);

  PipelineOptions p = fixed({"1", "a_x", "a_y", "a_z", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o"});
  p.batch.fixed_terms = {"1", "a_i", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o"};
  const auto result = inertia::procedure::run_pipeline(data, p, "paper");
  // Model coefficients are output unit per SI input (m/s^2); the truth is per g.
  const double g0 = 9.80665;
  const std::map<std::string, double> expected = {
      {"a_i", truth->k_i / g0},
      {"a_i^2", truth->k_i * truth->k_ii / (g0 * g0)},
      {"a_p^2", truth->k_i * truth->k_pp / (g0 * g0)},
      {"a_o^2", truth->k_i * truth->k_oo / (g0 * g0)},
      {"a_i*a_p", truth->k_i * truth->k_ip / (g0 * g0)},
      {"a_i*a_o", truth->k_i * truth->k_io / (g0 * g0)},
      {"a_p*a_o", truth->k_i * truth->k_po / (g0 * g0)},
  };
  ASSERT_TRUE(result.square_corner_rad_s.has_value());
  for (const auto& [name, value] : expected) {
    const auto it = std::find(result.fit.labels.begin(), result.fit.labels.end(), name);
    ASSERT_NE(it, result.fit.labels.end()) << name;
    const double estimate = result.fit.theta(std::distance(result.fit.labels.begin(), it));
    std::printf("batch %s: %.6g (truth %.6g)\n", name.c_str(), estimate, value);
    EXPECT_NEAR(estimate, value, (name == "a_i" ? 1e-3 : 0.15) * std::abs(value)) << name;
  }

  // Blocks 5-6 read no batch option: mountings estimated under another batch model give the
  // batch the same frames (reproduce-paper shares them between its cases (2) and (3)).
  PipelineOptions other = p;
  other.batch.fixed_terms = {"1", "a_i"};
  other.batch_square_highpass = !p.batch_square_highpass;
  const auto shared = inertia::procedure::identify_batch(inertia::procedure::run_mounting_stages(data, other, "paper"), data, p, "paper");
  ASSERT_EQ(shared.fit.labels, result.fit.labels);
  EXPECT_LE((shared.fit.theta - result.fit.theta).norm(), 1e-12 * result.fit.theta.norm());
  for (std::size_t c = 0; c < data.cases.size(); ++c)
    EXPECT_LE((shared.cases[c].m_es - result.cases[c].m_es).norm(), 1e-12) << data.cases[c].name;
}

}  // namespace

namespace {

// The shaker cube of config/sim-imu.toml takes its bias from the dividing head (IEEE 1293
// 12.3.5.7). The bias it was handed, with sd s, adds to its angles' variance what moving the bias
// by s moves them by (central difference; the fixed model's fit is linear in the output). The
// unit's y accelerometer, its fixed model's angles by algorithm 1, white noise: with an AR noise
// model each pass refits the whitener to a residual the moved bias leaves a constant in, which
// takes part of it out (the fixed point then moves the angles less than with the whitener held),
// and the bias's share is taken at the whitener held, as every other share of the sd. s is large
// enough to dominate the placements' share.
TEST(PaperMisalignment, AShakerMountingsAnglesCarryTheBiasItWasHandedAsMovingTheBiasMovesThem) {
  const inertia::config::BenchConfig bench =
      inertia::config::load_bench_config(std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-imu.toml");
  const inertia::sim::BenchSimulation sim = inertia::sim::simulate_bench(bench);
  const inertia::dataset::Dataset data = inertia::sim::sensor_dataset(bench, sim, 1);
  std::vector<std::size_t> cases;
  for (std::size_t c = 0; c < data.cases.size(); ++c)
    if (data.cases[c].mounting == "shaker-cube") cases.push_back(c);
  ASSERT_EQ(cases.size(), 3u);
  PipelineOptions p = fixed({"a_x", "a_y", "a_z"});
  p.whitening_max_order = 0;
  const double bias = -0.034, sd = 0.05;   // output unit
  const auto at = [&](double b, double s) { return inertia::procedure::estimate_mounting(data, cases, "shaker-cube", p, "imu", b, s); };
  const inertia::procedure::MountingResult without = at(bias, 0.0), with = at(bias, sd), up = at(bias + sd, 0.0), down = at(bias - sd, 0.0);
  for (int angle = 1; angle < 3; ++angle) {
    const double moved = 0.5 * (up.angles(angle) - down.angles(angle));
    const double added = with.angles_sd(angle) * with.angles_sd(angle) - without.angles_sd(angle) * without.angles_sd(angle);
    std::printf("angle %d: sd %.3g rad without the bias's, %.3g with; moving the bias by its sd moves it %.3g rad\n", angle,
                without.angles_sd(angle), with.angles_sd(angle), moved);
    EXPECT_GT(moved * moved, 0.1 * without.angles_sd(angle) * without.angles_sd(angle)) << "the bias matters here";
    EXPECT_NEAR(added, moved * moved, 1e-2 * moved * moved) << angle;
  }
}

}  // namespace
