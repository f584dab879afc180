// inertia-daqd --check and a real bench's devices, on the real binary: the simulated
// bench controllers served over Modbus TCP on loopback and Modbus RTU on a pseudo-terminal;
// CAN interfaces, GPIO chips and serial ports that this machine does not have (no AF_CAN, no
// vcan, no /dev/gpiochip*), which must be reported with their bench-file line and a fix, never
// crash; `optional = true` devices the daemon starts without, degraded.
#include <gtest/gtest.h>

#include <fstream>
#include <optional>
#include <regex>

#include "hal/wire_sim/bench_controllers.hpp"
#include "tests/integration/daqd_harness.hpp"
#include "tests/support/pseudo_terminal.hpp"

namespace inertia::daq::testing {
namespace {

using hal::wire_sim::BenchControllerServer;
using hal::wire_sim::BenchControllerState;

BenchControllerState frozen_controllers() {
  BenchControllerState s;
  s.frozen = true;
  s.temperature_degC = 31.25;
  s.table_angle_rad = 0.5;
  return s;
}

/// The registers of the simulated controllers (hal/wire_sim/bench_controllers.hpp) in bench-file form.
std::string controller_registers(const std::string& extra_for_temperature = "") {
  return "[[modbus_device.register]]\nname = \"temperature\"\naddress = 0x2000\nkind = \"input\"\ntype = \"i16\"\n"
         "scale = 0.01\nunit = \"degC\"\n" + extra_for_temperature +
         "[[modbus_device.register]]\nname = \"table_angle\"\naddress = 0x2002\nkind = \"input\"\ntype = \"f32\"\n"
         "word_order = \"CDAB\"\nunit = \"rad\"\nrange = [-7.0, 7.0]\n"
         "[[modbus_device.register]]\nname = \"setpoint\"\naddress = 0x1000\nkind = \"holding\"\ntype = \"i16\"\n"
         "scale = 0.01\nwritable = true\nmin = 10.0\nmax = 60.0\n";
}

const std::string kRealBench = "[bench]\nname = \"check-bench\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n\n";

std::string tcp_device(const std::string& name, int port, const std::string& extra = "", const std::string& registers = controller_registers()) {
  return "[[modbus_device]]\nname = \"" + name + "\"\nrole = \"thermal\"\nhost = \"127.0.0.1\"\nport = " + std::to_string(port) +
         "\nresponse_timeout_s = 0.3\npoll_interval_ms = 50\n" + extra + registers;
}

std::string rtu_device(const std::string& name, const std::string& port, int unit, const std::string& extra = "") {
  return "[[modbus_device]]\nname = \"" + name + "\"\nrole = \"table\"\ntransport = \"rtu\"\nserial_port = \"" + port +
         "\"\nbaud = 115200\nunit_id = " + std::to_string(unit) + "\nresponse_timeout_s = 0.3\npoll_interval_ms = 50\n" + extra +
         controller_registers();
}

std::string can_device(const std::string& extra = "") {
  return "[[can_device]]\nname = \"adc\"\ninterface = \"can0\"\nbitrate = 1000000\nfd = true\ndbitrate = 5000000\n" + extra +
         "[[can_device.signal]]\nname = \"acc1\"\nid = 0x101\nbit_length = 24\nsigned = true\n";
}

std::string gpio_device(const std::string& extra = "") {
  return "[[gpiod_encoder]]\nname = \"table_encoder\"\nchip = \"gpiochip0\"\nline_a = 5\nline_b = 6\nkind = \"rotary\"\n"
         "resolution = 1e-6\n" + extra;
}

/// 1-based line of the first line of `text` that starts with `prefix` at or after line `from`.
std::size_t line_of(const std::string& text, const std::string& prefix, std::size_t from = 1) {
  std::istringstream in(text);
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n)
    if (n >= from && line.rfind(prefix, 0) == 0) return n;
  return 0;
}

struct CheckRun {
  int status;
  std::string out;
};

CheckRun run_check(const fs::path& bench) {
  TempDir tmp;
  DaqdProcess check({"--check", "--config", bench.string()}, {}, tmp.path / "out.txt");
  CheckRun r{check.wait(60), {}};
  r.out = check.output();
  return r;
}

class DeviceCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    tcp_ = BenchControllerServer::start(0, &why, frozen_controllers());
    ASSERT_NE(tcp_, nullptr) << why;
    rtu_link_ = (dir_.path / "ttyBENCH").string();
    // The serial line is a pseudo-terminal: the tests that use it skip (fail in CI) without one.
    rtu_missing_ = inertia::testing::pseudo_terminals_missing();
    if (rtu_missing_) return;
    rtu_ = BenchControllerServer::start_rtu(rtu_link_, 3, &why, frozen_controllers());
    ASSERT_NE(rtu_, nullptr) << why;
  }
  fs::path write(const std::string& text) {
    text_ = text;
    const fs::path p = dir_.path / "bench.toml";
    std::ofstream(p) << text;
    return p;
  }
  TempDir dir_;
  std::string text_;
  std::unique_ptr<BenchControllerServer> tcp_, rtu_;
  std::string rtu_link_;
  std::optional<std::string> rtu_missing_;   // why no serial line could be made here
};

