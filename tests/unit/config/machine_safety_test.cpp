// What makes a real bench safe to command, refused at load with file:line and the fix
// (common/config/machine_safety.hpp): every controller that can move or heat has a heartbeat its
// communication-loss action watches, whose timeout stays within the daemon's watchdog and above
// a healthy daemon's worst heartbeat gap; an angle move names what stops it; a writable register
// without a role may join the safe state.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/config/machine_safety.hpp"
#include "common/input_error.hpp"
#include "tests/unit/config/bench_file_test.hpp"

namespace {

using inertia::InputError;
using namespace inertia::config;
namespace fs = std::filesystem;

const std::string kHead = "[bench]\nname = \"s\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n";

std::string device(const std::string& settings, const std::string& registers) {
  return "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\nwrites_enabled = true\n" + settings + registers;
}
const std::string kRate =
    "[[modbus_device.register]]\nname = \"rate_setpoint\"\naddress = 1\nkind = \"holding\"\ntype = \"f32\"\nwritable = true\n"
    "min = -3.0\nmax = 3.0\nrole = \"table_rate\"\nmax_rate = 2.0\nsafe = 0.0\n";
std::string heartbeat(const std::string& keys = "timeout_s = 2.0\nstop_s = 2.0\n") {
  return "[[modbus_device.register]]\nname = \"watchdog\"\naddress = 7\nkind = \"holding\"\nwritable = true\nmin = 0\n"
         "max = 65535\nrole = \"heartbeat\"\n" + keys;
}

using MachineSafety = inertia::config::testing::BenchFileTest;

TEST_F(MachineSafety, AHeartbeatLoadsWithItsControllersTimeoutAndStopTime) {
  const BenchConfig b = load_bench_config(write(kHead + "stop_within_s = 4.0\n" + device("", kRate + heartbeat("period_s = 0.2\ntimeout_s = 1.5\nstop_s = 2.5\n"))));
  const ModbusDevice& d = b.modbus_devices[0];
  const auto h = heartbeat_register(d);
  ASSERT_TRUE(h);
  EXPECT_EQ(*h, 1u);
  EXPECT_EQ(d.registers[*h].role, RegisterRole::Heartbeat);
  EXPECT_DOUBLE_EQ(d.registers[*h].heartbeat_period_s, 0.2);
  EXPECT_DOUBLE_EQ(d.registers[*h].heartbeat_timeout_s, 1.5);
  EXPECT_DOUBLE_EQ(d.registers[*h].heartbeat_stop_s, 2.5);
  ASSERT_TRUE(b.stop_within_s);
  EXPECT_DOUBLE_EQ(*b.stop_within_s, 4.0);
  // Defaults: poll 100 ms, response timeout 0.5 s: 0.2 + 0.1 + 1.0.
  EXPECT_DOUBLE_EQ(heartbeat_worst_gap_s(d, d.registers[*h]), 1.3);
}

TEST_F(MachineSafety, AControllerThatCanMoveWithoutAHeartbeatIsRefusedAtItsRole) {
  const std::string text = kHead + device("", kRate);
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"table_rate\""));
  EXPECT_NE(std::string(e.what()).find("has no register with role = \"heartbeat\": a daemon that died would leave it as it was"),
            std::string::npos)
      << e.what();
  // Writes off: the daemon commands nothing, so nothing needs its heartbeat.
  std::string off = kHead + device("", kRate);
  off.replace(off.find("writes_enabled = true"), 21, "writes_enabled = false");
  EXPECT_NO_THROW((void)load_bench_config(write(off)));
}

TEST_F(MachineSafety, ATimeoutBeyondTheWatchdogOrWithinAHealthyDaemonsGapIsRefusedAtTimeout) {
  std::string text = kHead + device("", kRate + heartbeat("timeout_s = 6.0\nstop_s = 1.0\n"));
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "timeout_s = 6.0"));
  EXPECT_NE(std::string(e.what()).find("longer than the daemon's watchdog (5 s)"), std::string::npos) << e.what();
  // 0.1 s period + 0.1 s poll + 2 x 0.5 s response timeout = 1.2 s: a timeout of 1.2 s trips on
  // one slow request.
  text = kHead + device("", kRate + heartbeat("timeout_s = 1.2\nstop_s = 1.0\n"));
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "timeout_s = 1.2"));
  EXPECT_NE(std::string(e.what()).find("would stop a healthy bench: the heartbeat may come period_s + poll_interval_ms + 2 x "
                                       "response_timeout_s = 1.2 s apart"),
            std::string::npos)
      << e.what();
  // A shorter response timeout makes the same timeout safe.
  EXPECT_NO_THROW((void)load_bench_config(write(kHead + device("response_timeout_s = 0.2\n", kRate + heartbeat("timeout_s = 1.2\nstop_s = 1.0\n")))));
}

