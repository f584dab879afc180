// Real hardware's failure modes, injected by the simulator into the real daemon's wires
// (--fault kinds and [bench.sim_timing] keys; daq/README.md "Failure modes of real hardware"):
// each is survived, counted on INERTIA_STATUS, and the log holds exactly the simulator's samples.
// The CAN bus runs on the real timing path ([bench.sim_timing], paced): its frames carry a
// counter, so the log's sample_index channel is the counter and the sample's true number follows
// from it; the values are compared with the same plan run through hal/sim here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <optional>
#include <regex>
#include <sstream>

#include "common/config/bench_config.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "daq/clock_fit.hpp"
#include "daq/sim_bench.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "tests/integration/executive_bench.hpp"

namespace inertia::daq::testing {
namespace {

constexpr double kRateHz = 10000.0;   // daq-small's sample rate
constexpr double kClockPpm = 40.0;

struct DaqdRun {
  std::string out;
  std::vector<sample_block_t> accel;
  daq_status_t last_status;
  config::BenchConfig bench;
};

// daq-small with [bench.sim_timing] (`timing` adds keys), paced for `duration` s with `faults`.
DaqdRun run_daqd(const TempDir& tmp, const std::string& timing, double duration_s, const std::vector<std::string>& faults) {
  DaqdRun r;
  const fs::path config = tmp.path / "bench.toml";
  {
    std::ifstream in(source_path("tests/integration/configs/daq-small.toml"));
    std::stringstream text;
    text << in.rdbuf();
    std::ofstream(config) << text.str() << "\n[bench.sim_timing]\njitter_us = 200.0\nclock_ppm = " << kClockPpm << "\n"
                          << timing;
  }
  std::vector<std::string> args{"--config", config.string(), "--duration", std::to_string(duration_s), "--log",
                                (tmp.path / "log").string(), "--lcm-url", private_lcm_url()};
  for (const std::string& f : faults) {
    args.emplace_back("--fault");
    args.push_back(f);
  }
  DaqdProcess daqd(args, {}, tmp.path / "daqd.txt");
  const int rc = daqd.wait(60.0 + 3.0 * duration_s);
  r.out = daqd.output();
  EXPECT_EQ(rc, 0) << r.out;
  const auto events = read_log_dir(tmp.path / "log");
  r.accel = decode_all<sample_block_t>(events, "INERTIA_RAW_ACCEL");
  const auto statuses = decode_all<daq_status_t>(events, "INERTIA_STATUS");
  EXPECT_FALSE(statuses.empty());
  if (!statuses.empty()) r.last_status = statuses.back();
  r.bench = config::load_bench_config(config);
  return r;
}

const device_status_t* device(const daq_status_t& st, const std::string& name) {
  for (const auto& d : st.devices)
    if (d.device == name) return &d;
  return nullptr;
}

/// The simulator's value of channel `name` at sample `n` of the run (the plan repeats), or NaN
/// for a channel that is not a simulated reading (sample_index).
class Truth {
 public:
  explicit Truth(const config::BenchConfig& bench) : bench_(bench), sim_(sim::simulate_bench(bench)) {}
  [[nodiscard]] double value(const std::string& name, std::int64_t n) const {
    const auto& sc = sim_.cases.at(0);
    const auto k = static_cast<Eigen::Index>(n % static_cast<std::int64_t>(sc.motion.size()));
    for (std::size_t i = 0; i < bench_.sensors.size(); ++i)
      if (bench_.sensors[i].name == name) return sc.sensors[i].y[k];
    for (std::size_t i = 0; i < bench_.monitors.size(); ++i)
      if (bench_.monitors[i].name == name) return sc.references.monitors(k, static_cast<Eigen::Index>(i));
    if (name == "control") return sc.references.control[k];
    return std::nan("");
  }

