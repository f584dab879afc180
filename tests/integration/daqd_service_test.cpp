// inertia-daqd as a service: started as systemd would start it (NOTIFY_SOCKET, WATCHDOG_USEC),
// READY/WATCHDOG/STOPPING, graceful SIGTERM with nothing lost, SIGHUP rotation, a disk stall that
// must not stall sampling or publishing, bad input, and the unit file under systemd-analyze.
#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>

#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

const std::string kSmall = source_path("tests/integration/configs/daq-small.toml");

/// Total samples per channel of a device in the log, checking continuity on the way.
inline std::int64_t logged_samples(const std::vector<LogEvent>& events, const std::string& channel, std::int64_t* gaps) {
  const auto blocks = decode_all<sample_block_t>(events, channel);
  *gaps = sequence_gaps(blocks);
  std::int64_t n = 0;
  for (const auto& b : blocks) n += b.num_samples;
  return n;
}

TEST(DaqdService, NotifiesReadyAndWatchdogThenStopsCleanlyOnSigterm) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  NotifySocket notify(tmp.path / "notify.sock");
  const std::string url = private_lcm_url();
  // Paced, with a duration far longer than the test: only SIGTERM ends it.
  DaqdProcess daqd({"--config", kSmall, "--duration", "600", "--log", (tmp.path / "log").string(), "--lcm-url", url},
                   {"NOTIFY_SOCKET=" + notify.path().string(), "WATCHDOG_USEC=400000"}, tmp.path / "stderr.txt");
  bool ready = false;
  int watchdogs = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10) && watchdogs < 3) {
    const std::string msg = notify.receive(1.0);
    if (msg.find("READY=1") != std::string::npos) ready = true;
    if (msg.find("WATCHDOG=1") != std::string::npos) {
      EXPECT_TRUE(ready) << "WATCHDOG=1 before READY=1";
      ++watchdogs;
    }
  }
  EXPECT_TRUE(ready) << daqd.output();
  EXPECT_GE(watchdogs, 3) << "WATCHDOG=1 every WATCHDOG_USEC/2 while the samplers run";
  daqd.signal(SIGTERM);
  bool stopping = false;
  for (int i = 0; i < 20 && !stopping; ++i) stopping = notify.receive(0.5).find("STOPPING=1") != std::string::npos;
  EXPECT_TRUE(stopping);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("stopped (SIGTERM)"), std::string::npos) << out;

  // Nothing lost: every sample the samplers took is in the log, in order, without gaps.
  const auto events = read_log_dir(tmp.path / "log");
  std::int64_t gaps = 0;
  const std::int64_t accel = logged_samples(events, "INERTIA_RAW_ACCEL", &gaps);
  EXPECT_EQ(gaps, 0);
  EXPECT_GT(accel, 3000) << "at least 0.3 s at 10 kHz (three 200-ms watchdog periods)";
  const auto blocks = decode_all<sample_block_t>(events, "INERTIA_RAW_ACCEL");
  EXPECT_EQ(accel * blocks.front().num_channels, summary_value(out, "  accel:", "samples"));
  const std::int64_t enc = logged_samples(events, "INERTIA_RAW_LINEAR_ENCODER", &gaps);
  EXPECT_EQ(gaps, 0);
  EXPECT_EQ(enc * 2, summary_value(out, "  linear_encoder:", "samples"));
  EXPECT_EQ(summary_value(out, "  log:", "lost"), 0);
  // The log: every published message once, plus one INERTIA_BENCH header per file.
  const long long headers = summary_value(out, "  log:", "headers");
  EXPECT_EQ(headers, 1);
  EXPECT_EQ(static_cast<long long>(events.size()), summary_value(out, "  log:", "messages") + headers);
  EXPECT_EQ(static_cast<long long>(events.size()), summary_value(out, "  lcm:", "messages") + headers);
}

TEST(DaqdService, RunsWithoutSystemdAndSaysWhenNothingIsLogged) {
  // Without NOTIFY_SOCKET (started by hand) the daemon runs and exits as usual; without --log
  // it says that nothing is recorded durably.
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  DaqdProcess daqd({"--config", kSmall, "--fast", "--duration", "0.3", "--lcm-url", private_lcm_url()}, {},
                   tmp.path / "stderr.txt");
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  EXPECT_NE(daqd.output().find("no --log DIR"), std::string::npos) << "running without a log is said, not hidden";
}

