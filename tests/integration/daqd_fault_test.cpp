// Faults injected by the simulator (--fault), and a real full disk (a small tmpfs the test
// mounts; skipped when not root): the daemon keeps sampling every healthy device, reports the
// fault on INERTIA_STATUS, recovers when it clears, and the log shows exactly which samples are
// missing or invalid.
#include <gtest/gtest.h>
#include <grp.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>

#include "common/config/bench_config.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

const std::string kSmall = source_path("tests/integration/configs/daq-small.toml");

struct DaqdRun {
  std::vector<LogEvent> events;
  std::vector<LcmCollector::Received> live;
  std::string out;
};

DaqdRun run_daqd(const std::vector<std::string>& extra, double timeout_s) {
  DaqdRun r;
  TempDir tmp;
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  std::vector<std::string> args{"--config", kSmall, "--log", (tmp.path / "log").string(), "--lcm-url", url};
  args.insert(args.end(), extra.begin(), extra.end());
  DaqdProcess daqd(args, {}, tmp.path / "stderr.txt");
  const int rc = daqd.wait(timeout_s);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  r.out = daqd.output();
  EXPECT_EQ(rc, 0) << r.out;
  r.events = read_log_dir(tmp.path / "log");
  r.live = live.take();
  return r;
}

std::vector<daq_status_t> statuses(const std::vector<LogEvent>& events) { return decode_all<daq_status_t>(events, "INERTIA_STATUS"); }

const device_status_t* device(const daq_status_t& st, const std::string& name) {
  for (const auto& d : st.devices)
    if (d.device == name) return &d;
  return nullptr;
}

bool has_fault(const device_status_t& d, const std::string& f) {
  return std::find(d.faults.begin(), d.faults.end(), f) != d.faults.end();
}

TEST(DaqdFaults, ModbusServerGoneFiveSecondsOtherDevicesKeepSamplingAndItRecovers) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // Paced: 1.4 s plan run for 12 s (the plan repeats); the controller server is gone from 1 s to
  // 6 s, the 5 s outage, and the reconnect backoff must bring it back before the end. The
  // backoff doubles from 0.5 s (bench_config.hpp), so the attempts after the first failure come
  // 0.5, 1.5, 3.5 and 7.5 s later: the one that finds the server back falls between 6 and about
  // 9.5 s, depending on how soon the loss was detected.
  const DaqdRun r = run_daqd({"--duration", "12", "--fault", "modbus-gone@1+5"}, 40);
  const auto st = statuses(r.events);
  ASSERT_GE(st.size(), 3u);
  bool gone_seen = false, accel_ran_while_gone = false;
  for (const auto& s : st) {
    const auto* c = device(s, "controller");
    const auto* a = device(s, "accel");
    ASSERT_TRUE(c && a);
    if (has_fault(*c, "modbus-gone")) {
      gone_seen = true;
      accel_ran_while_gone = accel_ran_while_gone || a->sample_rate_hz > 5000.0;
    }
  }
  EXPECT_TRUE(gone_seen) << "the outage is reported on INERTIA_STATUS";
  EXPECT_TRUE(accel_ran_while_gone) << "the CAN device kept sampling during the outage";
  EXPECT_FALSE(has_fault(*device(st.back(), "controller"), "modbus-gone")) << "recovered by itself\n" << r.out;
  EXPECT_GE(device(st.back(), "controller")->resyncs, 1) << "reconnects are counted";
  EXPECT_GT(device(st.back(), "controller")->decode_errors, 0) << "failed requests are counted";

  // The log marks the outage: invalid controller samples, valid ones before and after.
  const auto blocks = decode_all<sample_block_t>(r.events, "INERTIA_RAW_CONTROLLER");
  EXPECT_EQ(sequence_gaps(blocks), 0);
  const int t = channel_index(blocks.front(), "temperature");
  std::vector<bool> valid;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s) valid.push_back(sample_valid(b, t, s));
  const auto first_invalid = std::find(valid.begin(), valid.end(), false);
  ASSERT_NE(first_invalid, valid.end()) << "some samples are marked invalid";
  EXPECT_TRUE(valid.front());
  EXPECT_TRUE(valid.back()) << "valid again after the server came back";
  const auto invalid = std::count(valid.begin(), valid.end(), false);
  std::cout << "modbus gone 5 s: " << invalid << " of " << valid.size() << " controller rows invalid\n";
  // Accelerometers: no gap at all.
  EXPECT_EQ(sequence_gaps(decode_all<sample_block_t>(r.events, "INERTIA_RAW_ACCEL")), 0);
  EXPECT_EQ(summary_value(r.out, "  accel:", "ring drops"), 0);
}

