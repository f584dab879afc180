// truth.toml is a model file (docs/design.md "Model file"): the analyzer's reader accepts it, every
// term name is canonical in the analyzer's grammar, and the coefficients are equation 12's. And
// `simulate --model` puts a model file's own noise on the output it simulates.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "analyzer/commands/simulate_model.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/dataset/dataset.hpp"
#include "common/units.hpp"
#include "hal/sim/simulate.hpp"
#include "sim_test_util.hpp"

namespace {

using namespace inertia;

TEST(TruthFile, ReadsAsAModelFileWithCanonicalTerms) {
  const auto cfg = sim::test::temp_dir("cfg");
  const auto out = sim::test::temp_dir("out");
  const auto bench = sim::test::write_file(cfg / "b.toml", R"([bench]
name = "t"
sample_rate_hz = 1000.0
[[sensor]]
name = "acc"
type = "accelerometer"
[sensor.truth]
k_s = 1e-5
k_a = 2e-5
k_oq = 3e-5
scale_tc_per_degc = 1e-4
bias_tc_g_per_degc = 2e-5
[[sensor]]
name = "fog"
type = "gyroscope"
output_unit = "rad/s"
[sensor.truth]
s0 = 2.0
c_i = 1.001
c_f1 = 1e-4
eps_t_ppm_per_degc = 30.0
c_t1 = 1e-6
c_t2 = -5e-7
drift_rad_s = 1e-6
[[case]]
name = "s"
kind = "static"
orientation = "IA"
[[case.phase]]
kind = "dwell"
duration_s = 0.1
)");
  std::ostringstream sink;
  sim::run_simulate(bench, out, sink);

  const model::ModelFile acc = model::read_model(out / "acc" / "truth.toml");
  EXPECT_EQ(acc.sensor, dataset::SensorKind::Accelerometer);
  const double ki = 0.86, g = kStandardGravity;   // AccelerometerParams default K_i (table 1)
  for (const model::ModelTerm& t : acc.terms) {
    EXPECT_EQ(ident::parse_term(t.term.to_string()).to_string(), t.term.to_string());
  }
  EXPECT_NEAR(*acc.coefficient(ident::parse_term("a_i")), ki / g, 1e-15);
  EXPECT_NEAR(*acc.coefficient(ident::parse_term("sign(a_i)")), ki * 1e-5, 1e-18);
  EXPECT_NEAR(*acc.coefficient(ident::parse_term("abs(a_i)")), ki * 2e-5 / g, 1e-18);
  EXPECT_NEAR(*acc.coefficient(ident::parse_term("a_i*abs(a_i)")), ki * 3e-5 / (g * g), 1e-18);
  EXPECT_NEAR(*acc.coefficient(ident::parse_term("a_i*T")), ki * 1e-4 / g, 1e-18);
  ASSERT_TRUE(acc.white_sd.has_value());
  EXPECT_NEAR(*acc.white_sd, ki * 1e-4, 1e-18);
  EXPECT_TRUE(frames::is_rotation(acc.m_cs, 1e-12));

  const model::ModelFile fog = model::read_model(out / "fog" / "truth.toml");
  EXPECT_EQ(fog.sensor, dataset::SensorKind::Gyroscope);
  // Equation 5 in the model file's convention: Omega (1 + 1e-6 eps_T T + c_f1 w_i) =
  //   (c_i w_i + c_T1 T + c_T2 T[k-1] + D_F)/S0, so y*T and y*w_i carry +1e-6 eps_T and +c_f1.
  EXPECT_NEAR(*fog.coefficient(ident::parse_term("w_i")), 1.001 / 2.0, 1e-15);
  EXPECT_NEAR(*fog.coefficient(ident::parse_term("T[k-1]")), -5e-7 / 2.0, 1e-20);
  EXPECT_NEAR(*fog.coefficient(ident::parse_term("y*T")), 30e-6, 1e-20);
  EXPECT_NEAR(*fog.coefficient(ident::parse_term("y*w_i")), 1e-4, 1e-20);
  EXPECT_NEAR(*fog.coefficient(ident::parse_term("1")), 1e-6 / 2.0, 1e-20);
}


TEST(SimulateModel, TheOutputsWhiteNoiseIsTheModelsNNotItsInnovationSd) {
  // A model characterized on a tumble states white_sd, the batch innovation's sd, which also holds
  // what differs between the poses; its [noise] N is the noise at rest. The output simulated from
  // it scatters about the model by N / sqrt(dt) per sample: here 5e-5 g s^1/2 at 1 kHz is 1.58e-3 g,
  // and the white_sd of 4e-3 g is not used. Over 3 x 2000 samples the sd estimate scatters by
  // 1 / sqrt(2 n) = 0.9 %: 4 % is more than 4 of those.
  const auto cfg = sim::test::temp_dir("cfg");
  const auto out = sim::test::temp_dir("out");
  const auto bench = sim::test::write_file(cfg / "b.toml", R"([bench]
name = "t"
sample_rate_hz = 1000.0
[[sensor]]
name = "acc"
type = "accelerometer"
[[case]]
name = "up"
kind = "static"
m_ec = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
[[case.phase]]
kind = "dwell"
duration_s = 2.0
[[case]]
name = "down"
kind = "static"
m_ec = [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
[[case.phase]]
kind = "dwell"
duration_s = 2.0
[[case]]
name = "side"
kind = "static"
m_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[[case.phase]]
kind = "dwell"
duration_s = 2.0
)");
  const auto model_file = sim::test::write_file(cfg / "model.toml", R"(sensor = "accelerometer"
m_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[terms]
"1" = 0.01
"a_i" = 0.1
[noise]
white_sd = 4.0e-3
N = 5.0e-5
)");
  commands::SimulateOptions options;
  options.bench = bench;
  options.out = out;
  options.models[""] = model_file;
  std::ostringstream summary;
  ASSERT_EQ(commands::run_simulate(options, summary), 0);
  EXPECT_NE(summary.str().find("from its [noise] N"), std::string::npos) << summary.str();
  const dataset::Dataset data = dataset::read_dataset(out);
  double squares = 0.0;
  Eigen::Index samples = 0;
  for (const dataset::CaseData& c : data.cases) {
    // The output's mean per case is the model at the case's pose; the scatter about it is the noise.
    const Eigen::VectorXd centered = c.y.array() - c.y.mean();
    squares += centered.squaredNorm();
    samples += c.y.size() - 1;
  }
  const double sd = std::sqrt(squares / static_cast<double>(samples));
  EXPECT_NEAR(sd / (5.0e-5 / std::sqrt(1e-3)), 1.0, 0.04) << sd;
}
}  // namespace
