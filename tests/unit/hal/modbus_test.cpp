// Modbus: register words <-> values, then ModbusController against the simulated bench
// controllers served by a real libmodbus TCP server on 127.0.0.1.
#include <chrono>
#include <time.h>

#include <cmath>
#include <functional>
#include <limits>
#include <thread>

#include <gtest/gtest.h>

#include "hal/modbus/modbus_controller.hpp"
#include "hal/wire_sim/bench_controllers.hpp"

namespace inertia::hal::modbus {
namespace {

using wire_sim::BenchControllerServer;
using wire_sim::BenchControllerState;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

RegisterSpec spec(DataType type, WordOrder order, double scale = 1.0, double offset = 0.0) {
  RegisterSpec s;
  s.name = "x";
  s.type = type;
  s.order = order;
  s.scale = scale;
  s.offset = offset;
  return s;
}

TEST(RegisterMap, WordOrdersOfA32BitValue) {
  // pi as float32 is 0x40490FDB: bytes A=40 B=49 C=0F D=DB.
  struct Case { WordOrder order; std::uint16_t w0, w1; };
  for (const Case& c : {Case{WordOrder::ABCD, 0x4049, 0x0FDB}, Case{WordOrder::CDAB, 0x0FDB, 0x4049},
                        Case{WordOrder::BADC, 0x4940, 0xDB0F}, Case{WordOrder::DCBA, 0xDB0F, 0x4940}}) {
    const std::uint16_t words[2] = {c.w0, c.w1};
    EXPECT_FLOAT_EQ(static_cast<float>(decode(spec(DataType::Float32, c.order), words)), 3.14159274f);
    std::uint16_t out[2] = {0, 0};
    encode(spec(DataType::Float32, c.order), 3.14159274, out);
    EXPECT_EQ(out[0], c.w0);
    EXPECT_EQ(out[1], c.w1);
  }
  const std::uint16_t u32[2] = {0x7856, 0x3412};  // 0x12345678 in DCBA
  EXPECT_DOUBLE_EQ(decode(spec(DataType::UInt32, WordOrder::DCBA), u32), 0x12345678);
  const std::uint16_t i32[2] = {0xFFFF, 0xFFFE};  // -2 in ABCD
  EXPECT_DOUBLE_EQ(decode(spec(DataType::Int32, WordOrder::ABCD), i32), -2.0);
  const std::uint16_t i16[1] = {0xFF38};          // -200
  EXPECT_DOUBLE_EQ(decode(spec(DataType::Int16, WordOrder::ABCD, 0.01, 1.0), i16), -2.0 + 1.0);
}

TEST(RegisterMap, EncodeRoundsAndSaturates) {
  std::uint16_t w[2] = {0, 0};
  EXPECT_DOUBLE_EQ(encode(spec(DataType::Int16, WordOrder::ABCD, 0.01), 25.004, w), 25.0);
  EXPECT_EQ(w[0], 2500);
  EXPECT_DOUBLE_EQ(encode(spec(DataType::Int16, WordOrder::ABCD, 0.01), 1000.0, w), 327.67);
  EXPECT_DOUBLE_EQ(encode(spec(DataType::UInt16, WordOrder::ABCD), -5.0, w), 0.0);
  EXPECT_DOUBLE_EQ(encode(spec(DataType::Int32, WordOrder::CDAB), -70000.0, w), -70000.0);
  EXPECT_DOUBLE_EQ(decode(spec(DataType::Int32, WordOrder::CDAB), w), -70000.0);
}

TEST(RegisterMap, ValidationNamesTheRegister) {
  RegisterMap map = wire_sim::bench_controller_register_map();
  std::string why;
  ASSERT_TRUE(map.is_valid(&why)) << why;
  map.registers[3].writable = true;  // temperature: an input register
  EXPECT_FALSE(map.is_valid(&why));
  EXPECT_NE(why.find("'temperature'"), std::string::npos) << why;
  map = wire_sim::bench_controller_register_map();
  map.registers[1].name = "temperature_setpoint";
  EXPECT_FALSE(map.is_valid(&why));
  EXPECT_NE(why.find("twice"), std::string::npos) << why;
}

// A controller sends NaN (or infinity) in a float register for a broken sensor; such a
// word is no reading, never a sample (tests/fuzz/fuzz_modbus_registers checks every word).
TEST(RegisterMap, NonFiniteFloatRegistersAreNoReading) {
  const RegisterSpec f = spec(DataType::Float32, WordOrder::ABCD);
  const std::uint16_t nan_words[2] = {0x7FC0, 0x0000};
  const std::uint16_t inf_words[2] = {0xFF80, 0x0000};
  const std::uint16_t ten_words[2] = {0x4120, 0x0000};
  EXPECT_FALSE(decode_reading(f, nan_words));
  EXPECT_FALSE(decode_reading(f, inf_words));
  EXPECT_EQ(decode_reading(f, ten_words), 10.0);
  // A finite raw value that the scale carries past the double range is no reading either.
  const std::uint16_t big[2] = {0x7F7F, 0xFFFF};   // FLT_MAX
  EXPECT_FALSE(decode_reading(spec(DataType::Float32, WordOrder::ABCD, 1e300), big));
}

class BenchModbus : public ::testing::Test {
 protected:
  void start(const BenchControllerState& initial = {}) {
    std::string why;
    sim_ = BenchControllerServer::start(0, &why, initial);
    ASSERT_NE(sim_, nullptr) << why;
    config_.port = sim_->port();
    config_.map = wire_sim::bench_controller_register_map();
    config_.response_timeout_s = 0.2;
    config_.reconnect_initial_s = 0.05;
    config_.reconnect_max_s = 0.4;
    config_.timeouts_before_reconnect = 2;
  }
  std::unique_ptr<ModbusController> connect() {
    std::string why;
    auto c = ModbusController::connect(config_, &why);
    EXPECT_NE(c, nullptr) << why;
    return c;
  }
  static double value(ModbusController& c, std::string_view name) {
    const int i = c.config().map.find(name);
    EXPECT_GE(i, 0) << name;
    const PolledValue& v = c.values()[static_cast<std::size_t>(i)];
    EXPECT_TRUE(v.valid) << name;
    return v.value;
  }
  static bool all_valid(std::span<const PolledValue> values) {
    for (const PolledValue& v : values)
      if (!v.valid) return false;
    return true;
  }
  std::unique_ptr<BenchControllerServer> sim_;
  ModbusConfig config_;
};

TEST_F(BenchModbus, PollReadsEveryRegisterThroughTheMap) {
  BenchControllerState s;
  s.frozen = true;
  s.temperature_degC = 31.25;
  s.temperature_setpoint_degC = 35.5;
  s.peltier_power_w = -12.3;
  s.table_angle_rad = 1.2345678;
  s.table_rate_rad_s = -0.75;
  s.table_rate_setpoint_rad_s = 0.5;
  s.shaker_status = 0x5;
  s.shaker_frequency_hz = 123.456;
  s.table_turns = -3;
  start(s);
  auto c = connect();
  ASSERT_NE(c, nullptr);
  const auto values = c->poll();
  ASSERT_EQ(values.size(), 10u);
  EXPECT_TRUE(all_valid(values));
  EXPECT_EQ(values[3].name, "temperature");
  EXPECT_DOUBLE_EQ(value(*c, "temperature"), 31.25);
  EXPECT_DOUBLE_EQ(value(*c, "temperature_setpoint"), 35.5);
  EXPECT_NEAR(value(*c, "peltier_power"), -12.3, 1e-12);
  EXPECT_DOUBLE_EQ(value(*c, "table_angle"), static_cast<double>(1.2345678f));   // CDAB
  EXPECT_DOUBLE_EQ(value(*c, "table_rate"), -0.75);                               // BADC
  EXPECT_DOUBLE_EQ(value(*c, "table_rate_setpoint"), 0.5);                        // ABCD
  EXPECT_DOUBLE_EQ(value(*c, "shaker_status"), 5.0);
  EXPECT_NEAR(value(*c, "shaker_frequency"), 123.456, 1e-9);                      // uint32 DCBA
  EXPECT_DOUBLE_EQ(value(*c, "table_turns"), -3.0);                               // int32 ABCD
  EXPECT_EQ(c->link().health().errors, 0u);
  // Contiguous registers share a request: 0x1000..0x1003 and 0x2000..0x200A.
  EXPECT_EQ(c->link().health().requests, 2u);
}

TEST_F(BenchModbus, NanAndInfiniteRegistersArePolledAsInvalidOthersStayValid) {
  BenchControllerState s;
  s.frozen = true;
  s.temperature_degC = 31.25;
  s.table_angle_rad = std::numeric_limits<double>::quiet_NaN();
  s.table_rate_rad_s = std::numeric_limits<double>::infinity();
  start(s);
  auto c = connect();
  ASSERT_NE(c, nullptr);
  const auto values = c->poll();
  const auto at = [&](std::string_view name) { return values[static_cast<std::size_t>(c->config().map.find(name))]; };
  EXPECT_FALSE(at("table_angle").valid);
  EXPECT_FALSE(at("table_rate").valid);
  EXPECT_TRUE(at("temperature").valid);
  EXPECT_DOUBLE_EQ(at("temperature").value, 31.25);
  EXPECT_EQ(c->link().health().errors, 0u);   // the link is fine: the values are what is missing
}

TEST_F(BenchModbus, AReadingOutsideItsRangeIsInvalidKeptAndCountedAtEveryPoll) {
  // A broken thermocouple reads 850 degC: the fixture's sensor range is -40..150. Checked at every
  // poll (not only by inertia-daqd --check); the request itself succeeded.
  BenchControllerState s;
  s.frozen = true;
  s.temperature_degC = 85.0;
  s.table_rate_rad_s = -0.75;
  start(s);
  const int t = config_.map.find("temperature");
  ASSERT_GE(t, 0);
  config_.map.registers[static_cast<std::size_t>(t)].range_min = -40.0;
  config_.map.registers[static_cast<std::size_t>(t)].range_max = 80.0;
  auto c = connect();
  ASSERT_NE(c, nullptr);
  for (int poll = 0; poll < 3; ++poll) {
    const PolledValue& v = c->poll()[static_cast<std::size_t>(t)];
    EXPECT_FALSE(v.valid);
    EXPECT_TRUE(v.out_of_range);
    EXPECT_DOUBLE_EQ(v.value, 85.0) << "kept as read, for the log";
  }
  EXPECT_EQ(c->range_faults(), 3u);
  EXPECT_DOUBLE_EQ(value(*c, "table_rate"), -0.75) << "the others stay valid";
  EXPECT_EQ(c->link().health().errors, 0u) << "an implausible reading is no link error";
}

TEST_F(BenchModbus, SetpointWritesAreOffUnlessEnabledThenClamped) {
  BenchControllerState s;
  s.frozen = true;
  start(s);
  auto c = connect();
  ASSERT_NE(c, nullptr);
  WriteResult r = c->write("temperature_setpoint", 40.0);
  EXPECT_EQ(r.status, WriteStatus::Disabled);
  EXPECT_DOUBLE_EQ(sim_->state().temperature_setpoint_degC, 23.0);

  config_.writes_enabled = true;
  c = connect();
  ASSERT_NE(c, nullptr);
  r = c->write("temperature_setpoint", 80.0);
  EXPECT_EQ(r.status, WriteStatus::Written);
  EXPECT_TRUE(r.clamped);
  EXPECT_DOUBLE_EQ(r.written, 60.0);
  r = c->write("table_rate_setpoint", -9.0);
  EXPECT_EQ(r.status, WriteStatus::Written);
  EXPECT_DOUBLE_EQ(r.written, -3.5);
  c->poll();
  EXPECT_DOUBLE_EQ(value(*c, "temperature_setpoint"), 60.0);
  EXPECT_DOUBLE_EQ(value(*c, "table_rate_setpoint"), -3.5);
  r = c->write("temperature_setpoint", 25.004);
  EXPECT_FALSE(r.clamped);
  EXPECT_DOUBLE_EQ(r.written, 25.0);  // the register holds 0.01 degC steps
  EXPECT_EQ(c->write("temperature", 30.0).status, WriteStatus::NotWritable);
  EXPECT_EQ(c->write("no_such", 1.0).status, WriteStatus::UnknownRegister);
  EXPECT_EQ(c->write("temperature_setpoint", NAN).status, WriteStatus::NotFinite);
  // The server saw the last accepted write (its tick reads setpoints from the registers).
  const auto deadline = Clock::now() + 3s;
  while (sim_->state().temperature_setpoint_degC != 25.0 && Clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_DOUBLE_EQ(sim_->state().temperature_setpoint_degC, 25.0);
}

TEST_F(BenchModbus, AWriteIsConfirmedByReadingItBackAndAControllerThatDoesNotTakeItIsCaught) {
  namespace r = wire_sim::bench_registers;
  BenchControllerState s;
  s.frozen = true;
  s.ignore_writes = 3u << (r::kTableRateSetpoint - r::kHoldingStart);  // answers, never takes it (both words)
  start(s);
  config_.writes_enabled = true;
  auto c = connect();
  ASSERT_NE(c, nullptr);
  const std::uint64_t before = c->link().health().requests;
  WriteResult w = c->write("temperature_setpoint", 40.0);
  EXPECT_EQ(w.status, WriteStatus::Written);
  EXPECT_DOUBLE_EQ(w.read_back, 40.0);
  EXPECT_EQ(c->link().health().requests - before, 2u) << "the write and the read back";
  w = c->write("table_rate_setpoint", 1.0);
  EXPECT_EQ(w.status, WriteStatus::NotConfirmed);
  EXPECT_DOUBLE_EQ(w.written, 1.0);
  EXPECT_DOUBLE_EQ(w.read_back, 0.0) << "the register still holds the old value";
  EXPECT_DOUBLE_EQ(sim_->state().table_rate_setpoint_rad_s, 0.0);
  EXPECT_STREQ(to_string(w.status), "not confirmed: the register read back holds another value");
}

TEST_F(BenchModbus, ARateLimitedSetpointMovesInStepsAndAnImmediateWriteAtOnce) {
  BenchControllerState s;
  s.frozen = true;
  start(s);
  config_.writes_enabled = true;
  const double max_rate = 2.0;  // rad/s per second
  config_.map.registers[1].max_rate = max_rate;
  auto c = connect();
  ASSERT_NE(c, nullptr);
  // First write: a tenth of a second's worth from what the device holds (0).
  auto t_prev = Clock::now();
  WriteResult w = c->write("table_rate_setpoint", 1.0);
  ASSERT_EQ(w.status, WriteStatus::Written);
  EXPECT_TRUE(w.rate_limited);
  EXPECT_NEAR(w.written, max_rate * ModbusController::kMaxRampStepS, 1e-6);
  double prev = w.written;
  int steps = 1;
  const auto t0 = t_prev;
  while (w.rate_limited && steps < 100) {
    std::this_thread::sleep_for(30ms);
    const auto t = Clock::now();
    w = c->write("table_rate_setpoint", 1.0);
    ASSERT_EQ(w.status, WriteStatus::Written);
    const double dt = std::min(std::chrono::duration<double>(t - t_prev).count() + 0.002, ModbusController::kMaxRampStepS);
    EXPECT_LE(w.written - prev, max_rate * dt + 1e-6) << "step " << steps;
    EXPECT_GT(w.written, prev);
    prev = w.written;
    t_prev = t;
    ++steps;
  }
  EXPECT_FALSE(w.rate_limited);
  EXPECT_DOUBLE_EQ(w.written, 1.0);
  EXPECT_GE(std::chrono::duration<double>(Clock::now() - t0).count(), (1.0 - 0.2) / max_rate - 0.01);
  EXPECT_GE(steps, 5);
  // The safe value goes out in one write, whatever the rate limit.
  w = c->write("table_rate_setpoint", 0.0, Ramp::Immediate);
  EXPECT_EQ(w.status, WriteStatus::Written);
  EXPECT_FALSE(w.rate_limited);
  EXPECT_DOUBLE_EQ(w.written, 0.0);
}

TEST_F(BenchModbus, SimulatedControllersTakeSetpointsMoveAtTheirRateAndReportSettled) {
  namespace r = wire_sim::bench_registers;
  BenchControllerState s;
  s.thermal_time_constant_s = 0.2;
  s.table_max_accel_rad_s2 = 4.0;
  s.table_max_rate_rad_s = 2.0;
  start(s);
  config_.writes_enabled = true;
  const double inf = std::numeric_limits<double>::infinity();
  auto add = [&](const char* name, int address, RegisterKind kind, DataType type, bool writable, double lo, double hi) {
    config_.map.registers.push_back({name, address, kind, type, WordOrder::ABCD, 1.0, 0.0, writable, lo, hi, inf});
  };
  add("table_angle_setpoint", r::kTableAngleSetpoint, RegisterKind::Holding, DataType::Float32, true, -20.0, 20.0);
  add("shaker_profile", r::kShakerProfile, RegisterKind::Holding, DataType::UInt16, true, 0.0, 8.0);
  add("table_status", r::kTableStatus, RegisterKind::Input, DataType::UInt16, false, -inf, inf);
  add("thermal_status", r::kThermalStatus, RegisterKind::Input, DataType::UInt16, false, -inf, inf);
  add("table_position", r::kTablePosition, RegisterKind::Input, DataType::Float32, false, -inf, inf);
  auto c = connect();
  ASSERT_NE(c, nullptr);
  auto poll_until = [&](const std::function<bool()>& done, double timeout_s) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < deadline) {
      c->poll();
      if (done()) return true;
      std::this_thread::sleep_for(10ms);
    }
    return false;
  };
  auto bits = [&](const char* name) { return static_cast<unsigned>(value(*c, name)); };

