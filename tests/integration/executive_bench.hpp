#pragma once
// The real bench the executive and safety tests run the daemon on: the simulated bench
// controllers (hal/wire_sim/bench_controllers.hpp) behind a real Modbus TCP server on loopback,
// wired as three devices with their roles, safe values and heartbeats, and the test plans.
#include <time.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "hal/wire_sim/bench_controllers.hpp"
#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {

using hal::wire_sim::BenchControllerServer;
using hal::wire_sim::BenchControllerState;
namespace reg = hal::wire_sim::bench_registers;

/// The controllers' communication-loss timeout, on both sides: the simulated controllers trip
/// after it, and the bench file says so. Above the heartbeat's worst gap on these devices (period
/// 0.1 s + poll 0.02 s + 2 x 0.3 s response timeout).
inline constexpr double kHeartbeatTimeoutS = 1.0;

inline std::int64_t mono_now_ns() {
  timespec t{};
  ::clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}

inline std::size_t line_of(const std::string& text, const std::string& prefix, int nth = 1) {
  std::istringstream in(text);
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n)
    if (line.rfind(prefix, 0) == 0 && --nth == 0) return n;
  return 0;
}

inline std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

/// The controllers' communication-loss watchdog: the simulated controllers' heartbeat register.
inline std::string heartbeat_register() {
  return "[[modbus_device.register]]\nname = \"watchdog\"\naddress = 0x1007\nkind = \"holding\"\nwritable = true\nmin = 0\n"
         "max = 65535\nrole = \"heartbeat\"\ntimeout_s = " + std::to_string(kHeartbeatTimeoutS) + "\nstop_s = 1.0\n";
}

/// The three simulated controllers as a real bench wires them: one device each, all on the one
/// server (three connections, three polling threads, three safe states, three heartbeats on the
/// one register). The controllers' communication-loss trip (comm_status bit 0) is a fault.
inline std::string controllers(int port, const std::string& writes = "true") {
  const std::string head = "host = \"127.0.0.1\"\nport = " + std::to_string(port) +
                           "\npoll_interval_ms = 20\nresponse_timeout_s = 0.3\nwrites_enabled = " + writes + "\n";
  return "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\n" + head +
         "[[modbus_device.register]]\nname = \"rate_setpoint\"\naddress = 0x1001\nkind = \"holding\"\ntype = \"f32\"\n"
         "unit = \"rad/s\"\nwritable = true\nmin = -3.0\nmax = 3.0\nrole = \"table_rate\"\nmax_rate = 4.0\nsafe = 0.0\n"
         "measured = \"rate\"\ntolerance = 0.005\nsettle_s = 0.1\nsettle_timeout_s = 5.0\n"
         "[[modbus_device.register]]\nname = \"angle_setpoint\"\naddress = 0x1004\nkind = \"holding\"\ntype = \"f32\"\n"
         "unit = \"rad\"\nwritable = true\nmin = -10.0\nmax = 10.0\nrole = \"table_angle\"\nmax_rate = 20.0\n"
         "stopped_by = \"rate_setpoint\"\nsettled_by = \"status\"\nsettled_mask = 2\nsettle_s = 0.05\nsettle_timeout_s = 5.0\n"
         "[[modbus_device.register]]\nname = \"rate\"\naddress = 0x2004\nkind = \"input\"\ntype = \"f32\"\nword_order = \"BADC\"\nunit = \"rad/s\"\n"
         "[[modbus_device.register]]\nname = \"status\"\naddress = 0x200B\nkind = \"input\"\n"
         "[[modbus_device.register]]\nname = \"position\"\naddress = 0x200D\nkind = \"input\"\ntype = \"f32\"\nunit = \"rad\"\n"
         "[[modbus_device.register]]\nname = \"comm\"\naddress = 0x200F\nkind = \"input\"\nrole = \"fault\"\nfault_mask = 1\n" +
         heartbeat_register() +
         "\n[[modbus_device]]\nname = \"shaker\"\nrole = \"shaker\"\n" + head +
         "[[modbus_device.register]]\nname = \"run\"\naddress = 0x1003\nkind = \"holding\"\nwritable = true\nmin = 0\nmax = 1\n"
         "role = \"shaker_run\"\nsafe = 0\nsettled_by = \"status\"\nsettled_mask = 1\nsettle_timeout_s = 5.0\n"
         "[[modbus_device.register]]\nname = \"profile\"\naddress = 0x1006\nkind = \"holding\"\nwritable = true\nmin = 1\nmax = 8\n"
         "role = \"shaker_profile\"\n"
         "[[modbus_device.register]]\nname = \"status\"\naddress = 0x2006\nkind = \"input\"\nrole = \"fault\"\nfault_mask = 2\n"
         "[[modbus_device.register]]\nname = \"frequency\"\naddress = 0x2007\nkind = \"input\"\ntype = \"u32\"\nword_order = \"DCBA\"\n"
         "scale = 0.001\nunit = \"Hz\"\n" +
         heartbeat_register() +
         "\n[[modbus_device]]\nname = \"thermal\"\nrole = \"thermal\"\n" + head +
         "[[modbus_device.register]]\nname = \"setpoint\"\naddress = 0x1000\nkind = \"holding\"\ntype = \"i16\"\nscale = 0.01\n"
         "unit = \"degC\"\nwritable = true\nmin = 10.0\nmax = 60.0\nrole = \"thermal_setpoint\"\nmax_rate = 20.0\nsafe = 25.0\n"
         "measured = \"temperature\"\ntolerance = 0.1\nsettle_s = 0.1\nsettle_timeout_s = 5.0\n"
         "[[modbus_device.register]]\nname = \"temperature\"\naddress = 0x2000\nkind = \"input\"\ntype = \"i16\"\nscale = 0.01\nunit = \"degC\"\n" +
         heartbeat_register();
}

