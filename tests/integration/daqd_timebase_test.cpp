// The real-bench time base on every shipped simulated bench: with [bench.sim_timing]
// the simulator's CAN frames carry a counter, arrive with exponential receive jitter, run on a
// sample clock off the host's by clock_ppm and are lost at frame_loss, so the daemon takes the
// path real hardware takes (daq/clock_fit.hpp, numbered blocks). Each bench runs paced for 10
// seconds: the fitted drift is the simulated one, every sample of a lost frame is in the log as
// NaN (or, when its whole block was lost, as a jump of the block's numbers) and counted on
// INERTIA_STATUS, and no channel moves against another (no "misaligned").
// config/sim-paper.toml runs too: the same plan as sim-paper-daq at 10 kHz, its encoders' counts
// on CAN (wire = "can") as their MHz of edges would not keep real time on 2 cores through GPIO.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "common/config/link_capacity.hpp"
#include "daq/sim_bench.hpp"
#include "tests/integration/daqd_harness.hpp"
#include "tests/support/files.hpp"

namespace inertia::daq::testing {
namespace {

using inertia::testing::text_of;

constexpr double kClockPpm = 40.0;

class DaqdTimeBase : public ::testing::TestWithParam<const char*> {};

TEST_P(DaqdTimeBase, DriftFittedLostFramesAccountedNoChannelShifted) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const fs::path config = tmp.path / "bench.toml";
  {
    std::ifstream in(source_path(std::string("config/") + GetParam()));
    std::stringstream text;
    text << in.rdbuf();
    std::ofstream(config) << text.str() << "\n[bench.sim_timing]\njitter_us = 200.0\nclock_ppm = " << kClockPpm
                          << "\nframe_loss = 0.005\n";
  }
  DaqdProcess daqd({"--config", config.string(), "--duration", "10", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(90.0), 0) << daqd.output();
  const std::string out = daqd.output();
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"((\d+) CAN frame\(s\) lost on purpose)"))) << out;
  const long frames_lost = std::stol(m[1]);
  EXPECT_GT(frames_lost, 0) << "0.5 % of a few thousand frames";

  // An encoder on the simulated GPIO wire faster than a real GPIO line carries is said at the
  // start (the simulator's pipe carries it; config/link_capacity.hpp refuses it on a real bench).
  const config::BenchConfig bench = config::load_bench_config(config);
  const struct {
    const config::Encoder& encoder;
    bool table;
    const char* name;
  } encoders[] = {{bench.table_encoder, true, "table_encoder"}, {bench.linear_encoder, false, "linear_encoder"}};
  for (const auto& e : encoders) {
    if (!e.encoder.present || e.encoder.wire != config::EncoderWire::Gpio) continue;
    const double edges = config::quadrature_edges_per_line(config::motion_peak_speed(bench, e.table), e.encoder.resolution);
    const bool beyond = edges > config::gpio_line_edge_capacity(config::GpiodEncoder{});
    std::cout << "[ figures ] " << GetParam() << " " << e.name << ": " << edges << " edges/s per GPIO line\n";
    EXPECT_EQ(out.find(std::string("the ") + e.name + "'s fastest motion makes") != std::string::npos, beyond) << out;
  }

  const auto events = read_log_dir(tmp.path / "log");
  const auto statuses = decode_all<daq_status_t>(events, "INERTIA_STATUS");
  ASSERT_FALSE(statuses.empty());
  for (const auto& st : statuses)
    for (const auto& d : st.devices)
      EXPECT_EQ(std::find(d.faults.begin(), d.faults.end(), "misaligned"), d.faults.end()) << d.device;
  std::int64_t lost_on_status = 0;
  bool fitted = false;
  for (const auto& d : statuses.back().devices) {
    lost_on_status += d.lost_samples;
    if (d.device == "accel") {   // the simulated CAN device: its frames carry the counter
      fitted = true;
      std::cout << "[ figures ] " << GetParam() << " " << d.device << ": drift " << d.clock_drift_ppm << " ppm, residual "
                << d.clock_residual_us << " us, lost " << d.lost_samples << ", late " << d.late_samples << "\n";
      // The drift the daemon closed with, within 3 of the fit's own sd: the floor the fit follows
      // wanders with the host's load (sd 0.5 ppm at 1 kHz alone, 1 to 40 ppm at 100 Hz on a loaded host).
      std::smatch fit_match;
      ASSERT_TRUE(std::regex_search(out, fit_match, std::regex(R"(accel: clock drift ([-+]?[\d.]+) \+- ([\d.]+) ppm)"))) << out;
      const double drift = std::stod(fit_match[1]), drift_sd = std::stod(fit_match[2]);
      std::cout << "[ figures ] closing fit: drift " << drift << " +- " << drift_sd << " ppm\n";
      EXPECT_NEAR(drift, kClockPpm, 3.0 * drift_sd) << d.device;
      // No bound on the residual itself: it is how far the host's load lifted the floor (15 us
      // alone, 330 us beside a second paced daemon on 2 cores), and the sd above carries it.
    }
  }
  EXPECT_TRUE(fitted) << "no CAN device on its own time base";
  // Every sample that never arrived is a NaN in the log or inside a jump of its device's block
  // numbers, and nothing else is.
  std::int64_t nan_in_log = 0, in_jumps = 0;
  std::map<std::string, std::int64_t> next_seq;
  for (const auto& e : events) {
    if (e.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
    sample_block_t b;
    if (b.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0 || b.num_channels == 0) continue;
    for (const auto& ch : b.values)
      for (double v : ch) nan_in_log += std::isnan(v) ? 1 : 0;
    const auto it = next_seq.find(b.device);
    if (it != next_seq.end() && b.channel_seq[0] > it->second) in_jumps += (b.channel_seq[0] - it->second) * b.num_channels;
    next_seq[b.device] = b.channel_seq[0] + b.num_samples;
  }
  std::cout << "[ figures ] " << GetParam() << ": " << frames_lost << " frames lost, " << lost_on_status
            << " samples lost on INERTIA_STATUS, " << nan_in_log << " NaN samples and " << in_jumps << " in jumps in the log\n";
  EXPECT_EQ(nan_in_log + in_jumps, lost_on_status);
  // A frame lost before the first that arrived or after the last cannot be known lost.
  EXPECT_GE(lost_on_status, frames_lost - 2);
}