TEST_F(MachineSafety, APollSlowerThanTheWatchdogIsRefusedOnADeviceTheExecutiveJudges) {
  const std::string text = kHead + device("poll_interval_ms = 4500\n", kRate + heartbeat("timeout_s = 5.0\nstop_s = 1.0\n"));
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "poll_interval_ms = 4500"));
  EXPECT_NE(std::string(e.what()).find("one poll may take poll_interval_ms + 2 x response_timeout_s = 5.5 s, more than the "
                                       "daemon's watchdog (5 s)"),
            std::string::npos)
      << e.what();
}

TEST_F(MachineSafety, TwoHeartbeatsOnOneControllerAreRefused) {
  std::string second = heartbeat();
  second.replace(second.find("watchdog"), 8, "watchdog2");
  second.replace(second.find("address = 7"), 11, "address = 8");
  const std::string text = kHead + device("", kRate + heartbeat() + second);
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"heartbeat\"", 2));
  EXPECT_NE(std::string(e.what()).find("already has a heartbeat register ('watchdog'"), std::string::npos) << e.what();
}

TEST_F(MachineSafety, AnAngleMoveNamesTheRegisterThatStopsItWhichHasASafeValue) {
  const std::string angle =
      "[[modbus_device.register]]\nname = \"angle_setpoint\"\naddress = 4\nkind = \"holding\"\ntype = \"f32\"\nwritable = true\n"
      "min = -7.0\nmax = 7.0\nrole = \"table_angle\"\nmax_rate = 1.0\n";
  std::string text = kHead + device("", kRate + angle + heartbeat());
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"table_angle\""));
  EXPECT_NE(std::string(e.what()).find("needs stopped_by"), std::string::npos) << e.what();

  text = kHead + device("", kRate + angle + "safe = 0.0\n" + heartbeat());
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "safe = 0.0", 2));
  EXPECT_NE(std::string(e.what()).find("an angle setpoint has no safe value"), std::string::npos) << e.what();

  // A mode register without a role joins the safe state; one without `safe` cannot stop a move.
  const std::string mode =
      "[[modbus_device.register]]\nname = \"mode\"\naddress = 9\nkind = \"holding\"\nwritable = true\nmin = 0\nmax = 2\n";
  text = kHead + device("", kRate + angle + "stopped_by = \"mode\"\n" + mode + heartbeat());
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "stopped_by = \"mode\""));
  EXPECT_NE(std::string(e.what()).find("register 'mode' has no safe value"), std::string::npos) << e.what();

  const BenchConfig b = load_bench_config(write(kHead + device("", kRate + angle + "stopped_by = \"mode\"\n" + mode + "safe = 0\n" + heartbeat())));
  EXPECT_EQ(b.modbus_devices[0].registers[1].stopped_by, "mode");
  EXPECT_EQ(b.modbus_devices[0].registers[2].role, RegisterRole::None);
  ASSERT_TRUE(b.modbus_devices[0].registers[2].safe);
  EXPECT_DOUBLE_EQ(*b.modbus_devices[0].registers[2].safe, 0.0);
}

TEST_F(MachineSafety, HeartbeatKeysBelongToAHeartbeatAndItMustBeWritable) {
  std::string text = kHead + device("", kRate + heartbeat() + "[[modbus_device.register]]\nname = \"t\"\naddress = 2\nkind = \"input\"\ntimeout_s = 1.0\n");
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "timeout_s = 1.0"));
  EXPECT_NE(std::string(e.what()).find("applies to a register with role = \"heartbeat\""), std::string::npos) << e.what();
  text = kHead + device("", kRate + "[[modbus_device.register]]\nname = \"w\"\naddress = 7\nkind = \"holding\"\nrole = \"heartbeat\"\ntimeout_s = 1.0\nstop_s = 1.0\n");
  e = error_of(text);
  EXPECT_NE(std::string(e.what()).find("needs writable = true"), std::string::npos) << e.what();
  text = kHead + device("", kRate + heartbeat("stop_s = 1.0\n"));
  e = error_of(text);
  EXPECT_NE(std::string(e.what()).find("needs timeout_s: the controller's communication-loss timeout"), std::string::npos) << e.what();
}

}  // namespace