inline std::string bench_head(const std::string& executive) {
  return "[bench]\nname = \"exec-bench\"\nbackend = \"real\"\nexecutive = \"" + executive + "\"\nsample_rate_hz = 1000.0\n\n";
}

inline const std::string kTableCase =
    "\n[[case]]\nname = \"table\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
    "[[case.phase]]\nkind = \"dwell\"\nduration_s = 0.3\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nrate_deg_s = 45.0\nduration_s = 0.4\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nangle_deg = 90.0\nduration_s = 0.4\n";
inline const std::string kShakerCase =
    "\n[[case]]\nname = \"shake\"\nkind = \"shaker\"\norientation = \"IA\"\n"
    "[[case.phase]]\nkind = \"sine\"\nfrequency_hz = 30.0\namplitude_g = 1.0\nprofile = 3\nduration_s = 0.3\n";
inline const std::string kThermalCase =
    "\n[[case]]\nname = \"warm\"\nkind = \"thermal\"\norientation = \"IA\"\n"
    "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 27.0\nduration_s = 0.3\n";

inline BenchControllerState moving_controllers() {
  BenchControllerState s;
  s.temperature_degC = 25.0;
  s.temperature_setpoint_degC = 25.0;
  s.thermal_time_constant_s = 0.3;
  s.table_max_accel_rad_s2 = 4.0;
  s.table_max_rate_rad_s = 2.0;
  s.heartbeat_timeout_s = kHeartbeatTimeoutS;
  return s;
}


/// A test on a real bench of the simulated controllers: the controllers' server, a scratch
/// directory for the bench file and the daemon's command socket, and a wait on the daemon's output.
class RealBenchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    controllers_ = BenchControllerServer::start(0, &why, moving_controllers());
    ASSERT_NE(controllers_, nullptr) << why;
  }
  /// `text` as `name` in the scratch directory, with `mode`.
  fs::path write(const std::string& text, const std::string& name = "bench.toml", fs::perms mode = fs::perms(0644)) {
    const fs::path p = dir_.path / name;
    std::ofstream(p) << text;
    fs::permissions(p, mode);
    return p;
  }
  /// The daemon's command socket (inertia-daqd mark and arm reach it with --socket).
  [[nodiscard]] std::string socket_path() const { return (dir_.path / "command.sock").string(); }
  /// Polls the daemon's output until `text` appears; false after `timeout_s`.
  static bool wait_for(const DaqdProcess& daqd, const std::string& text, double timeout_s) {
    const std::int64_t deadline = mono_now_ns() + static_cast<std::int64_t>(timeout_s * 1e9);
    while (mono_now_ns() < deadline) {
      if (daqd.output().find(text) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }
  TempDir dir_;
  std::unique_ptr<BenchControllerServer> controllers_;
};

}  // namespace inertia::daq::testing
