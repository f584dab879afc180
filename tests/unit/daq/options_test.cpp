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
                                "--fault", "encoder-glitch@100", "--fault", "stuck@2+0.5"},
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
}

TEST(DaemonOptions, BadInputNamesTheOption) {
  bool help = false;
  auto message = [&](const std::vector<std::string>& args) {
    try {
      (void)parse_options(args, &help);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(message({}).find("--config"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--duration", "x"}).find("--duration"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--duration", "-1"}).find("--duration"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--log"}).find("--log needs a value"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fault", "meteor@1"}).find("meteor"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--fault", "bus-off@1"}).find("AT+DURATION"), std::string::npos);
  EXPECT_NE(message({"--config", "b", "--frobnicate"}).find("--frobnicate"), std::string::npos);
}

}  // namespace
}  // namespace inertia::daq
