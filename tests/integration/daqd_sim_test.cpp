// Done-when test of the daemon issue: the real inertia-daqd on a simulated bench (fast pacing),
// its LCM stream received by another thread, its log read after exit; sample counts, sequence
// continuity and values against the simulator's truth (same config, same seed, hal/sim run here).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "common/config/bench_config.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "daq/sim_bench.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

// The encoder by either of the simulator's wires (config::EncoderWire): GPIO edges into the gpiod
// decoder, or the counter's count in CAN frames into the socketcan decoder; the same counts.
class DaqdSim : public ::testing::TestWithParam<const char*> {};

TEST_P(DaqdSim, LogAndStreamMatchSimulatorTruth) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = (tmp.path / "bench.toml").string();
  {
    std::ifstream in(source_path("tests/integration/configs/daq-small.toml"));
    std::stringstream text;
    text << in.rdbuf();
    std::string bench = text.str();
    const std::string key = "[linear_encoder]\nresolution_m = 1e-6\n";
    const auto at = bench.find(key);
    ASSERT_NE(at, std::string::npos);
    bench.insert(at + key.size(), std::string("wire = \"") + GetParam() + "\"\n");
    std::ofstream(config) << bench;
  }
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  DaqdProcess daqd({"--config", config, "--fast", "--log", (tmp.path / "log").string(), "--lcm-url", url}, {},
                   tmp.path / "stderr.txt");
  ASSERT_EQ(daqd.wait(60), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  const std::string out = daqd.output();

  // Truth: the same plan through hal/sim.
  const config::BenchConfig bench = config::load_bench_config(config);
  const sim::BenchSimulation truth = sim::simulate_bench(bench);
  ASSERT_EQ(truth.cases.size(), 1u);
  const auto& sc = truth.cases[0];
  const auto n_samples = static_cast<std::int64_t>(sc.motion.size());

  const auto events = read_log_dir(tmp.path / "log");
  const auto accel = decode_all<sample_block_t>(events, "INERTIA_RAW_ACCEL");
  ASSERT_FALSE(accel.empty());
  EXPECT_EQ(sequence_gaps(accel), 0);
  std::int64_t total = 0;
  for (const auto& b : accel) total += b.num_samples;
  EXPECT_EQ(total, n_samples) << "every simulated sample is in the log, once";
  EXPECT_EQ(summary_value(out, "  accel:", "samples"), n_samples * static_cast<std::int64_t>(accel[0].num_channels));
  EXPECT_EQ(summary_value(out, "  accel:", "ring drops"), 0);
  EXPECT_EQ(summary_value(out, "  log:", "lost"), 0);

  // Values: within half a count of the simulated CAN ADC (kSimCanScale) of the truth.
  const int idx_ch = channel_index(accel[0], "sample_index");
  ASSERT_GE(idx_ch, 0);
  std::int64_t compared = 0, invalid = 0;
  double worst = 0.0;
  for (const auto& b : accel) {
    const double period_ns = b.sample_period_s * 1e9;
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const auto k = static_cast<Eigen::Index>(b.channel_seq[0] + s);
      ASSERT_EQ(b.values[static_cast<std::size_t>(idx_ch)][static_cast<std::size_t>(s)], static_cast<double>(k));
      for (std::int32_t c = 0; c < b.num_channels; ++c) {
        if (!sample_valid(b, c, s)) ++invalid;
        const std::string& name = b.channel_names[static_cast<std::size_t>(c)];
        double expected = NAN;
        for (std::size_t i = 0; i < bench.sensors.size(); ++i)
          if (bench.sensors[i].name == name) expected = sc.sensors[i].y[k];
        for (std::size_t i = 0; i < bench.monitors.size(); ++i)
          if (bench.monitors[i].name == name) expected = sc.references.monitors(k, static_cast<Eigen::Index>(i));
        if (name == "control") expected = sc.references.control[k];
        if (std::isnan(expected)) continue;
        const double err = std::abs(b.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)] - expected);
        worst = std::max(worst, err);
        ++compared;
      }
    }
    (void)period_ns;
  }
  EXPECT_EQ(invalid, 0);
  EXPECT_EQ(compared, n_samples * (static_cast<std::int64_t>(accel[0].num_channels) - 1));
  EXPECT_LE(worst, 0.5 * kSimCanScale * (1 + 1e-6)) << "quantisation of the simulated CAN ADC bounds the error";
  // Times: sample k of the run at sim_t0 + k / rate, whatever the pacing.
  for (std::size_t i = 1; i < accel.size(); ++i)
    EXPECT_NEAR(static_cast<double>(accel[i].t0_mono_ns - accel[0].t0_mono_ns),
                static_cast<double>(accel[i].channel_seq[0]) * accel[0].sample_period_s * 1e9, 1.0);

  // Encoder on the sample clock: count = floor(x / resolution) - floor(x0 / resolution), exactly.
  const auto enc = decode_all<sample_block_t>(events, "INERTIA_RAW_LINEAR_ENCODER");
  ASSERT_FALSE(enc.empty());
  EXPECT_EQ(sequence_gaps(enc), 0);
  const double res = bench.linear_encoder.resolution;
  const double c0 = std::floor(sc.motion.shaker_x_m[0] / res);
  std::int64_t enc_total = 0, enc_wrong = 0;
  for (const auto& b : enc) {
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const auto k = static_cast<Eigen::Index>(b.channel_seq[0] + s);
      const double expected = std::floor(sc.motion.shaker_x_m[k] / res) - c0;
      if (b.values[0][static_cast<std::size_t>(s)] != expected) ++enc_wrong;
      EXPECT_NEAR(b.values[1][static_cast<std::size_t>(s)], expected * res, 1e-12);
      ++enc_total;
    }
  }
  EXPECT_EQ(enc_total, n_samples);
  EXPECT_EQ(enc_wrong, 0);

  // Controller over Modbus: temperatures inside the simulated range (0.01 degC register steps).
  const auto ctrl = decode_all<sample_block_t>(events, "INERTIA_RAW_CONTROLLER");
  ASSERT_FALSE(ctrl.empty());
  EXPECT_EQ(sequence_gaps(ctrl), 0);
  const int t_ch = channel_index(ctrl[0], "temperature");
  ASSERT_GE(t_ch, 0);
  const double tmin = std::min(sc.references.temp_measured_c.minCoeff(), sc.motion.temp_c.minCoeff()) - 0.006;
  const double tmax = std::max(sc.references.temp_measured_c.maxCoeff(), sc.motion.temp_c.maxCoeff()) + 0.006;
  std::int64_t ctrl_invalid = 0, ctrl_rows = 0;
  for (const auto& b : ctrl)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      ++ctrl_rows;
      if (!sample_valid(b, t_ch, s)) {  // a request that failed under load: must be counted
        ++ctrl_invalid;
        continue;
      }
      const double v = b.values[static_cast<std::size_t>(t_ch)][static_cast<std::size_t>(s)];
      EXPECT_GE(v, tmin);
      EXPECT_LE(v, tmax);
    }

  // A fast run polls the controllers only a few times (3 rows seen in CI), and a poll that times out
  // under a loaded ctest -j2 is correctly marked invalid, so a ratio over so few rows says nothing
  // about the daemon: require valid rows to exist and invalid ones to be flagged (checked above).
  EXPECT_LT(ctrl_invalid, ctrl_rows);
  // Plan markers: case start/end and start/end of each of the 5 phases, with names.
  const auto marks = decode_all<plan_event_t>(events, "INERTIA_EVENT");
  std::size_t phase_starts = 0;
  for (const auto& m : marks)
    if (m.mark == plan_event_t::MARK_PHASE_START) {
      ++phase_starts;
      EXPECT_EQ(m.case_name, "shaker-ia");
    }
  EXPECT_EQ(phase_starts, bench.cases[0].phases.size());
  EXPECT_EQ(marks.size(), 2 + 2 * bench.cases[0].phases.size());

  // Health: at least the final status, no drops anywhere.
  const auto status = decode_all<daq_status_t>(events, "INERTIA_STATUS");
  ASSERT_FALSE(status.empty());
  for (const auto& d : status.back().devices) {
    if (d.device == "controller" && ctrl_invalid > 0) {
      EXPECT_GT(d.decode_errors, 0) << "invalid rows are failed requests, counted";
    }
    EXPECT_EQ(d.ring_drops, 0) << d.device;
    EXPECT_EQ(d.state, device_status_t::STATE_ACTIVE) << d.device;
  }

  // Live stream: every message received is byte-identical to the logged one (the log is what
  // went on the wire); loss on loopback is reported.
  const auto received = live.take();
  std::map<std::string, std::vector<const LogEvent*>> logged;
  for (const auto& e : events) logged[e.channel].push_back(&e);
  std::size_t raw_received = 0, raw_logged = 0, matched = 0;
  for (const auto& [ch, v] : logged)
    if (ch.rfind("INERTIA_RAW_", 0) == 0) raw_logged += v.size();
  for (const auto& r : received) {
    if (r.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
    ++raw_received;
    sample_block_t b;
    ASSERT_GE(b.decode(r.data.data(), 0, static_cast<int>(r.data.size())), 0);
    const auto& v = logged[r.channel];
    if (b.seq >= 0 && static_cast<std::size_t>(b.seq) < v.size() && v[static_cast<std::size_t>(b.seq)]->data == r.data)
      ++matched;
  }
  EXPECT_EQ(matched, raw_received);
  EXPECT_GT(raw_received, 0u);
  std::cout << "live LCM: received " << raw_received << " of " << raw_logged << " raw blocks (loss "
            << raw_logged - raw_received << "), worst value error " << worst << "\n";
  RecordProperty("lcm_raw_loss", static_cast<int>(raw_logged - raw_received));
}

INSTANTIATE_TEST_SUITE_P(EncoderWire, DaqdSim, ::testing::Values("gpio", "can"),
                         [](const ::testing::TestParamInfo<const char*>& info) { return std::string(info.param); });

}  // namespace
}  // namespace inertia::daq::testing