 private:
  const config::BenchConfig& bench_;
  sim::BenchSimulation sim_;
};

/// Every valid sample of every channel against the simulator's value at its true number;
/// `number(block, s)` gives that number. Returns the samples compared; counts the mismatches.
template <class Number>
std::int64_t compare_with_truth(const DaqdRun& r, const Truth& truth, Number number, std::int64_t* wrong) {
  std::int64_t compared = 0;
  *wrong = 0;
  for (const auto& b : r.accel)
    for (std::int32_t s = 0; s < b.num_samples; ++s)
      for (std::int32_t c = 0; c < b.num_channels; ++c) {
        if (!sample_valid(b, c, s)) continue;
        const double expected = truth.value(b.channel_names[static_cast<std::size_t>(c)], number(b, s));
        if (std::isnan(expected)) continue;
        ++compared;
        // Within half a count of the simulated ADC.
        if (std::abs(b.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)] - expected) > 0.5 * kSimCanScale * (1 + 1e-6))
          ++*wrong;
      }
  return compared;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

TEST(DaqdHardwareFaults, ASixteenBitCounterResetStartsANewClockSegmentAndNoSampleMovesOrOverlaps) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // The adapter reboots at 4 s (its 16-bit counter at 40000, above 32768: by value alone a
  // forward jump of 2.5 s) and counts from 0 again 0.3 s later.
  TempDir tmp;
  constexpr double kResetAt = 4.0, kDown = 0.3;
  const DaqdRun r = run_daqd(tmp, "counter_bits = 16\n", 10.0, {"can-reset@4+0.3"});
  ASSERT_FALSE(r.accel.empty());
  const auto* st = device(r.last_status, "accel");
  ASSERT_NE(st, nullptr);
  EXPECT_EQ(st->counter_resets, 1);
  EXPECT_EQ(std::find(st->faults.begin(), st->faults.end(), "misaligned"), st->faults.end());
  EXPECT_NE(r.out.find("clock segments 2"), std::string::npos) << r.out;

  // Blocks follow one another: numbers increase, and no block starts before the previous ended
  // (the analyzer refuses overlapping blocks).
  const int idx = channel_index(r.accel.front(), "sample_index");
  ASSERT_GE(idx, 0);
  std::int64_t overlaps = 0;
  for (std::size_t i = 1; i < r.accel.size(); ++i) {
    const auto& a = r.accel[i - 1];
    const auto& b = r.accel[i];
    ASSERT_GE(b.channel_seq[0], a.channel_seq[0] + a.num_samples);
    const double end = static_cast<double>(a.t0_mono_ns) + a.num_samples * a.sample_period_s * 1e9;
    if (static_cast<double>(b.t0_mono_ns) < end - 0.5 * b.sample_period_s * 1e9) ++overlaps;
  }
  EXPECT_EQ(overlaps, 0);

  // The true number of each sample: its counter before the reset (4 s at 10 kHz: no roll-over
  // yet), its counter plus the restart's sample after it (6 s: none either).
  const auto back = static_cast<std::int64_t>(std::llround((kResetAt + kDown) * kRateHz));
  std::int64_t restart_seq = -1;
  double previous_counter = -1.0;
  for (const auto& b : r.accel)
    for (std::int32_t s = 0; s < b.num_samples && restart_seq < 0; ++s) {
      const double c = b.values[static_cast<std::size_t>(idx)][static_cast<std::size_t>(s)];
      if (!sample_valid(b, idx, s)) continue;
      if (c < previous_counter) restart_seq = b.channel_seq[0] + s;
      previous_counter = c;
    }
  ASSERT_GT(restart_seq, 0) << "the counter restarted in the log";
  auto number = [&](const sample_block_t& b, std::int32_t s) {
    const auto counter = static_cast<std::int64_t>(b.values[static_cast<std::size_t>(idx)][static_cast<std::size_t>(s)]);
    return b.channel_seq[0] + s >= restart_seq ? counter + back : counter;
  };
  const Truth truth(r.bench);
  std::int64_t wrong = 0;
  const std::int64_t compared = compare_with_truth(r, truth, number, &wrong);
  EXPECT_EQ(wrong, 0) << "of " << compared << ": every sample is the simulator's of its number";
  EXPECT_GT(compared, static_cast<std::int64_t>(9.0 * kRateHz) * 7);