// A receive latency longer than the time between batches (3 ms mean against 1 ms batches) holds
// the frames back, not the simulated device: the simulator keeps its schedule, as a real device
// keeps its sample clock however late the host reads it, and the fitted drift is the simulated
// one. A simulator that waited out each batch's latency itself would fall seconds behind here.
TEST(DaqdSimulatedTiming, ALatencyLongerThanABatchDelaysTheFramesNotTheDevice) {
  INERTIA_REQUIRE_LCM_ROUTE();
  TempDir tmp;
  const fs::path config = tmp.path / "bench.toml";
  std::ofstream(config) << text_of(source_path("tests/integration/configs/daq-small.toml"))
                        << "\n[bench.sim_timing]\njitter_us = 3000.0\nclock_ppm = " << kClockPpm << "\n";
  DaqdProcess daqd({"--config", config.string(), "--duration", "4", "--lcm-url", private_lcm_url()}, {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(60.0), 0) << daqd.output();
  const std::string out = daqd.output();
  const std::optional<double> behind_ms = sim_schedule_lag_ms(out);
  std::smatch fit;
  ASSERT_TRUE(behind_ms) << out;
  ASSERT_TRUE(std::regex_search(out, fit, std::regex(R"(accel: clock drift ([-+]?[\d.]+) \+- ([\d.]+) ppm)"))) << out;
  std::cout << "[ figures ] behind its schedule " << *behind_ms << " ms; drift " << fit[1] << " +- " << fit[2] << " ppm\n";
  EXPECT_LE(*behind_ms * 1e-3, SimBench::kScheduleToleranceS) << out;
  EXPECT_EQ(out.find("could not run the simulated devices on time"), std::string::npos) << out;
  EXPECT_NEAR(std::stod(fit[1]), kClockPpm, 3.0 * std::stod(fit[2])) << out;
}

INSTANTIATE_TEST_SUITE_P(EveryShippedBench, DaqdTimeBase,
                         ::testing::Values("sim-paper.toml", "sim-paper-daq.toml", "sim-rotation-table.toml", "sim-shaker.toml",
                                           "sim-thermal.toml", "sim-tumble.toml", "sim-gyro-thermal.toml"),
                         [](const ::testing::TestParamInfo<const char*>& info) { return bench_test_name(info.param); });

}  // namespace
}  // namespace inertia::daq::testing
