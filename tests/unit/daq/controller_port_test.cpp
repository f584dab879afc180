// The executive's way to a controller, against the simulated controllers behind a real Modbus
// TCP server on loopback, the port served by this thread as the device's polling thread serves
// it: the safe state is held (written, read back, retried, written again after a reconnect) and
// refuses the plan's commands while it is; the heartbeat counts through its range while the
// daemon's life sign is alive, and stops when it lapses.
#include "daq/controller_port.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "hal/device.hpp"
#include "hal/wire_sim/bench_controllers.hpp"

namespace inertia::daq {
namespace {

using hal::wire_sim::BenchControllerServer;
using hal::wire_sim::BenchControllerState;
namespace reg = hal::wire_sim::bench_registers;
using namespace std::chrono_literals;

class Port : public ::testing::Test {
 protected:
  void SetUp() override {
    BenchControllerState s;
    s.frozen = true;
    s.table_rate_setpoint_rad_s = 1.5;
    s.temperature_setpoint_degC = 40.0;
    std::string why;
    server_ = BenchControllerServer::start(0, &why, s);
    ASSERT_NE(server_, nullptr) << why;
    hal::modbus::ModbusConfig c;
    c.name = "bench";
    c.port = server_->port();
    c.writes_enabled = true;
    c.response_timeout_s = 0.1;
    c.reconnect_initial_s = 0.05;
    c.reconnect_max_s = 5.0;   // a long back-off: the safe state must not wait for it
    c.map = hal::wire_sim::bench_controller_register_map();
    c.map.registers.push_back({"heartbeat", reg::kHeartbeat, hal::modbus::RegisterKind::Holding, hal::modbus::DataType::UInt16,
                               hal::modbus::WordOrder::ABCD, 1.0, 0.0, true, 0.0, 3.0});
    controller_ = hal::modbus::ModbusController::connect(c, &why);
    ASSERT_NE(controller_, nullptr) << why;
    rate_ = static_cast<std::size_t>(c.map.find("table_rate_setpoint"));
    temperature_ = static_cast<std::size_t>(c.map.find("temperature_setpoint"));
    heartbeat_ = static_cast<std::size_t>(c.map.find("heartbeat"));
  }
  /// Serves the port as the polling thread does, until `done` or `limit`.
  template <class Done>
  bool serve_until(ControllerPort& port, Done done, std::chrono::milliseconds limit = 3000ms) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      port.serve(*controller_);
      if (done()) return true;
      port.wait_until(hal::monotonic_now_ns() + 5'000'000);
    }
    return false;
  }
  std::unique_ptr<BenchControllerServer> server_;
  std::unique_ptr<hal::modbus::ModbusController> controller_;
  std::size_t rate_ = 0, temperature_ = 0, heartbeat_ = 0;
};

TEST_F(Port, TheHeldSafeStateIsWrittenReadBackAndRefusesThePlansCommands) {
  ControllerPort port("bench", {{rate_, 0.0}, {temperature_, 25.0}});
  port.hold_safe_state();
  ASSERT_TRUE(serve_until(port, [&] { return port.safe_state().confirmed; }));
  const ControllerPort::SafeState st = port.safe_state();
  EXPECT_TRUE(st.held);
  EXPECT_EQ(st.attempts, 1);
  EXPECT_EQ(st.written, (std::vector<std::string>{"table_rate_setpoint = 0", "temperature_setpoint = 25"}));
  EXPECT_TRUE(st.failures.empty());
  EXPECT_DOUBLE_EQ(server_->state().table_rate_setpoint_rad_s, 0.0);
  EXPECT_DOUBLE_EQ(server_->state().temperature_setpoint_degC, 25.0);
  // While held, a command is refused, never sent.
  const std::uint64_t ticket = port.post(rate_, 1.0);
  ASSERT_TRUE(serve_until(port, [&] { return false; }, 30ms) || true);
  const auto refused = port.take_outcome(ticket);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->result.status, hal::modbus::WriteStatus::Disabled);
  EXPECT_DOUBLE_EQ(server_->state().table_rate_setpoint_rad_s, 0.0);
  // Released (armed), it goes out.
  port.release_safe_state();
  const std::uint64_t go = port.post(rate_, 1.0);
  std::optional<ControllerPort::Outcome> done;
  ASSERT_TRUE(serve_until(port, [&] { return (done = port.take_outcome(go)).has_value(); }));
  EXPECT_EQ(done->result.status, hal::modbus::WriteStatus::Written);
}