TEST(DaqdFaults, CanBusOffIsReportedAndTheMissingSamplesAreExactlyVisible) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // Paced 2.5 s; bus-off from 0.5 s for 1.2 s: 12000 samples never sent.
  const DaqdRun r = run_daqd({"--duration", "2.5", "--fault", "bus-off@0.5+1.2"}, 30);
  bool bus_off_seen = false;
  for (const auto& s : statuses(r.events)) bus_off_seen = bus_off_seen || has_fault(*device(s, "accel"), "bus-off");
  EXPECT_TRUE(bus_off_seen);
  EXPECT_FALSE(has_fault(*device(statuses(r.events).back(), "accel"), "bus-off")) << "restarted";
  const auto blocks = decode_all<sample_block_t>(r.events, "INERTIA_RAW_ACCEL");
  EXPECT_EQ(sequence_gaps(blocks), 0) << "the daemon lost nothing of what arrived";
  const int idx = channel_index(blocks.front(), "sample_index");
  std::vector<double> index;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s) index.push_back(b.values[static_cast<std::size_t>(idx)][static_cast<std::size_t>(s)]);
  std::size_t jumps = 0;
  double missing = 0;
  for (std::size_t i = 1; i < index.size(); ++i)
    if (index[i] != index[i - 1] + 1) {
      ++jumps;
      missing += index[i] - index[i - 1] - 1;
    }
  EXPECT_EQ(jumps, 1u);
  EXPECT_EQ(missing, 12000.0) << "exactly the samples of the bus-off time are missing";
  EXPECT_EQ(static_cast<double>(index.size()) + missing, 25000.0);
  // The other devices did not notice.
  EXPECT_EQ(sequence_gaps(decode_all<sample_block_t>(r.events, "INERTIA_RAW_LINEAR_ENCODER")), 0);
}

TEST(DaqdFaults, EncoderGlitchesAreCountedAndTheCountStaysRight) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  const DaqdRun r = run_daqd({"--fast", "--fault", "encoder-glitch@50"}, 60);
  const config::BenchConfig bench = config::load_bench_config(kSmall);
  const auto truth = sim::simulate_bench(bench);
  const auto& x = truth.cases[0].motion.shaker_x_m;
  const double res = bench.linear_encoder.resolution;
  std::int64_t edges = 0;
  for (Eigen::Index k = 1; k < x.size(); ++k)
    edges += std::llabs(static_cast<std::int64_t>(std::floor(x[k] / res) - std::floor(x[k - 1] / res)));
  const auto last = statuses(r.events).back();
  EXPECT_EQ(device(last, "linear_encoder")->decode_errors, edges / 50) << "one glitch per 50 edges, each counted";
  const auto blocks = decode_all<sample_block_t>(r.events, "INERTIA_RAW_LINEAR_ENCODER");
  const double c0 = std::floor(x[0] / res);
  std::int64_t wrong = 0;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s)
      wrong += b.values[0][static_cast<std::size_t>(s)] != std::floor(x[b.channel_seq[0] + s] / res) - c0;
  EXPECT_EQ(wrong, 0) << "a duplicate edge is a glitch, not motion";
}

}  // namespace
}  // namespace inertia::daq::testing

namespace inertia::daq::testing {
namespace {

TEST(DaqdFaults, StuckSensorIsMarkedInvalidExactlyFromDetectionOn) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // Fast; the first sensor's output freezes from 0.5 s for 0.3 s (3000 samples at 10 kHz).
  const DaqdRun r = run_daqd({"--fast", "--fault", "stuck@0.5+0.3"}, 60);
  const auto blocks = decode_all<sample_block_t>(r.events, "INERTIA_RAW_ACCEL");
  ASSERT_FALSE(blocks.empty());
  const int stuck_ch = channel_index(blocks.front(), "acc-a");
  ASSERT_EQ(stuck_ch, 0);
  // Held from sample 5000 (its own value) through 7999: samples 5001.. repeat it; the run reaches
  // kSimStuckSamples (100) at 5100, so 5100..7999 are invalid: 2900 samples, and nothing else.
  std::int64_t invalid = 0, wrong = 0, other_invalid = 0;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const std::int64_t k = b.channel_seq[0] + s;
      const bool expect_invalid = k >= 5100 && k < 8000;
      const bool valid = sample_valid(b, stuck_ch, s);
      invalid += valid ? 0 : 1;
      wrong += (valid == expect_invalid) ? 1 : 0;
      for (std::int32_t c = 1; c < b.num_channels; ++c) other_invalid += sample_valid(b, c, s) ? 0 : 1;
    }
  EXPECT_EQ(invalid, 2900);
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(other_invalid, 0) << "the other channels of the bus are unaffected";
  EXPECT_EQ(summary_value(r.out, "  accel:", "stuck"), 2900);
}

}  // namespace
}  // namespace inertia::daq::testing