TEST(DaqdService, SighupStartsANewLogFileWithoutLosingAnything) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  NotifySocket notify(tmp.path / "notify.sock");
  DaqdProcess daqd({"--config", kSmall, "--duration", "600", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {"NOTIFY_SOCKET=" + notify.path().string()}, tmp.path / "stderr.txt");
  for (int i = 0; i < 20; ++i)
    if (notify.receive(0.5).find("READY=1") != std::string::npos) break;
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  daqd.signal(SIGHUP);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  daqd.signal(SIGHUP);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  std::size_t files = 0;
  const auto events = read_log_dir(tmp.path / "log", &files);
  EXPECT_EQ(files, 3u);
  std::int64_t gaps = 0;
  const std::int64_t accel = logged_samples(events, "INERTIA_RAW_ACCEL", &gaps);
  EXPECT_EQ(gaps, 0) << "the files join without a gap";
  const auto blocks = decode_all<sample_block_t>(events, "INERTIA_RAW_ACCEL");
  EXPECT_EQ(accel * blocks.front().num_channels, summary_value(daqd.output(), "  accel:", "samples"));
  // Each file is a valid LCM log on its own (lcm-logplayer plays any one of them).
  for (const auto& e : std::filesystem::directory_iterator(tmp.path / "log")) {
    lcm::LogFile f(e.path().string(), "r");
    ASSERT_TRUE(f.good());
    EXPECT_NE(f.readNextEvent(), nullptr) << e.path();
  }
}

/// The writer sleeps 1.5 s (an injected disk stall) while the bench runs paced: the live stream
/// must keep flowing (no gap in received blocks near the stall's length), the status must say
/// "disk-slow", and with a queue large enough nothing is lost from the log.
void run_stall(std::size_t queue, bool expect_loss) {
  TempDir tmp;
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  DaqdProcess daqd({"--config", kSmall, "--duration", "2.5", "--log", (tmp.path / "log").string(), "--lcm-url", url,
                    "--fault", "log-stall@0.3+1500", "--log-queue", std::to_string(queue)},
                   {}, tmp.path / "stderr.txt");
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  const std::string out = daqd.output();
  const auto received = live.take();
  std::int64_t max_gap_ns = 0, last = 0;
  bool disk_slow = false;
  for (const auto& r : received) {
    if (r.channel == "INERTIA_RAW_ACCEL") {
      if (last != 0) max_gap_ns = std::max(max_gap_ns, r.mono_ns - last);
      last = r.mono_ns;
    }
    if (r.channel == "INERTIA_STATUS") {
      daq_status_t st;
      if (st.decode(r.data.data(), 0, static_cast<int>(r.data.size())) >= 0)
        for (const auto& f : st.faults) disk_slow = disk_slow || f == "disk-slow";
    }
  }
  EXPECT_TRUE(disk_slow) << "the stall is reported on INERTIA_STATUS";
  EXPECT_LT(max_gap_ns, 300'000'000) << "publishing went on during the 1.5 s stall (blocks every 10 ms)";
  const long long published = summary_value(out, "  lcm:", "messages");
  const long long written = summary_value(out, "  log:", "messages");
  const long long lost = summary_value(out, "  log:", "lost");
  EXPECT_EQ(written + lost, published) << "every message is either in the log or counted as lost";
  EXPECT_EQ(static_cast<long long>(read_log_dir(tmp.path / "log").size()), written + summary_value(out, "  log:", "headers"))
      << "the log holds the written messages and one INERTIA_BENCH header per file";
  EXPECT_EQ(summary_value(out, "  accel:", "ring drops"), 0) << "sampling did not stall";
  if (expect_loss) {
    EXPECT_GT(lost, 0);
  } else {
    EXPECT_EQ(lost, 0);
  }
  std::cout << "log stall 1.5 s, queue " << queue << ": max live gap " << max_gap_ns / 1e6 << " ms, log lost " << lost
            << " of " << published << "\n";
}

TEST(DaqdService, DiskStallOfOneAndAHalfSecondsDoesNotStallSamplingOrPublishing) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  run_stall(512, false);
}

TEST(DaqdService, LogLossFromAStallLongerThanTheQueueIsCountedNotSilent) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  run_stall(16, true);
}

TEST(DaqdService, BadConfigExitsTwoNamingFileAndLine) {
  TempDir tmp;
  const auto bad = tmp.path / "bad.toml";
  std::ofstream(bad) << "[bench]\nname = \"x\"\nbackend = \"sim\"\nsample_rate_hz = \"fast\"\n";
  DaqdProcess daqd({"--config", bad.string()}, {}, tmp.path / "stderr.txt");
  EXPECT_EQ(daqd.wait(20), 2);
  EXPECT_NE(daqd.output().find("bad.toml:4"), std::string::npos) << daqd.output();
  DaqdProcess missing({"--config", (tmp.path / "none.toml").string()}, {}, tmp.path / "stderr2.txt");
  EXPECT_EQ(missing.wait(20), 2);
  EXPECT_NE(missing.output().find("none.toml"), std::string::npos) << missing.output();
  DaqdProcess option({"--config", kSmall, "--duration", "soon"}, {}, tmp.path / "stderr3.txt");
  EXPECT_EQ(option.wait(20), 2);
  EXPECT_NE(option.output().find("--duration"), std::string::npos) << option.output();
}

