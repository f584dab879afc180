// `inertia-analyze online` live: the real daemon plays a simulated shaker bench in real time on a
// private multicast port, the real analyzer subscribes, fuses and estimates, and a third process
// (this test) receives INERTIA_ESTIMATE_ACC1 and checks it against the simulator's truth.
#include <gtest/gtest.h>

#include <cmath>

#include "common/config/bench_config.hpp"
#include "daqd_harness.hpp"
#include "inertia/model_estimate_t.hpp"

namespace inertia::daq::testing {
namespace {

std::string analyze_binary() { return std::string(INERTIA_BINARY_DIR) + "/bin/inertia-analyze"; }

TEST(OnlineLive, EstimatesFromTheDaemonsStreamMatchTheSimulatorsTruth) {
  if (lcm_route_missing()) GTEST_SKIP() << kNoRouteMessage;
  TempDir tmp;
  const std::string config = source_path("tests/integration/configs/online-shaker.toml");
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());

  DaqdProcess online({"online", "--config", config, "--lcm-url", url, "--publish-hz", "5"}, {},
                     tmp.path / "online.txt", analyze_binary());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));   // subscribed before the daemon's first message
  DaqdProcess daqd({"--config", config, "--lcm-url", url}, {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(60), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));   // the last blocks reach the analyzer
  online.signal(SIGTERM);                                         // graceful: fuses the open case, publishes
  ASSERT_EQ(online.wait(30), 0) << online.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();

  std::vector<model_estimate_t> estimates;
  for (const auto& r : live.take()) {
    if (r.channel != "INERTIA_ESTIMATE_ACC1") continue;
    model_estimate_t m;
    ASSERT_GE(m.decode(r.data.data(), 0, static_cast<int>(r.data.size())), 0);
    estimates.push_back(std::move(m));
  }
  ASSERT_GE(estimates.size(), 10u) << "about 5 Hz over the ~6 s run\n" << online.output();
  const model_estimate_t& last = estimates.back();
  EXPECT_EQ(last.sensor, "acc1");
  EXPECT_EQ(last.output_unit, "mA");

  // Both cases fused and used, minus what the assembler excluded (it prints that on its summary).
  const config::BenchConfig bench = config::load_bench_config(config);
  double planned_s = 0.0;
  for (const auto& c : bench.cases)
    for (const auto& p : c.phases) planned_s += p.duration_s;
  const auto planned = static_cast<std::int64_t>(planned_s * bench.sample_rate_hz);
  EXPECT_GT(last.samples_used, planned * 9 / 10) << online.output();
  EXPECT_LE(last.samples_used, planned);
  EXPECT_TRUE(last.converged) << online.output();
  // Estimates grow monotonically in samples: the stream was consumed in order.
  for (std::size_t i = 1; i < estimates.size(); ++i) EXPECT_GE(estimates[i].samples_used, estimates[i - 1].samples_used);

  const auto coefficient = [&](const std::string& term, double* sd) -> double {
    for (std::int32_t j = 0; j < last.num_terms; ++j) {
      if (last.terms[static_cast<std::size_t>(j)] == term) {
        *sd = last.std_devs[static_cast<std::size_t>(j)];
        return last.values[static_cast<std::size_t>(j)];
      }
    }
    ADD_FAILURE() << "no term " << term;
    return NAN;
  };
  // Truth (online-shaker.toml, per g -> per m/s^2). The fused reference carries the monitors'
  // uncalibrated scale errors (largest 1.2e-3) and misalignments (<= 0.06 deg): a relative error
  // of the reference up to ~1.5e-3 on top of the estimator's own standard deviation.
  constexpr double g = 9.80665, reference_relative = 1.5e-3;
  double sd = 0.0;
  const double k_i = coefficient("a_i", &sd);
  EXPECT_NEAR(k_i, 0.86 / g, 4.0 * sd + reference_relative * 0.86 / g);
  const double k_ip = coefficient("a_i*a_p", &sd);
  EXPECT_NEAR(k_ip, 1e-3 / (g * g), 4.0 * sd + reference_relative * 1e-3 / (g * g) + 0.03 * 1e-3 / (g * g));
  const double bias = coefficient("1", &sd);
  // The bias is seen against 10 g of vibration: its sd is large; still, it must be the right size.
  EXPECT_NEAR(bias, 4e-3, 4.0 * sd + 0.05 * 4e-3);
  // Residual: at least the sensor's white noise (1e-4 g); at most that plus the fused reference's
  // noise (monitors 5e-4 g each, ~4e-4 g along any axis after the fit) and its uncalibrated linear
  // error (reference_relative of ~9 g RMS of vibration; it differs per orientation, so the global
  // linear terms cannot absorb it), all times K = 0.86 mA/g.
  const double floor_mA = 0.86 * 1e-4;
  const double ceiling_mA = 0.86 * std::sqrt(1e-4 * 1e-4 + 4e-4 * 4e-4 + std::pow(reference_relative * 9.0, 2));
  EXPECT_GT(std::sqrt(last.residual_variance), 0.9 * floor_mA);
  EXPECT_LT(std::sqrt(last.residual_variance), ceiling_mA);
}

TEST(OnlineLive, BadInputExitsTwoNamingIt) {
  TempDir tmp;
  DaqdProcess missing({"online", "--config", (tmp.path / "nope.toml").string()}, {}, tmp.path / "a.txt", analyze_binary());
  EXPECT_EQ(missing.wait(30), 2);
  EXPECT_NE(missing.output().find("nope.toml"), std::string::npos) << missing.output();
  DaqdProcess wrong_sensor({"online", "--config", source_path("tests/integration/configs/online-shaker.toml"),
                            "--model", "accX=" + source_path("tests/integration/configs/online-shaker.toml")},
                           {}, tmp.path / "b.txt", analyze_binary());
  EXPECT_EQ(wrong_sensor.wait(30), 2);
  EXPECT_NE(wrong_sensor.output().find("accX"), std::string::npos) << wrong_sensor.output();
}

}  // namespace
}  // namespace inertia::daq::testing