  // The fit the daemon closed with is the new segment's, reopened at the restart: its drift is
  // the bench clock's, within 3 of its own sd (a fit tilted by the restart would carry the
  // restart's offset over its span: hundreds of us over seconds, tens of ppm).
  std::smatch fit;
  ASSERT_TRUE(std::regex_search(r.out, fit, std::regex(R"(accel: clock drift ([-+]?[\d.]+) \+- ([\d.]+) ppm)"))) << r.out;
  const double drift = std::stod(fit[1]), drift_sd = std::stod(fit[2]);
  std::cout << "[ figures ] the new segment's fit: drift " << drift << " +- " << drift_sd << " ppm (bench clock " << kClockPpm << ")\n";
  EXPECT_NEAR(drift, kClockPpm, 3.0 * drift_sd);

  // Times against the simulator's clock, for the record: sample n at T0 + n periods of the
  // bench's clock plus the receive floor, T0 + floor from the old segment's last 2 s. Each
  // segment's fit follows the floor its own frames saw, which on a shared host moves by tens of
  // us with the load (the simulator's wake-ups are the receive latency): so the 20 us target is
  // asserted where the latency is known (tests/unit/daq/publisher_test.cpp), and here the
  // figures are printed per span after the start and after the restart.
  const double period_ns = 1e9 / kRateHz * (1.0 + kClockPpm * 1e-6);
  std::vector<double> origin;
  for (const auto& b : r.accel)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      if (b.channel_seq[0] + s >= restart_seq) continue;
      const std::int64_t n = number(b, s);
      if (n < 2 * static_cast<std::int64_t>(kRateHz)) continue;
      origin.push_back(static_cast<double>(b.t0_mono_ns) + s * b.sample_period_s * 1e9 - static_cast<double>(n) * period_ns);
    }
  const double t0 = percentile(origin, 0.5);
  constexpr int kSpans = 4;
  const double spans[kSpans][2] = {{0.0, 0.5}, {0.5, 2.0}, {2.0, 4.0}, {4.0, 6.0}};
  std::vector<double> after_start[kSpans], after_restart[kSpans];   // signed errors, us
  for (const auto& b : r.accel)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const std::int64_t n = number(b, s);
      const double error_us =
          (static_cast<double>(b.t0_mono_ns) + s * b.sample_period_s * 1e9 - t0 - static_cast<double>(n) * period_ns) * 1e-3;
      const bool restarted = b.channel_seq[0] + s >= restart_seq;
      const double since_s = static_cast<double>(restarted ? n - back : n) / kRateHz;
      for (int k = 0; k < kSpans; ++k)
        if (since_s >= spans[k][0] && since_s < spans[k][1]) (restarted ? after_restart : after_start)[k].push_back(error_us);
    }
  // Per span: the median error (the offset of its fit's floor) and the p99 scatter about it.
  auto scatter = [](const std::vector<double>& e) {
    const double m = percentile(e, 0.5);
    std::vector<double> d;
    for (double x : e) d.push_back(std::abs(x - m));
    return std::make_pair(m, percentile(d, 0.99));
  };
  for (int k = 0; k < kSpans; ++k) {
    const auto [m0, s0] = scatter(after_start[k]);
    const auto [m1, s1] = scatter(after_restart[k]);
    std::cout << "[ figures ] " << spans[k][0] << " to " << spans[k][1] << " s after the start: median " << m0 << " us, p99 about it "
              << s0 << " us; after the restart: median " << m1 << " us, p99 about it " << s1 << " us\n";
  }
}

