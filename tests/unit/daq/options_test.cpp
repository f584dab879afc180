// Command line of inertia-daqd: the documented options parse; bad ones throw InputError naming
// the option (main turns that into exit status 2).
#include <gtest/gtest.h>

#include "common/input_error.hpp"
#include "daq/daemon.hpp"

namespace inertia::daq {
namespace {

TEST(DaemonOptions, ParsesTheDocumentedCommandLine) {
  bool help = false;
  const auto o = parse_options({"--config", "b.toml", "--duration", "2.5", "--log", "/tmp/x", "--fast", "--block-ms", "20",
                                "--fault", "modbus-gone@1+5", "--fault", "bus-off@0.5+0.2", "--fault", "log-stall@1+1000",
                                "--fault", "encoder-glitch@100", "--fault", "stuck@2+0.5", "--fault", "nan@1.5+0.25"},
                               &help);
  EXPECT_FALSE(help);
  EXPECT_EQ(o.config, "b.toml");
  EXPECT_DOUBLE_EQ(o.duration_s, 2.5);
  EXPECT_EQ(o.log_dir, "/tmp/x");
  EXPECT_TRUE(o.fast);
  EXPECT_DOUBLE_EQ(o.block_ms, 20.0);
  EXPECT_DOUBLE_EQ(o.faults.modbus_gone_at_s, 1.0);
  EXPECT_DOUBLE_EQ(o.faults.modbus_gone_s, 5.0);
  EXPECT_DOUBLE_EQ(o.faults.bus_off_s, 0.2);
  EXPECT_EQ(o.log_stall_ms, 1000);
  EXPECT_EQ(o.faults.glitch_every, 100u);
  EXPECT_DOUBLE_EQ(o.faults.stuck_at_s, 2.0);
  EXPECT_DOUBLE_EQ(o.faults.stuck_s, 0.5);
  EXPECT_DOUBLE_EQ(o.faults.nan_at_s, 1.5);
  EXPECT_DOUBLE_EQ(o.faults.nan_s, 0.25);
}

TEST(DaemonOptions, BenchFileDaemonTableFillsWhatTheCommandLineDidNotSay) {
  config::DaemonSettings file;
  file.block_ms = 25.0;
  file.fifo_priority = 70;
  file.cpu_affinity = 1;
  file.mlock = true;
  file.rotate_mb = 16.0;
  file.fsync_ms = 200;
  file.log_queue = 64;
  file.ring_samples = 8192;
  file.log_dir = "/var/log/x";
  file.lcm_url = "udpm://239.255.76.67:7667?ttl=0";
  bool help = false;
  // Nothing on the command line: the file decides.
  DaemonOptions a = parse_options({"--config", "b.toml"}, &help);
  apply_bench_settings(a, file);
  EXPECT_DOUBLE_EQ(a.block_ms, 25.0);
  EXPECT_EQ(a.fifo_priority, 70);
  EXPECT_EQ(a.cpu, 1);
  EXPECT_TRUE(a.mlock);
  EXPECT_DOUBLE_EQ(a.rotate_mb, 16.0);
  EXPECT_EQ(a.fsync_ms, 200);
  EXPECT_EQ(a.log_queue, 64u);
  EXPECT_EQ(a.ring, 8192u);
  EXPECT_EQ(a.log_dir, "/var/log/x");
  EXPECT_EQ(a.lcm_url, file.lcm_url);
  // The command line wins, option by option, even when it repeats the built-in default.
  DaemonOptions b = parse_options({"--config", "b.toml", "--block-ms", "10", "--fifo-priority", "0", "--cpu", "-1",
                                   "--fsync-ms", "1000", "--log", "/tmp/y", "--ring", "131072"},
                                  &help);
  apply_bench_settings(b, file);
  EXPECT_DOUBLE_EQ(b.block_ms, 10.0);
  EXPECT_EQ(b.fifo_priority, 0);
  EXPECT_EQ(b.cpu, -1);
  EXPECT_EQ(b.fsync_ms, 1000);
  EXPECT_EQ(b.log_dir, "/tmp/y");
  EXPECT_EQ(b.ring, 131072u);
  EXPECT_TRUE(b.mlock) << "not on the command line: from the file";
  EXPECT_DOUBLE_EQ(b.rotate_mb, 16.0);
  // No [daemon] table: the built-in defaults stay.
  DaemonOptions c = parse_options({"--config", "b.toml"}, &help);
  apply_bench_settings(c, config::DaemonSettings{});
  EXPECT_DOUBLE_EQ(c.block_ms, 10.0);
  EXPECT_EQ(c.fifo_priority, 0);
  EXPECT_FALSE(c.mlock);
  EXPECT_TRUE(c.log_dir.empty());
}

// What parse_options says of `args`: its InputError's text, or "(accepted)".
std::string message(const std::vector<std::string>& args) {
  bool help = false;
  try {
    (void)parse_options(args, &help);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(DaemonOptions, BadInputNamesTheOption) {
  EXPECT_NE(message({}).find("--config"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--duration", "x"}).find("--duration"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--duration", "-1"}).find("--duration"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--log"}).find("--log needs a value"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fault", "meteor@1"}).find("meteor"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fault", "bus-off@1"}).find("AT+DURATION"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--frobnicate"}).find("--frobnicate"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fsync-ms", "0"}).find("--fsync-ms"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fault", "nan@1"}).find("AT+DURATION"), std::string::npos);
}

TEST(DaemonOptions, CountsAndIndicesAreWholeNumbersInRangeNeverAnUndefinedCast) {
  for (const char* option : {"--fifo-priority", "--cpu", "--ring", "--log-queue", "--fsync-ms"}) {
    for (const char* value : {"-5", "1e30", "2.5", "nan", "inf"}) {
      const std::string m = message({"--config", "b", option, value});
      EXPECT_NE(m.find(option), std::string::npos) << option << " " << value << ": " << m;
    }
  }
  for (const char* value : {"nan", "inf", "5000"}) {
    EXPECT_NE(message({"--config", "b", "--block-ms", value}).find("--block-ms"), std::string::npos) << value;
  }
  EXPECT_NE(message({"--config", "b", "--duration", "inf"}).find("--duration"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--rotate-mb", "nan"}).find("--rotate-mb"), std::string::npos);
  // The bench file's ranges (config::DaemonLimits), both ends accepted.
  EXPECT_EQ(message({"--config", "b", "--fifo-priority", "99", "--cpu", "4095", "--ring", "268435456", "--log-queue", "4"}),
            "(accepted)");
  EXPECT_EQ(message({"--config", "b", "--fifo-priority", "0", "--cpu", "-1", "--ring", "1024", "--fsync-ms", "3600000"}),
            "(accepted)");
  // --check samples nothing: a sampling option beside it would be ignored, so it is refused.
  EXPECT_NE(message({"--check", "--config", "b", "--log", "/tmp/x"}).find("--log"), std::string::npos);
  EXPECT_NE(message({"--check", "--config", "b", "--fast"}).find("--fast"), std::string::npos);
  EXPECT_EQ(message({"--check", "--config", "b"}), "(accepted)");
}

}  // namespace
}  // namespace inertia::daq