namespace inertia::daq::testing {
namespace {

TEST(DaqdFaults, NanSensorIsMarkedInvalidExactlyReportedAndRecovers) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // Paced 3.5 s; the first sensor sends "no valid reading" from 0.5 s for 1 s: samples
  // 5000..14999 (10000 at 10 kHz) and no others.
  const DaqdRun r = run_daqd({"--duration", "3.5", "--fault", "nan@0.5+1"}, 30);
  const auto blocks = decode_all<sample_block_t>(r.events, "INERTIA_RAW_ACCEL");
  ASSERT_FALSE(blocks.empty());
  EXPECT_EQ(sequence_gaps(blocks), 0);
  const int ch = channel_index(blocks.front(), "acc-a");
  ASSERT_EQ(ch, 0);
  std::int64_t invalid = 0, wrong = 0, not_nan = 0, other_invalid = 0, samples = 0;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s, ++samples) {
      const std::int64_t k = b.channel_seq[0] + s;
      const bool expect_invalid = k >= 5000 && k < 15000;
      const bool valid = sample_valid(b, ch, s);
      invalid += valid ? 0 : 1;
      wrong += (valid == expect_invalid) ? 1 : 0;
      if (!valid && !std::isnan(b.values[0][static_cast<std::size_t>(s)])) ++not_nan;
      for (std::int32_t c = 1; c < b.num_channels; ++c) other_invalid += sample_valid(b, c, s) ? 0 : 1;
    }
  EXPECT_EQ(samples, 35000);
  EXPECT_EQ(invalid, 10000);
  EXPECT_EQ(wrong, 0) << "exactly the samples of the NaN time are invalid";
  EXPECT_EQ(not_nan, 0) << "an invalid sample carries NaN, never a number";
  EXPECT_EQ(other_invalid, 0) << "the other channels of the bus are unaffected";
  EXPECT_EQ(summary_value(r.out, "  accel:", "invalid"), 10000);
  EXPECT_EQ(summary_value(r.out, "  accel:", "stuck"), 0) << "NaN is not a stuck value";
  // INERTIA_STATUS: reported while it lasts, cleared after; the journal says both.
  bool seen = false;
  for (const auto& s : statuses(r.events)) seen = seen || has_fault(*device(s, "accel"), "invalid-samples");
  EXPECT_TRUE(seen);
  EXPECT_FALSE(has_fault(*device(statuses(r.events).back(), "accel"), "invalid-samples")) << "recovered";
  EXPECT_NE(r.out.find("accel: fault invalid-samples"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("accel: cleared invalid-samples"), std::string::npos) << r.out;
}


TEST(DaqdFaults, FullDiskKeepsSamplingAndPublishingCountsTheMissingBlocksAndResumes) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  SmallDisk disk(tmp.path / "disk", "6m");
  if (!disk.why_not.empty()) INERTIA_SKIP_OR_FAIL_IN_CI(disk.why_not);
  {  // 5 of the 6 MiB taken: the log (~1.3 MB/s) fills the rest within about a second
    std::ofstream filler(disk.path / "filler", std::ios::binary);
    const std::vector<char> chunk(1 << 20, 'f');
    for (int i = 0; i < 5; ++i) filler.write(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    ASSERT_TRUE(filler.good());
  }
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  DaqdProcess daqd({"--config", kSmall, "--duration", "5", "--log", (disk.path / "log").string(), "--lcm-url", url},
                   {}, tmp.path / "stderr.txt");
  const auto t0 = std::chrono::steady_clock::now();
  while (daqd.output().find("log: disk full") == std::string::npos &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_NE(daqd.output().find("log: disk full"), std::string::npos) << "the journal says so\n" << daqd.output();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  fs::remove(disk.path / "filler");  // space is back
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("log: writing again"), std::string::npos) << out;

  // INERTIA_STATUS (live: the log missed some of them) says disk-full while it lasted.
  bool full_seen = false, full_at_end = false;
  for (const auto& m : live.take()) {
    if (m.channel != "INERTIA_STATUS") continue;
    daq_status_t st;
    if (st.decode(m.data.data(), 0, static_cast<int>(m.data.size())) < 0) continue;
    full_at_end = std::find(st.faults.begin(), st.faults.end(), "disk-full") != st.faults.end();
    full_seen = full_seen || full_at_end;
  }
  EXPECT_TRUE(full_seen);
  EXPECT_FALSE(full_at_end) << "recovered by itself";

  // Sampling and publishing never noticed; every message is in the log or counted.
  EXPECT_EQ(summary_value(out, "  accel:", "ring drops"), 0);
  const long long published = summary_value(out, "  lcm:", "messages");
  const long long written = summary_value(out, "  log:", "messages");
  const long long lost = summary_value(out, "  log:", "lost");
  EXPECT_GT(lost, 10);
  EXPECT_EQ(summary_value(out, "  log:", "disk full lost"), lost);
  EXPECT_EQ(written + lost, published);
  std::size_t files = 0;
  const auto events = read_log_dir(disk.path / "log", &files);
  EXPECT_EQ(static_cast<long long>(events.size()), written + static_cast<long long>(files))
      << "whole records only (plus the INERTIA_BENCH header of each file)";

  // The log shows exactly which blocks are missing: seq gaps whose channel_seq jumps by the
  // samples of exactly those blocks, and blocks again after the gap up to the last one.
  long long missing_blocks = 0;
  for (const char* device_name : {"accel", "linear_encoder"}) {
    SCOPED_TRACE(device_name);
    const auto blocks = decode_all<sample_block_t>(events, raw_channel(device_name));
    ASSERT_GT(blocks.size(), 2u);
    EXPECT_EQ(blocks.front().seq, 0);
    long long device_missing = 0;
    for (std::size_t i = 1; i < blocks.size(); ++i) {
      const auto& a = blocks[i - 1];
      const auto& b = blocks[i];
      ASSERT_GT(b.seq, a.seq);
      const long long gap = b.seq - a.seq - 1;
      device_missing += gap;
      for (std::size_t c = 0; c < b.channel_seq.size(); ++c)
        EXPECT_EQ(b.channel_seq[c], a.channel_seq[c] + (gap + 1) * a.num_samples) << "block " << b.seq;
    }
    EXPECT_EQ(blocks.back().seq + 1, summary_value(out, "  " + std::string(device_name) + ":", "blocks"));
    EXPECT_GT(device_missing, 0);
    missing_blocks += device_missing;
  }
  EXPECT_LE(missing_blocks, lost) << "the rest of the lost messages are statuses and markers";
  std::cout << "full disk: " << lost << " messages lost (" << missing_blocks << " accel/encoder blocks), " << written
            << " written\n";
}

// A refused SCHED_FIFO or mlock is on INERTIA_STATUS for the whole run, not one stderr
// line. The daemon runs as nobody with RLIMIT_RTPRIO 0 and a 64 KiB RLIMIT_MEMLOCK, so the
// kernel refuses both, as it would on a bench PC without the unit's limits.
TEST(DaqdFaults, RefusedRealTimeSettingsAreFaultsOnTheStatusChannel) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  if (::geteuid() != 0) INERTIA_SKIP_OR_FAIL_IN_CI("not root: cannot run the daemon as another user");
  TempDir tmp;
  fs::permissions(tmp.path, fs::perms::all);
  const auto drop = [] {
    const rlimit none{0, 0}, small{64 * 1024, 64 * 1024};
    return ::setrlimit(RLIMIT_RTPRIO, &none) == 0 && ::setrlimit(RLIMIT_MEMLOCK, &small) == 0 && ::setgroups(0, nullptr) == 0 &&
           ::setgid(65534) == 0 && ::setuid(65534) == 0;
  };
  DaqdProcess daqd({"--config", kSmall, "--duration", "2", "--fifo-priority", "20", "--mlock", "--log",
                    (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt", daqd_binary(), drop);
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("mlockall"), std::string::npos) << out;
  const auto st = statuses(read_log_dir(tmp.path / "log"));
  ASSERT_FALSE(st.empty());
  const daq_status_t& last = st.back();
  EXPECT_NE(std::find(last.faults.begin(), last.faults.end(), "mlock-refused"), last.faults.end());
  EXPECT_NE(std::find(last.faults.begin(), last.faults.end(), "publisher-realtime-refused"), last.faults.end());
  ASSERT_FALSE(last.devices.empty());
  // Every sampling thread asked for SCHED_FIFO; the Modbus poller ("controller") never does.
  for (const auto& d : last.devices) EXPECT_EQ(has_fault(d, "realtime-refused"), d.device != "controller") << d.device;
}

}  // namespace
}  // namespace inertia::daq::testing