TEST(DaqdHardwareFaults, AnEightSecondSilenceOnASixteenBitCounterKeepsItsLength) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // The bus is off from 1 s to 9 s: 80000 samples at 10 kHz, one roll-over of the 16-bit counter
  // and 14464 more. By value alone the numbers after it would come 65536 short.
  TempDir tmp;
  const DaqdRun r = run_daqd(tmp, "counter_bits = 16\n", 10.0, {"bus-off@1+8"});
  ASSERT_FALSE(r.accel.empty());
  const auto* st = device(r.last_status, "accel");
  ASSERT_NE(st, nullptr);
  EXPECT_EQ(st->counter_resets, 0);
  // The blocks' numbers jump by the silence, and every sample is the simulator's of its number.
  std::int64_t jump = 0;
  for (std::size_t i = 1; i < r.accel.size(); ++i)
    jump = std::max(jump, r.accel[i].channel_seq[0] - (r.accel[i - 1].channel_seq[0] + r.accel[i - 1].num_samples));
  EXPECT_GE(jump, static_cast<std::int64_t>(8.0 * kRateHz) - 200) << "the silence, less the blocks it began and ended in";
  const Truth truth(r.bench);
  std::int64_t wrong = 0;
  const std::int64_t compared =
      compare_with_truth(r, truth, [](const sample_block_t& b, std::int32_t s) { return b.channel_seq[0] + s; }, &wrong);
  EXPECT_EQ(wrong, 0) << "of " << compared;
  EXPECT_GT(compared, static_cast<std::int64_t>(1.8 * kRateHz) * 7) << "before and after the silence";
}

TEST(DaqdHardwareFaults, ShortDuplicateAndSwappedFramesAreRefusedCountedAndNoSampleDiffers) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // One of each in 60000 frames: the frame of the sample due at 2 s cut short before its counter,
  // the one at 3 s sent twice, the one at 4 s sent after the next one (overtaken).
  TempDir tmp;
  const DaqdRun r = run_daqd(tmp, "", 6.0, {"short-frame@2", "duplicate-frame@3", "swapped-frames@4"});
  ASSERT_FALSE(r.accel.empty());
  const auto* st = device(r.last_status, "accel");
  ASSERT_NE(st, nullptr);
  const std::int64_t nch = r.accel.front().num_channels;
  std::cout << "[ figures ] short " << st->short_frames << ", duplicate " << st->duplicate_frames << ", out of order "
            << st->out_of_order_frames << ", lost samples " << st->lost_samples << ", resets " << st->counter_resets << "\n";
  EXPECT_EQ(st->short_frames, 1);
  EXPECT_EQ(st->duplicate_frames, 1);
  EXPECT_EQ(st->out_of_order_frames, 1);
  EXPECT_EQ(st->counter_resets, 0);
  // The short frame's sample and the overtaken one never arrived: missing, every channel.
  EXPECT_EQ(st->lost_samples, 2 * nch);
  EXPECT_EQ(sequence_gaps(r.accel), 0);
  const int idx = channel_index(r.accel.front(), "sample_index");
  ASSERT_GE(idx, 0);
  std::vector<std::int64_t> missing;
  for (const auto& b : r.accel)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      if (!std::isnan(b.values[static_cast<std::size_t>(idx)][static_cast<std::size_t>(s)])) {
        // The sample's number is its counter (a 32-bit counter from 0: no roll-over).
        ASSERT_EQ(b.values[static_cast<std::size_t>(idx)][static_cast<std::size_t>(s)], static_cast<double>(b.channel_seq[0] + s));
        continue;
      }
      missing.push_back(b.channel_seq[0] + s);
      for (std::int32_t c = 0; c < b.num_channels; ++c) EXPECT_FALSE(sample_valid(b, c, s));
    }
  EXPECT_EQ(missing, (std::vector<std::int64_t>{static_cast<std::int64_t>(2 * kRateHz), static_cast<std::int64_t>(4 * kRateHz)}));
  const Truth truth(r.bench);
  std::int64_t wrong = 0;
  const std::int64_t compared =
      compare_with_truth(r, truth, [](const sample_block_t& b, std::int32_t s) { return b.channel_seq[0] + s; }, &wrong);
  EXPECT_EQ(wrong, 0) << "of " << compared;
  EXPECT_GT(compared, static_cast<std::int64_t>(5.0 * kRateHz) * 7);
}

