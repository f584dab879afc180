// The simulate verb: dataset folders per the design's contract, truth.toml, the orientation chain
// end to end through a noiseless sensor, seeds (same seed, same bytes; other seed, other data).
#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>

#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/simulate.hpp"
#include "sim_test_util.hpp"

namespace {

using inertia::kStandardGravity;
using namespace inertia::sim;
using namespace inertia::sim::test;
namespace fs = std::filesystem;

const char* const kSmall = R"([bench]
name = "small"
sample_rate_hz = 1000.0
seed = SEED

[fixture.thermal]
initial_c = 30.0

[[sensor]]
name = "acc"
type = "accelerometer"
[sensor.truth]
k_i = 0.86
k_b = 4e-3

[[monitor]]
name = "m1"
axis = [0.70710678, 0.70710678, 0.0]
noise_sd_g = 1e-3

[control_accelerometer]
noise_sd_g = 1e-3

[linear_encoder]
resolution_m = 1e-7

[table_encoder]
resolution_rad = 1e-6

[[case]]
name = "table"
kind = "rotation_table"
m_ec = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
case_misalignment = { axis = [0, 1, 0], angle_deg = 2.0 }
start_attitude = { axis = [1, -1, 0], angle_deg = 35.0 }
[[case.phase]]
kind = "rotation"
axis = [1, 1, 1]
angle_deg = 360.0
duration_s = 1.0

[[case]]
name = "shaker-oa"
kind = "shaker"
orientation = "OA"
fixture_misalignment = { axis = [1, 2, 3], angle_deg = 0.5 }
case_misalignment = { axis = [1, 1, 1], angle_deg = 2.0 }
[[case.phase]]
kind = "sine"
frequency_hz = 20.0
amplitude_g = 5.0
duration_s = 0.5
[[case.phase]]
kind = "random"
f1_hz = 20.0
f2_hz = 400.0
grms = 3.0
duration_s = 0.5

[[case]]
name = "heat"
kind = "thermal"
orientation = "IA"
[[case.phase]]
kind = "thermal_step"
setpoint_c = 35.0
duration_s = 0.5
)";

std::string small_bench(int seed) {
  std::string s = kSmall;
  return s.replace(s.find("SEED"), 4, std::to_string(seed));
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Frame-rotation DCM by Rodrigues' formula, written out here rather than taken from frames.hpp.
Eigen::Matrix3d rodrigues_frame(Eigen::Vector3d k, double th) {
  k.normalize();
  Eigen::Matrix3d kx;
  kx << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
  const Eigen::Matrix3d active = Eigen::Matrix3d::Identity() * std::cos(th) + std::sin(th) * kx +
                                 (1 - std::cos(th)) * k * k.transpose();
  return active.transpose();
}

TEST(Simulate, WritesTheDatasetContractAndTruth) {
  const fs::path dir = temp_dir("out");
  const fs::path bench = write_file(temp_dir("cfg") / "bench.toml", small_bench(5));
  std::ostringstream summary;
  ASSERT_EQ(run_simulate(bench, dir, summary), inertia::kExitOk);
  EXPECT_NE(summary.str().find("case shaker-oa: kind shaker, 1000 samples"), std::string::npos) << summary.str();

  std::ostringstream warnings;
  const inertia::dataset::Dataset ds = inertia::dataset::read_dataset(dir, warnings);
  EXPECT_TRUE(warnings.str().empty()) << warnings.str();
  ASSERT_EQ(ds.cases.size(), 3u);
  EXPECT_EQ(ds.sensor, inertia::dataset::SensorKind::Accelerometer);
  const auto& shaker = ds.cases[1];
  EXPECT_EQ(shaker.kind, inertia::dataset::CaseKind::Shaker);
  EXPECT_EQ(shaker.size(), 1000);
  EXPECT_DOUBLE_EQ(shaker.sample_period_s, 1e-3);
  // m_ec is the nominal Fig. 2 slot, not the misaligned truth.
  EXPECT_LT((shaker.m_ec - inertia::config::slot_orientation(inertia::config::Orientation::OA,
                                                              inertia::deg_to_rad(25.0)))
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
  ASSERT_EQ(shaker.phase_names.size(), 2u);
  EXPECT_EQ(shaker.phase_names[0], "sine");
  EXPECT_EQ(shaker.phase_names[1], "random");
  ASSERT_TRUE(ds.cases[2].temp.has_value());
  EXPECT_GT(ds.cases[2].temp->maxCoeff(), 30.0);   // heating towards 35 degC
  EXPECT_EQ(ds.cases[2].phase_names[0], "thermal");
  EXPECT_TRUE(fs::exists(dir / "references" / "shaker-oa.csv"));

  const toml::table truth = toml::parse_file((dir / "truth.toml").string());
  EXPECT_EQ(truth["sensor"].value_or(std::string()), "accelerometer");
  EXPECT_NEAR(truth["terms"]["a_i"].value_or(0.0), 0.86 / kStandardGravity, 1e-15);
  EXPECT_NEAR(truth["terms"]["1"].value_or(0.0), 0.86 * 4e-3, 1e-15);
  // True M_E^C of the shaker case: R_C M_nom R_F with hand-built rotations.
  const Eigen::Matrix3d expected = rodrigues_frame({1, 1, 1}, inertia::deg_to_rad(2.0)) * shaker.m_ec *
                                   rodrigues_frame({1, 2, 3}, inertia::deg_to_rad(0.5));
  const toml::array& rows = *truth["case"][1]["m_ec_true"].as_array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(rows[static_cast<std::size_t>(r)].as_array()->get(static_cast<std::size_t>(c))->value_or(9.0),
                  expected(r, c), 1e-14);
    }
  }
}

