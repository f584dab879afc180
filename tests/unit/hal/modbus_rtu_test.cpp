// Modbus RTU: ModbusController over a real serial line, the slave side of a pseudo-terminal pair,
// against the simulated bench controllers served by a libmodbus RTU server on the master side
// (hal/wire_sim/modbus_tcp_server.hpp, rtu_link). The client opens the tty by a symbolic link,
// as a bench opens /dev/serial/by-id/...; the same timeouts and recovery as the TCP path.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "hal/modbus/modbus_controller.hpp"
#include "hal/wire_sim/bench_controllers.hpp"
#include "tests/support/pseudo_terminal.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia::hal::modbus {
namespace {

using wire_sim::BenchControllerServer;
using wire_sim::BenchControllerState;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

class RtuModbus : public ::testing::Test {
 protected:
  void SetUp() override { INERTIA_REQUIRE_PSEUDO_TERMINALS(); }
  void start(int slave_id = 5, const BenchControllerState& initial = frozen()) {
    link_ = (dir_.path / "ttyBENCH").string();
    std::string why;
    sim_ = BenchControllerServer::start_rtu(link_, slave_id, &why, initial);
    ASSERT_NE(sim_, nullptr) << why;
    config_.serial.device = link_;
    config_.serial.baud = 19200;
    config_.serial.parity = 'E';
    config_.unit_id = slave_id;
    config_.map = wire_sim::bench_controller_register_map();
    config_.response_timeout_s = 0.2;
    config_.reconnect_initial_s = 0.05;
    config_.reconnect_max_s = 0.4;
    config_.timeouts_before_reconnect = 2;
  }
  static BenchControllerState frozen() {
    BenchControllerState s;
    s.frozen = true;
    s.temperature_degC = 31.25;
    s.table_angle_rad = 1.2345678;
    s.table_rate_rad_s = -0.75;
    s.shaker_frequency_hz = 123.456;
    s.table_turns = -3;
    return s;
  }
  std::unique_ptr<ModbusController> connect() {
    std::string why;
    auto c = ModbusController::connect(config_, &why);
    EXPECT_NE(c, nullptr) << why;
    return c;
  }
  static bool all_valid(std::span<const PolledValue> values) {
    for (const PolledValue& v : values)
      if (!v.valid) return false;
    return true;
  }
  static double value(ModbusController& c, std::string_view name) {
    const int i = c.config().map.find(name);
    return c.values()[static_cast<std::size_t>(i)].value;
  }
  /// Polls until every value is valid or `limit` passes; whether it came back.
  static bool recovers(ModbusController& c, std::chrono::milliseconds limit) {
    const auto deadline = Clock::now() + limit;
    while (Clock::now() < deadline) {
      if (all_valid(c.poll())) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }

  testing::TempDir dir_{"inertia-rtu"};
  std::string link_;
  std::unique_ptr<BenchControllerServer> sim_;
  ModbusConfig config_;
};

TEST_F(RtuModbus, PollReadsEveryRegisterOverTheSerialLine) {
  start();
  auto c = connect();
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(config_.endpoint(), link_ + " 19200 8E1");
  ASSERT_TRUE(all_valid(c->poll()));
  EXPECT_DOUBLE_EQ(value(*c, "temperature"), 31.25);
  EXPECT_DOUBLE_EQ(value(*c, "table_angle"), static_cast<double>(1.2345678f));  // CDAB
  EXPECT_DOUBLE_EQ(value(*c, "table_rate"), -0.75);                              // BADC
  EXPECT_NEAR(value(*c, "shaker_frequency"), 123.456, 1e-9);                     // uint32 DCBA
  EXPECT_DOUBLE_EQ(value(*c, "table_turns"), -3.0);
  EXPECT_EQ(c->link().health().errors, 0u);
  EXPECT_EQ(c->link().health().requests, 2u);  // the same grouping as over TCP
  EXPECT_EQ(sim_->server().requests_served(), 2u);
}

TEST_F(RtuModbus, SetpointWritesCrossTheLineClamped) {
  start();
  config_.writes_enabled = true;
  auto c = connect();
  ASSERT_NE(c, nullptr);
  const WriteResult r = c->write("temperature_setpoint", 80.0);
  EXPECT_EQ(r.status, WriteStatus::Written);
  EXPECT_TRUE(r.clamped);
  EXPECT_DOUBLE_EQ(r.written, 60.0);
  c->poll();
  EXPECT_DOUBLE_EQ(value(*c, "temperature_setpoint"), 60.0);
}

TEST_F(RtuModbus, AnotherSlaveAddressIsNeverAnsweredSoItTimesOut) {
  // On a shared RS-485 line a slave ignores frames for other addresses: a wrong unit_id shows as
  // timeouts, never as someone else's answer, and a poll is bounded by the response timeout.
  start(5);
  config_.unit_id = 6;
  auto c = connect();  // opening a serial port needs no answer
  ASSERT_NE(c, nullptr);
  const auto t0 = Clock::now();
  EXPECT_FALSE(all_valid(c->poll()));
  EXPECT_LT(Clock::now() - t0, 1500ms);
  EXPECT_GE(c->link().health().timeouts, 1u);
  EXPECT_EQ(c->link().health().last_errno, ETIMEDOUT);
  EXPECT_EQ(sim_->server().requests_served(), 0u);
}

TEST_F(RtuModbus, SilentControllerTimeoutsReopenThePortAndRecover) {
  start();
  auto c = connect();
  ASSERT_NE(c, nullptr);
  ASSERT_TRUE(all_valid(c->poll()));
  sim_->set_silent(true);
  EXPECT_FALSE(all_valid(c->poll()));
  EXPECT_GE(c->link().health().timeouts, 1u);
  c->poll();  // a second timeout in a row closes the port (timeouts_before_reconnect = 2)
  EXPECT_GE(c->link().health().disconnects, 1u);
  EXPECT_FALSE(c->link().connected());
  sim_->set_silent(false);
  EXPECT_TRUE(recovers(*c, 4000ms));
  EXPECT_TRUE(c->link().connected());
  EXPECT_GE(c->link().health().reconnects, 1u);
}

TEST_F(RtuModbus, AdapterUnpluggedThenPluggedBackBehindTheSameNameRecovers) {
  start();
  auto c = connect();
  ASSERT_NE(c, nullptr);
  ASSERT_TRUE(all_valid(c->poll()));
  sim_->stop();  // the pty closes: the descriptor the client holds hangs up, the device file goes
  const auto down_until = Clock::now() + 500ms;
  int polls = 0;
  while (Clock::now() < down_until) {
    const auto t0 = Clock::now();
    EXPECT_FALSE(all_valid(c->poll()));
    EXPECT_LT(Clock::now() - t0, 1500ms);  // never stuck inside libmodbus
    ++polls;
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_FALSE(c->link().connected());
  EXPECT_GE(c->link().health().disconnects, 1u);
  EXPECT_LT(c->link().health().reconnect_attempts, static_cast<std::uint64_t>(polls));  // backed off
  std::string why;
  ASSERT_TRUE(sim_->restart(&why)) << why;  // plugged back: a new tty behind the same link
  EXPECT_TRUE(recovers(*c, 4000ms));
  EXPECT_GE(c->link().health().reconnects, 1u);
}

/// The tests that open no serial line run without pseudo-terminals.
class RtuModbusWithoutLine : public RtuModbus {
 protected:
  void SetUp() override {}
};

TEST_F(RtuModbusWithoutLine, ConnectNamesAMissingSerialPort) {
  config_.serial.device = (dir_.path / "ttyUSB9").string();
  config_.map = wire_sim::bench_controller_register_map();
  std::string why;
  EXPECT_EQ(ModbusController::connect(config_, &why), nullptr);
  EXPECT_NE(why.find("ttyUSB9 19200 8E1"), std::string::npos) << why;
  EXPECT_NE(why.find("No such file or directory"), std::string::npos) << why;
  config_.serial.device = "/dev/null";  // not a tty: libmodbus' tcgetattr refuses it
  EXPECT_EQ(ModbusController::connect(config_, &why), nullptr);
  config_.serial.device = (dir_.path / "ttyUSB9").string();
  config_.unit_id = 0;  // broadcast: never answered on a serial line
  EXPECT_EQ(ModbusController::connect(config_, &why), nullptr);
  EXPECT_NE(why.find("outside 1..247"), std::string::npos) << why;
}

}  // namespace
}  // namespace inertia::hal::modbus