TEST(DaqdService, AbsentDeviceOnARealBenchExitsTwoNamingIt) {
  // The bench template wires CAN interfaces this machine does not have (no AF_CAN here, or no
  // can0 elsewhere): the daemon names the required device at its interface key, with the fix,
  // and exits 2 (daqd_check_test.cpp: optional devices).
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  DaqdProcess daqd({"--config", source_path("config/bench-template.toml"), "--lcm-url", private_lcm_url()}, {},
                   tmp.path / "stderr.txt");
  EXPECT_EQ(daqd.wait(20), 2);
  const std::string out = daqd.output();
  EXPECT_NE(out.find("config/bench-template.toml:"), std::string::npos) << out;
  EXPECT_NE(out.find(": device 'adc0' (CAN)"), std::string::npos) << out;
  EXPECT_NE(out.find("  fix: "), std::string::npos) << out;
}

TEST(DaqdService, UnitFilePassesSystemdAnalyzeVerify) {
  if (std::system("command -v systemd-analyze > /dev/null 2>&1") != 0) INERTIA_SKIP_OR_FAIL_IN_CI("systemd-analyze not installed");
  TempDir tmp;
  std::ifstream in(source_path("systemd/inertia-daqd.service"));
  std::stringstream ss;
  ss << in.rdbuf();
  std::string unit = ss.str();
  const std::string from = "/usr/bin/inertia-daqd";
  ASSERT_NE(unit.find(from), std::string::npos);
  unit.replace(unit.find(from), from.size(), daqd_binary());
  for (const char* key : {"Type=notify", "WatchdogSec=", "ProtectSystem=strict", "RestrictAddressFamilies=AF_CAN AF_INET AF_UNIX",
                          "CapabilityBoundingSet=\n", "LimitRTPRIO=", "LimitMEMLOCK=", "DeviceAllow=", "StateDirectory=inertia"})
    EXPECT_NE(unit.find(key), std::string::npos) << key;
  const auto path = tmp.path / "inertia-daqd.service";
  std::ofstream(path) << unit;
  const std::string cmd = "systemd-analyze verify " + path.string() + " > " + (tmp.path / "out.txt").string() + " 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream o(tmp.path / "out.txt");
  std::stringstream os;
  os << o.rdbuf();
  EXPECT_EQ(rc, 0) << os.str();
  // Exposure at most 1.8; docs/bench-pc.md, "Hardening", says what sets the floor.
  const std::string security = "systemd-analyze security --offline=yes " + path.string() + " 2>&1 | grep 'Overall exposure' > " +
                               (tmp.path / "security.txt").string();
  ASSERT_EQ(std::system(security.c_str()), 0) << "systemd-analyze security --offline=yes needs systemd >= 250";
  std::ifstream sec(tmp.path / "security.txt");
  std::string line;
  std::getline(sec, line);
  const auto colon = line.find(": ");
  ASSERT_NE(colon, std::string::npos) << line;
  EXPECT_LE(std::stod(line.substr(colon + 2)), 1.8) << line;
}

}  // namespace
}  // namespace inertia::daq::testing

namespace inertia::daq::testing {
namespace {

TEST(DaqdService, WatchdogIsWithheldWhileASamplingThreadHangsAndResumesAfter) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  NotifySocket notify(tmp.path / "notify.sock");
  // Paced; the CAN sampling thread sleeps 1.5 s from 0.5 s (as if stuck in a driver).
  DaqdProcess daqd({"--config", kSmall, "--duration", "600", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url(), "--fault", "sampler-hang@0.5+1.5"},
                   {"NOTIFY_SOCKET=" + notify.path().string(), "WATCHDOG_USEC=400000"}, tmp.path / "stderr.txt");
  std::vector<double> pings;
  // Times from READY=1 (the simulated clock starts there), however slow the start (sanitizers).
  bool ready = false;
  for (int i = 0; i < 60 && !ready; ++i) ready = notify.receive(0.5).find("READY=1") != std::string::npos;
  ASSERT_TRUE(ready) << daqd.output();
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - t0 < std::chrono::milliseconds(3500)) {
    const std::string msg = notify.receive(0.3);
    if (msg.find("WATCHDOG=1") != std::string::npos)
      pings.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  ASSERT_GE(pings.size(), 4u);
  double longest = 0;
  for (std::size_t i = 1; i < pings.size(); ++i) longest = std::max(longest, pings[i] - pings[i - 1]);
  EXPECT_GE(longest, 1.0) << "no WATCHDOG=1 while the sampler was stuck (systemd would restart us)";
  EXPECT_GT(pings.back(), 2.3) << "pings resume once the thread moves again";
  EXPECT_NE(daqd.output().find("accel is not moving"), std::string::npos) << daqd.output();
  // And nothing was lost: the bench waited (CAN back-pressure), the log has no gap.
  std::int64_t gaps = 0;
  (void)logged_samples(read_log_dir(tmp.path / "log"), "INERTIA_RAW_ACCEL", &gaps);
  EXPECT_EQ(gaps, 0);
}

}  // namespace
}  // namespace inertia::daq::testing