TEST(DaqdHardwareFaults, AGpioEncoderLineOverflowIsCountedResynchronizedAndOnlyItsSamplesAreInvalid) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // 17 edges of the linear encoder's line A lost from 0.3 s on (during the sine phase): a full
  // kernel FIFO of 16 and the edge after it. As fast as possible: the simulator's exact clock.
  TempDir tmp;
  const std::string config = source_path("tests/integration/configs/daq-small.toml");
  DaqdProcess daqd({"--config", config, "--fast", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url(), "--fault",
                    "gpio-overflow@0.3+17"},
                   {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(60), 0) << daqd.output();
  const auto events = read_log_dir(tmp.path / "log");
  const auto statuses = decode_all<daq_status_t>(events, "INERTIA_STATUS");
  ASSERT_FALSE(statuses.empty());
  const auto* st = device(statuses.back(), "linear_encoder");
  ASSERT_NE(st, nullptr);
  EXPECT_EQ(st->encoder_overflows, 1);
  bool raised = false;
  for (const auto& s : statuses) {
    const auto* d = device(s, "linear_encoder");
    raised = raised || std::find(d->faults.begin(), d->faults.end(), "encoder-overflow") != d->faults.end();
  }
  EXPECT_TRUE(raised) << "encoder-overflow on INERTIA_STATUS";

  // Truth: count = floor(x / resolution) - floor(x0 / resolution) at every sample tick.
  const config::BenchConfig bench = config::load_bench_config(config);
  const sim::BenchSimulation truth = sim::simulate_bench(bench);
  const auto& x = truth.cases.at(0).motion.shaker_x_m;
  const double res = bench.linear_encoder.resolution;
  const double c0 = std::floor(x[0] / res);
  const auto enc = decode_all<sample_block_t>(events, "INERTIA_RAW_LINEAR_ENCODER");
  ASSERT_FALSE(enc.empty());
  EXPECT_EQ(sequence_gaps(enc), 0);
  const auto lost_from = static_cast<std::int64_t>(0.3 * kRateHz);
  std::int64_t invalid = 0, first_invalid = -1, last_invalid = -1, wrong_before = 0;
  for (const auto& b : enc)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const std::int64_t k = b.channel_seq[0] + s;
      const double expected = std::floor(x[static_cast<Eigen::Index>(k)] / res) - c0;
      if (!sample_valid(b, 0, s)) {
        ++invalid;
        if (first_invalid < 0) first_invalid = k;
        last_invalid = k;
        EXPECT_FALSE(sample_valid(b, 1, s)) << "count and position together";
      } else if (k < lost_from && b.values[0][static_cast<std::size_t>(s)] != expected) {
        ++wrong_before;
      }
    }
  EXPECT_EQ(wrong_before, 0) << "every sample before the loss is the encoder's";
  ASSERT_GT(invalid, 0);
  EXPECT_GE(first_invalid, lost_from);
  // Invalid from the edge that showed the loss to the line levels the device read next, and
  // nowhere else. The device reads the levels as they are when it asks (a chip's lines now), so
  // the run lasts as long as the reader lags the wire: one simulator batch (10 ms of samples in a
  // fast run) when it keeps up, more on a loaded machine. What does not depend on the load: the
  // simulator writes the levels at the end of each batch only, so the run ends on a batch's last
  // sample; and a reader 100 ms behind would be a stalled one.
  const auto batch = static_cast<std::int64_t>(kRateHz / 100.0);
  EXPECT_EQ(last_invalid - first_invalid + 1, invalid) << "one run of invalid samples";
  EXPECT_EQ((last_invalid + 1) % batch, 0) << "the run ends where the levels were read: " << last_invalid;
  EXPECT_LE(invalid, 10 * batch);
  // After it the count follows the encoder, off by the steps that were lost: one constant.
  std::int64_t offset_changes = 0;
  std::optional<double> offset;
  for (const auto& b : enc)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const std::int64_t k = b.channel_seq[0] + s;
      if (k <= last_invalid) continue;
      const double d = b.values[0][static_cast<std::size_t>(s)] - (std::floor(x[static_cast<Eigen::Index>(k)] / res) - c0);
      if (offset && d != *offset) ++offset_changes;
      offset = d;
    }
  ASSERT_TRUE(offset.has_value());
  std::cout << "[ figures ] 17 edges of line A lost at 0.3 s: " << invalid << " samples invalid, count off by " << *offset
            << " after\n";
  EXPECT_EQ(offset_changes, 0);
}

}  // namespace
}  // namespace inertia::daq::testing