  // Position mode: to 1.5 rad at no more than 2 rad/s, then "in position".
  timespec t0{};
  ::clock_gettime(CLOCK_MONOTONIC, &t0);
  ASSERT_EQ(c->write("table_angle_setpoint", 1.5).status, WriteStatus::Written);
  EXPECT_GE(sim_->state().written_ns[r::kTableAngleSetpoint - r::kHoldingStart], t0.tv_sec * 1'000'000'000LL + t0.tv_nsec);
  double fastest = 0.0;
  ASSERT_TRUE(poll_until([&] {
    fastest = std::max(fastest, std::abs(value(*c, "table_rate")));
    return (bits("table_status") & r::kTableInPosition) != 0;
  }, 5.0));
  EXPECT_NEAR(value(*c, "table_position"), 1.5, r::kTablePositionTolerance);
  EXPECT_LE(fastest, 2.0 + 1e-6);
  EXPECT_GT(fastest, 1.0);
  // Rate mode: the rate setpoint takes over; "at rate" once there.
  ASSERT_EQ(c->write("table_rate_setpoint", 1.0).status, WriteStatus::Written);
  ASSERT_TRUE(poll_until([&] { return (bits("table_status") & r::kTableAtRate) != 0; }, 5.0));
  EXPECT_NEAR(value(*c, "table_rate"), 1.0, r::kTableRateTolerance);
  EXPECT_EQ(bits("table_status") & r::kTableInPosition, 0u);
  // Shaker: a profile, then enable: running after its start time, at the profile's frequency.
  ASSERT_EQ(c->write("shaker_profile", 3.0).status, WriteStatus::Written);
  ASSERT_EQ(c->write("shaker_enable", 1.0).status, WriteStatus::Written);
  ASSERT_TRUE(poll_until([&] { return (bits("shaker_status") & r::kShakerRunning) != 0; }, 3.0));
  EXPECT_DOUBLE_EQ(value(*c, "shaker_frequency"), 30.0);
  ASSERT_EQ(c->write("shaker_enable", 0.0).status, WriteStatus::Written);
  ASSERT_TRUE(poll_until([&] { return (bits("shaker_status") & r::kShakerRunning) == 0; }, 3.0));
  // Thermal: at setpoint once within its tolerance.
  ASSERT_EQ(c->write("temperature_setpoint", 30.0).status, WriteStatus::Written);
  ASSERT_TRUE(poll_until([&] { return (bits("thermal_status") & r::kThermalAtSetpoint) != 0; }, 5.0));
  EXPECT_NEAR(value(*c, "temperature"), 30.0, r::kThermalTolerance + 0.01);
}

TEST_F(BenchModbus, ThermalControllerFollowsAWrittenSetpoint) {
  BenchControllerState s;
  s.thermal_time_constant_s = 0.2;
  start(s);
  config_.writes_enabled = true;
  auto c = connect();
  ASSERT_NE(c, nullptr);
  ASSERT_EQ(c->write("temperature_setpoint", 40.0).status, WriteStatus::Written);
  bool heating_seen = false;
  double t = 0.0;
  const auto deadline = Clock::now() + 4s;
  while (Clock::now() < deadline) {
    c->poll();
    t = value(*c, "temperature");
    if (value(*c, "peltier_power") > 0.0) heating_seen = true;
    if (t > 39.5) break;
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_GT(t, 39.5);
  EXPECT_TRUE(heating_seen);
}

TEST_F(BenchModbus, LinkReportsAServerOutageAndReconnectsByItself) {
  start();
  auto c = connect();
  ASSERT_NE(c, nullptr);
  ASSERT_TRUE(all_valid(c->poll()));
  sim_->stop();
  // Down: polls fail fast and say so; the link drops and retries with back-off.
  const auto down_until = Clock::now() + 400ms;
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
  EXPECT_FALSE(c->link().health().last_error.empty());
  const std::uint64_t attempts_while_down = c->link().health().reconnect_attempts;
  EXPECT_GE(attempts_while_down, 1u);
  EXPECT_LT(attempts_while_down, static_cast<std::uint64_t>(polls));  // backed off, not every poll

  std::string why;
  ASSERT_TRUE(sim_->restart(&why)) << why;
  bool back = false;
  const auto deadline = Clock::now() + 4s;
  while (!back && Clock::now() < deadline) {
    back = all_valid(c->poll());
    if (!back) std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(back);
  EXPECT_TRUE(c->link().connected());
  EXPECT_GE(c->link().health().reconnects, 1u);
}

TEST_F(BenchModbus, SilentServerTimeoutsAreCountedAndRecovered) {
  start();
  auto c = connect();
  ASSERT_NE(c, nullptr);
  ASSERT_TRUE(all_valid(c->poll()));
  sim_->set_silent(true);
  EXPECT_FALSE(all_valid(c->poll()));
  EXPECT_GE(c->link().health().timeouts, 1u);
  EXPECT_EQ(c->link().health().last_errno, ETIMEDOUT);
  c->poll();  // a second timeout in a row drops the link (timeouts_before_reconnect = 2)
  EXPECT_GE(c->link().health().disconnects, 1u);
  sim_->set_silent(false);
  bool back = false;
  const auto deadline = Clock::now() + 4s;
  while (!back && Clock::now() < deadline) {
    back = all_valid(c->poll());
    if (!back) std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(back);
}

TEST_F(BenchModbus, DeviceExceptionsDoNotDropTheLink) {
  start();
  config_.map.registers.push_back({"absent", 0x3000, RegisterKind::Input, DataType::UInt16, WordOrder::ABCD, 1.0,
                                   0.0, false, 0.0, 0.0});
  auto c = connect();
  ASSERT_NE(c, nullptr);
  const auto values = c->poll();
  EXPECT_FALSE(values.back().valid);
  EXPECT_TRUE(values.front().valid);
  EXPECT_EQ(c->link().health().exceptions, 1u);
  EXPECT_EQ(c->link().health().last_error, "Illegal data address");
  EXPECT_TRUE(c->link().connected());
}

TEST_F(BenchModbus, ConnectFailsWithAReasonWhenNoServerListens) {
  start();
  sim_->stop();
  std::string why;
  EXPECT_EQ(ModbusController::connect(config_, &why), nullptr);
  EXPECT_NE(why.find("Connection refused"), std::string::npos) << why;
  config_.host = "localhost";
  EXPECT_EQ(ModbusController::connect(config_, &why), nullptr);
  EXPECT_NE(why.find("IPv4"), std::string::npos) << why;
}

}  // namespace
}  // namespace inertia::hal::modbus