/// First statement of a test that talks to the RTU controller.
#define REQUIRE_RTU_LINE()                                      \
  do {                                                          \
    if (rtu_missing_) INERTIA_SKIP_OR_FAIL_IN_CI(*rtu_missing_); \
  } while (false)

TEST_F(DeviceCheck, EveryRegisterOfTheSimulatedControllersOverTcpAndRtuIsReadyExitZero) {
  REQUIRE_RTU_LINE();
  const CheckRun r = run_check(write(kRealBench + tcp_device("thermal", tcp_->port()) + rtu_device("table", rtu_link_, 3)));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("DEVICE"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("connect 127.0.0.1:" + std::to_string(tcp_->port())), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("connect " + rtu_link_ + " 115200 8E1"), std::string::npos) << r.out;
  // Each register read alone, its value shown in SI with its unit.
  EXPECT_NE(r.out.find("input 8192 i16 = 31.25 degC"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("input 8194 f32 = 0.5 rad"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1 + 1 + 2 * 4 + 1) << r.out;  // title, head, 8 rows, verdict
  EXPECT_EQ(r.out.find("FAIL"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("every required device is ready"), std::string::npos) << r.out;
  EXPECT_GE(rtu_->server().requests_served(), 3u);
}

TEST_F(DeviceCheck, TheHeartbeatIsWrittenOnceAndItsStopTimeHeldAgainstTheBenchs) {
  // The setpoint (the last of controller_registers()) commanded, with writes enabled, and the
  // controller's watchdog on holding 0x1007.
  const std::string commanded =
      "role = \"thermal_setpoint\"\nmax_rate = 1.0\nsafe = 25.0\n"
      "[[modbus_device.register]]\nname = \"watchdog\"\naddress = 0x1007\nkind = \"holding\"\nwritable = true\nmin = 0\n"
      "max = 65535\nrole = \"heartbeat\"\ntimeout_s = 1.5\nstop_s = 2.0\n";
  const std::string device = tcp_device("thermal", tcp_->port(), "writes_enabled = true\n", controller_registers() + commanded);
  const std::uint16_t before = tcp_->state().heartbeat;
  CheckRun r = run_check(write(kRealBench + device));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("heartbeat watchdog"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("and read back; the controller stops 1.5 s after the daemon's last heartbeat and is at rest 3.5 s after it; "
                       "the bench gives no stop_within_s"),
            std::string::npos)
      << r.out;
  EXPECT_NE(tcp_->state().heartbeat, before) << "written";
  // Within the bench's stop distance, and beyond it.
  const std::string head_ok = "[bench]\nname = \"check-bench\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\nstop_within_s = 4.0\n\n";
  r = run_check(write(head_ok + device));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("within the bench's stop_within_s = 4 s"), std::string::npos) << r.out;
  std::string head_short = head_ok;
  head_short.replace(head_short.find("4.0"), 3, "3.0");
  const std::string text = head_short + device;
  r = run_check(write(text));
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("is at rest 3.5 s after it, more than the bench's stop_within_s = 3 s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bench.toml:" + std::to_string(line_of(text, "name = \"watchdog\"") - 1)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fix: shorten the controller's communication-loss timeout"), std::string::npos) << r.out;
}

TEST_F(DeviceCheck, AbsentInterfaceChipAndSerialPortAreNamedWithTheirLineAndAFix) {
  const std::string missing_port = (dir_.path / "ttyUSB7").string();
  tcp_->stop();  // nobody listens on that port any more
  const std::string text = kRealBench + can_device() + gpio_device() + rtu_device("chamber", missing_port, 1) +
                           tcp_device("shaker", tcp_->port());
  const CheckRun r = run_check(write(text));
  EXPECT_EQ(r.status, 2) << r.out;
  const std::string file = (dir_.path / "bench.toml").string();
  auto at = [&](const std::string& key, std::size_t from) { return "at " + file + ":" + std::to_string(line_of(text, key, from)) + ":"; };
  // CAN: this kernel has no AF_CAN and no can0; either is reported at the interface key.
  EXPECT_NE(r.out.find(at("interface = ", 1)), std::string::npos) << r.out;
  EXPECT_TRUE(r.out.find("no such network interface") != std::string::npos ||
              r.out.find("no SocketCAN") != std::string::npos)
      << r.out;
  EXPECT_TRUE(r.out.find("fix: ip link set can0 up type can bitrate 1000000 dbitrate 5000000 fd on") != std::string::npos ||
              r.out.find("fix: modprobe can_raw") != std::string::npos ||
              r.out.find("fix: plug in the adapter") != std::string::npos)
      << r.out;
  // GPIO: the chip, at the chip key.
  EXPECT_NE(r.out.find(at("chip = ", 1)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("chip gpiochip0"), std::string::npos) << r.out;
  // RTU: the serial port, at serial_port.
  EXPECT_NE(r.out.find(at("serial_port = ", 1)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("serial port " + missing_port), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fix: ls -l /dev/serial/by-id/"), std::string::npos) << r.out;
  // TCP: refused, at host.
  EXPECT_NE(r.out.find(at("host = ", 1)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Connection refused"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("nc -zv 127.0.0.1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("required, not ready: adc, table_encoder, chamber, shaker (exit status 2)"), std::string::npos) << r.out;
}

TEST_F(DeviceCheck, OptionalDevicesAreMarkedAndDoNotFailTheCheck) {
  const std::string text = kRealBench + can_device("optional = true\n") + gpio_device("optional = true\n") +
                           tcp_device("thermal", tcp_->port());
  const CheckRun r = run_check(write(text));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("adc (optional)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("table_encoder (optional)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("optional, not ready: adc, table_encoder (the daemon starts without them, degraded)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("every required device is ready"), std::string::npos) << r.out;
}

TEST_F(DeviceCheck, AValueOutOfRangeAWrongAddressAndAWrongSlaveFailOnTheirRegister) {
  REQUIRE_RTU_LINE();
  const std::string absent_register =
      "[[modbus_device.register]]\nname = \"humidity\"\naddress = 0x3000\nkind = \"input\"\ntype = \"u16\"\n";
  const std::string text = kRealBench +
                           tcp_device("thermal", tcp_->port(), "", controller_registers("range = [40.0, 80.0]\n") + absent_register) +
                           rtu_device("table", rtu_link_, 4);  // the RTU server answers as slave 3
  const CheckRun r = run_check(write(text));
  EXPECT_EQ(r.status, 2) << r.out;
  const std::string file = (dir_.path / "bench.toml").string();
  EXPECT_NE(r.out.find("input 8192 i16 = 31.25 degC: outside [40, 80]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Illegal data address"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("check address 12288 and kind = \"input\""), std::string::npos) << r.out;
  const std::size_t humidity_table = line_of(text, "name = \"humidity\"") - 1;
  EXPECT_NE(r.out.find("at " + file + ":" + std::to_string(humidity_table) + ":"), std::string::npos) << r.out;
  // A wrong slave address on the serial line: no answer, and the fix names the line settings.
  EXPECT_NE(r.out.find("Connection timed out"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("unit_id 4, baud 115200"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("required, not ready: thermal, table (exit status 2)"), std::string::npos) << r.out;
}

TEST_F(DeviceCheck, ASimulatedBenchHasNothingToCheck) {
  const CheckRun r = run_check(source_path("tests/integration/configs/daq-small.toml"));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("nothing to check"), std::string::npos) << r.out;
}

TEST_F(DeviceCheck, ABadBenchFileIsBadInput) {
  const CheckRun r = run_check(write(kRealBench + tcp_device("thermal", tcp_->port(), "", controller_registers() +
                                                   "[[modbus_device.register]]\nname = \"again\"\naddress = 0x2003\n"
                                                   "kind = \"input\"\ntype = \"u16\"\n")));
  EXPECT_EQ(r.status, 2) << r.out;
  EXPECT_NE(r.out.find("overlaps register 'table_angle'"), std::string::npos) << r.out;
}

// ---- the daemon on the same benches ----

TEST_F(DeviceCheck, TheDaemonStartsDegradedWithoutOptionalDevicesAndSaysSo) {
  REQUIRE_RTU_LINE();
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  const std::string text = kRealBench + can_device("optional = true\n") +
                           rtu_device("chamber", (dir_.path / "ttyUSB7").string(), 1, "optional = true\n") +
                           tcp_device("thermal", tcp_->port()) + rtu_device("table", rtu_link_, 3);
  const fs::path bench = write(text);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--duration", "1.5", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("adc: optional device left out, running degraded: " + (dir_.path / "bench.toml").string()), std::string::npos)
      << out;
  EXPECT_NE(out.find("chamber: optional device left out"), std::string::npos) << out;
  EXPECT_NE(out.find("degraded: 2 optional devices absent"), std::string::npos) << out;
  const auto events = read_log_dir(tmp.path / "log");
  // Both controllers were polled (every 50 ms for 1.5 s), over TCP and over the serial line.
  for (const char* channel : {"INERTIA_RAW_THERMAL", "INERTIA_RAW_TABLE"}) {
    const auto blocks = decode_all<sample_block_t>(events, channel);
    std::int64_t rows = 0;
    for (const auto& b : blocks) rows += b.num_samples;
    EXPECT_GE(rows, 10) << channel;
    EXPECT_EQ(sequence_gaps(blocks), 0) << channel;
  }
  const auto statuses = decode_all<daq_status_t>(events, "INERTIA_STATUS");
  ASSERT_FALSE(statuses.empty());
  const auto& faults = statuses.back().faults;
  EXPECT_NE(std::find(faults.begin(), faults.end(), "absent:adc"), faults.end());
  EXPECT_NE(std::find(faults.begin(), faults.end(), "absent:chamber"), faults.end());
}

TEST_F(DeviceCheck, TheDaemonNamesARequiredDeviceThatIsNotThereWithFileLineAndFix) {
  const std::string text = kRealBench + tcp_device("thermal", tcp_->port()) + gpio_device();
  const fs::path bench = write(text);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--duration", "1", "--lcm-url", private_lcm_url()}, {}, tmp.path / "stderr.txt");
  EXPECT_EQ(daqd.wait(30), 2);
  const std::string out = daqd.output();
  const std::string where = bench.string() + ":" + std::to_string(line_of(text, "chip = ")) + ":8: device 'table_encoder' (GPIO) chip gpiochip0";
  EXPECT_NE(out.find(where), std::string::npos) << out;
  EXPECT_NE(out.find("  fix: "), std::string::npos) << out;
}

TEST_F(DeviceCheck, WhatOnlyTheSimulatorDoesIsRefusedOnARealBenchNotIgnored) {
  const fs::path bench = write(kRealBench + tcp_device("thermal", tcp_->port()));
  for (const std::vector<std::string>& extra : {std::vector<std::string>{"--fast"}, std::vector<std::string>{"--fault", "stuck@1+1"}}) {
    TempDir tmp;
    std::vector<std::string> args{"--config", bench.string(), "--duration", "1", "--lcm-url", private_lcm_url()};
    args.insert(args.end(), extra.begin(), extra.end());
    DaqdProcess daqd(args, {}, tmp.path / "stderr.txt");
    EXPECT_EQ(daqd.wait(30), 2) << extra[0];
    EXPECT_NE(daqd.output().find("option " + extra[0] + ": bench"), std::string::npos) << daqd.output();
  }
}

}  // namespace
}  // namespace inertia::daq::testing