TEST(Simulate, OrientationChainEndToEndThroughANoiselessSensor) {
  // Only scale and bias, no noise and no sensor misalignment: y = K_i (K_b + a_i / g0) with
  // a_i the first row of the true M_E^C applied to the reference specific force.
  std::string text = small_bench(9);
  text.replace(text.find("k_b = 4e-3"), 10,
               "k_b = 4e-3\nk_ip = 0.0\nk_io = 0.0\nk_po = 0.0\nk_ii = 0.0\nk_pp = 0.0\nk_oo = 0.0\n"
               "alpha_p_rad = 0.0\nalpha_o_rad = 0.0\nwhite_sd_g = 0.0\npink_sd_g = 0.0");
  const auto bench = bench_from(text);
  const BenchSimulation sim = simulate_bench(bench);
  const Eigen::Matrix3d m_table = rodrigues_frame({0, 1, 0}, inertia::deg_to_rad(2.0));
  const Eigen::Matrix3d m_shaker = rodrigues_frame({1, 1, 1}, inertia::deg_to_rad(2.0)) * bench.cases[1].m_ec *
                                   rodrigues_frame({1, 2, 3}, inertia::deg_to_rad(0.5));
  const Eigen::Matrix3d m_true[] = {m_table, m_shaker, bench.cases[2].m_ec};
  for (std::size_t c = 0; c < 3; ++c) {
    SCOPED_TRACE(c);
    const SensorCase& sc = sim.cases[c].sensors[0];
    double worst = 0.0;
    for (Eigen::Index k = 0; k < sc.y.size(); ++k) {
      const double a_i = m_true[c].row(0).dot(sc.reference(sim.cases[c].motion).row(k));
      worst = std::max(worst, std::abs(sc.y[k] - 0.86 * (4e-3 + a_i / kStandardGravity)));
    }
    EXPECT_LT(worst, 1e-12 * (1.0 + sc.reference(sim.cases[c].motion).cwiseAbs().maxCoeff()));
  }
}

TEST(Simulate, SameSeedSameBytesOtherSeedOtherData) {
  const fs::path cfg = temp_dir("cfg");
  const fs::path a = temp_dir("a"), b = temp_dir("b"), c = temp_dir("c");
  std::ostringstream sink;
  run_simulate(write_file(cfg / "s5.toml", small_bench(5)), a, sink);
  run_simulate(write_file(cfg / "s5.toml", small_bench(5)), b, sink);
  run_simulate(write_file(cfg / "s6.toml", small_bench(6)), c, sink);
  for (const char* f : {"table.csv", "shaker-oa.csv", "heat.csv", "references/shaker-oa.csv", "truth.toml",
                        "dataset.toml"}) {
    SCOPED_TRACE(f);
    const std::string x = slurp(a / f);
    ASSERT_GT(x.size(), 100u);
    EXPECT_EQ(x, slurp(b / f));
  }
  // Another bench seed: other random vibration, reference noise and sensor noise.
  for (const char* f : {"table.csv", "shaker-oa.csv", "references/shaker-oa.csv"}) {
    EXPECT_NE(slurp(a / f), slurp(c / f)) << f;
  }
}

TEST(Simulate, SeveralSensorsGetOneFolderEach) {
  std::string text = small_bench(5);
  const std::string second = "[[sensor]]\nname = \"acc2\"\ntype = \"accelerometer\"\nseed = 77\n\n[[monitor]]";
  text.replace(text.find("[[monitor]]"), 11, second);
  const fs::path out = temp_dir("out");
  std::ostringstream sink;
  run_simulate(write_file(temp_dir("cfg") / "b.toml", text), out, sink);
  EXPECT_TRUE(fs::exists(out / "acc" / "dataset.toml"));
  EXPECT_TRUE(fs::exists(out / "acc2" / "truth.toml"));
  EXPECT_TRUE(fs::exists(out / "references" / "table.csv"));
  EXPECT_NE(slurp(out / "acc" / "table.csv"), slurp(out / "acc2" / "table.csv"));
}

TEST(Simulate, UnknownTruthParameterIsPositioned) {
  std::string text = small_bench(5);
  text.replace(text.find("k_b = 4e-3"), 10, "k_b = 4e-3\nk_bias = 1.0");
  const auto bench = bench_from(text);
  try {
    (void)sensor_params(bench);
    FAIL();
  } catch (const inertia::InputError& e) {
    EXPECT_EQ(e.where().line, 15u);
    EXPECT_EQ(e.where().column, 10u);
    EXPECT_NE(std::string(e.what()).find("unknown accelerometer truth parameter 'k_bias'"), std::string::npos);
  }
}

TEST(Simulate, ShippedSimBenchesHaveValidTruthAndTemplateIsRefused) {
  const fs::path dir = fs::path(INERTIA_SOURCE_DIR) / "config";
  for (const char* n : {"sim-paper.toml", "sim-shaker.toml", "sim-rotation-table.toml", "sim-thermal.toml"}) {
    SCOPED_TRACE(n);
    const auto bench = inertia::config::load_bench_config(dir / n);
    EXPECT_EQ(sensor_params(bench).size(), bench.sensors.size());
  }
  std::ostringstream sink;
  EXPECT_THROW(run_simulate(dir / "bench-template.toml", temp_dir("out"), sink), inertia::InputError);
}

}  // namespace