TEST_F(Port, ASafeValueTheControllerDoesNotTakeIsRetriedUntilItDoes) {
  server_->update([](BenchControllerState& s) { s.ignore_writes = 1u << (reg::kTemperatureSetpoint - reg::kHoldingStart); });
  ControllerPort port("bench", {{rate_, 0.0}, {temperature_, 25.0}});
  port.hold_safe_state();
  // Rounds every kSafeRetryS: after three of them, still not confirmed, the failure named.
  EXPECT_FALSE(serve_until(port, [&] { return port.safe_state().confirmed; }, std::chrono::milliseconds(static_cast<int>(2.5 * ControllerPort::kSafeRetryS * 1000))));
  ControllerPort::SafeState st = port.safe_state();
  EXPECT_GE(st.attempts, 3);
  EXPECT_LE(st.attempts, 4);
  EXPECT_EQ(st.written, (std::vector<std::string>{"table_rate_setpoint = 0"}));   // the one that went through, once
  ASSERT_EQ(st.failures.size(), 1u);
  EXPECT_EQ(st.failures[0], "temperature_setpoint: not confirmed: the register read back holds another value (reads 40)");
  server_->update([](BenchControllerState& s) { s.ignore_writes = 0; });
  ASSERT_TRUE(serve_until(port, [&] { return port.safe_state().confirmed; }));
  EXPECT_DOUBLE_EQ(server_->state().temperature_setpoint_degC, 25.0);
}

TEST_F(Port, AfterTheLinkReturnsTheSafeStateIsWrittenAtOnceAndAgainAfterAReconnect) {
  ControllerPort port("bench", {{rate_, 0.0}});
  server_->stop();
  port.hold_safe_state();
  EXPECT_FALSE(serve_until(port, [&] { return port.safe_state().confirmed; }, 500ms));
  EXPECT_FALSE(port.safe_state().failures.empty());
  std::string why;
  ASSERT_TRUE(server_->restart(&why)) << why;
  const auto back = std::chrono::steady_clock::now();
  // Not after the link's 5 s back-off: within a retry or two.
  ASSERT_TRUE(serve_until(port, [&] { return port.safe_state().confirmed; }, 2000ms));
  EXPECT_LT(std::chrono::steady_clock::now() - back, std::chrono::milliseconds(static_cast<int>(3 * ControllerPort::kSafeRetryS * 1000)));
  // The controller came back (restarted, say) with its rate set again: a reconnect writes the
  // safe state once more.
  server_->update([](BenchControllerState& s) { s.table_rate_setpoint_rad_s = 2.0; });
  server_->stop();
  (void)controller_->poll();   // the link drops
  ASSERT_TRUE(server_->restart(&why)) << why;
  ASSERT_TRUE(serve_until(port, [&] {
    (void)controller_->poll();
    return server_->state().table_rate_setpoint_rad_s == 0.0;
  }, 4000ms));
  EXPECT_TRUE(port.safe_state().confirmed);
}

TEST_F(Port, TheHeartbeatCountsThroughItsRangeWhileTheDaemonIsAliveAndStopsWhenItsLifeSignLapses) {
  auto life = std::make_shared<LifeSign>();
  life->renew(hal::monotonic_now_ns() + 10'000'000'000);
  ControllerPort port("bench", {}, ControllerPort::Heartbeat{heartbeat_, 10'000'000, 0.0, 3.0, 1.0}, life);
  std::vector<std::uint16_t> seen;
  ASSERT_TRUE(serve_until(port, [&] {
    const std::uint16_t v = server_->state().heartbeat;
    if (port.heartbeat().written > seen.size()) seen.push_back(v);
    return seen.size() >= 6;
  }));
  EXPECT_EQ(seen, (std::vector<std::uint16_t>{0, 1, 2, 3, 0, 1}));
  const std::uint64_t written = port.heartbeat().written;
  life->renew(0);   // the supervisor stopped renewing: the daemon is hung
  EXPECT_FALSE(serve_until(port, [&] { return port.heartbeat().written != written; }, 200ms));
  EXPECT_EQ(port.heartbeat().failed, 0u);
}

}  // namespace
}  // namespace inertia::daq