namespace inertia::daq::testing {
namespace {

TEST(DaqdHardwareFaults, AControllersRowsAfterItWentSilentKeepTheirOwnTimes) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // The table turns at 1 rad/s: its position, polled every 20 ms, is a clock. A second of
  // silence (every request times out, polls overrun) must leave the rows after it at their own
  // times, not early by the polls that did not happen.
  BenchControllerState turning;
  turning.table_rate_rad_s = 1.0;
  turning.table_rate_setpoint_rad_s = 1.0;
  std::string why;
  auto server = BenchControllerServer::start(0, &why, turning);
  ASSERT_NE(server, nullptr) << why;
  TempDir tmp;
  const fs::path bench = tmp.path / "bench.toml";
  std::ofstream(bench) << bench_head("operator") + controllers(server->port(), "false") + kTableCase;
  DaqdProcess daqd({"--config", bench.string(), "--duration", "4", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {}, tmp.path / "daqd.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  server->set_silent(true);
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  server->set_silent(false);
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  const auto rows = decode_all<sample_block_t>(read_log_dir(tmp.path / "log"), "INERTIA_RAW_TABLE");
  ASSERT_FALSE(rows.empty());
  const int position = channel_index(rows[0], "position");
  ASSERT_GE(position, 0);
  std::vector<std::pair<double, double>> points;   // (time s, position rad), valid rows in order
  for (const auto& b : rows)
    for (std::int32_t s = 0; s < b.num_samples; ++s)
      if (sample_valid(b, position, s))
        points.emplace_back(static_cast<double>(b.t0_mono_ns) * 1e-9 + s * b.sample_period_s,
                            b.values[static_cast<std::size_t>(position)][static_cast<std::size_t>(s)]);
  ASSERT_GT(points.size(), 100u);
  // The silence: the largest gap between valid rows.
  std::size_t gap = 1;
  for (std::size_t i = 1; i < points.size(); ++i)
    if (points[i].first - points[i - 1].first > points[gap].first - points[gap - 1].first) gap = i;
  ASSERT_GT(points[gap].first - points[gap - 1].first, 0.5) << "the silence shows as a gap";
  // The table's true line: 1 rad/s of host time (the simulated controller integrates the time
  // that passed between its ticks), through the rows before the silence. Each row against it, in
  // seconds of the table's turning. The rows' own slope is only a check that they are the table's:
  // while the time base slews a start-up correction in, their period may differ from the true one
  // by up to its slew limit.
  constexpr double kRateRadS = 1.0;
  constexpr double kMaxSlew = SlewedTimeBase::kDefaultMaxSlew;
  double st = 0, sp = 0, stt = 0, stp = 0;
  const auto n = static_cast<double>(gap);
  for (std::size_t i = 0; i < gap; ++i) {
    st += points[i].first;
    sp += points[i].second;
    stt += points[i].first * points[i].first;
    stp += points[i].first * points[i].second;
  }
  const double slope = (n * stp - st * sp) / (n * stt - st * st);
  EXPECT_NEAR(slope, kRateRadS, kMaxSlew * kRateRadS) << "the rows before the silence turn at the table's rate";
  const double offset = (sp - kRateRadS * st) / n;
  double before = 0, after = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double error_s = std::abs(points[i].second - (offset + kRateRadS * points[i].first)) / kRateRadS;
    (i < gap ? before : after) = std::max(i < gap ? before : after, error_s);
  }
  std::cout << "table rows against their own times: worst " << before * 1e3 << " ms before the silence, " << after * 1e3
            << " ms after it; their slope before it " << slope << " rad/s\n";
  // The simulated controller updates its position every physics step (20 ms): a reading is up to
  // a step old, its poll up to a step late on a loaded machine, and after the gap the time base
  // slews the fit's new estimate in over the next blocks rather than jumping. Timed by the count
  // of polls, the rows after the silence would be early by the polls it skipped: most of its 1 s.
  constexpr double kStepS = 0.02;
  EXPECT_LT(before, 2 * kStepS);
  EXPECT_LT(after, 5 * kStepS);
}

}  // namespace
}  // namespace inertia::daq::testing
