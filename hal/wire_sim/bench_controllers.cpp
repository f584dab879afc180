#include "hal/wire_sim/bench_controllers.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace inertia::hal::wire_sim {
namespace {

namespace r = bench_registers;
using modbus::DataType;
using modbus::RegisterKind;
using modbus::RegisterSpec;
using modbus::WordOrder;

// Bytes A (MSB) .. D of a 32-bit pattern, then placed by the named order: register n holds the
// first two letters (first letter in its high byte), register n+1 the last two.
void put32(std::uint16_t* regs, std::uint32_t v, WordOrder order) {
  const std::uint8_t A = static_cast<std::uint8_t>(v >> 24), B = static_cast<std::uint8_t>(v >> 16),
                     C = static_cast<std::uint8_t>(v >> 8), D = static_cast<std::uint8_t>(v);
  std::uint8_t seq[4];
  switch (order) {
    case WordOrder::ABCD: seq[0] = A; seq[1] = B; seq[2] = C; seq[3] = D; break;
    case WordOrder::CDAB: seq[0] = C; seq[1] = D; seq[2] = A; seq[3] = B; break;
    case WordOrder::BADC: seq[0] = B; seq[1] = A; seq[2] = D; seq[3] = C; break;
    case WordOrder::DCBA: seq[0] = D; seq[1] = C; seq[2] = B; seq[3] = A; break;
  }
  regs[0] = static_cast<std::uint16_t>((seq[0] << 8) | seq[1]);
  regs[1] = static_cast<std::uint16_t>((seq[2] << 8) | seq[3]);
}
std::uint32_t get32(const std::uint16_t* regs, WordOrder order) {
  const std::uint8_t s0 = static_cast<std::uint8_t>(regs[0] >> 8), s1 = static_cast<std::uint8_t>(regs[0]),
                     s2 = static_cast<std::uint8_t>(regs[1] >> 8), s3 = static_cast<std::uint8_t>(regs[1]);
  std::uint8_t A = 0, B = 0, C = 0, D = 0;
  switch (order) {
    case WordOrder::ABCD: A = s0; B = s1; C = s2; D = s3; break;
    case WordOrder::CDAB: C = s0; D = s1; A = s2; B = s3; break;
    case WordOrder::BADC: B = s0; A = s1; D = s2; C = s3; break;
    case WordOrder::DCBA: D = s0; C = s1; B = s2; A = s3; break;
  }
  return (std::uint32_t{A} << 24) | (std::uint32_t{B} << 16) | (std::uint32_t{C} << 8) | D;
}
std::uint32_t float_bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}
float bits_float(std::uint32_t u) {
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}
std::uint16_t s16(double v) {
  return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::clamp(std::lround(v), -32768L, 32767L)));
}

std::uint16_t* holding(modbus_mapping_t& m, int address) { return &m.tab_registers[address - r::kHoldingStart]; }
std::uint16_t* input(modbus_mapping_t& m, int address) { return &m.tab_input_registers[address - r::kInputStart]; }

}  // namespace

modbus::RegisterMap bench_controller_register_map() {
  const double inf = std::numeric_limits<double>::infinity();
  return modbus::RegisterMap{{
      {"temperature_setpoint", r::kTemperatureSetpoint, RegisterKind::Holding, DataType::Int16, WordOrder::ABCD,
       0.01, 0.0, true, 10.0, 60.0},
      {"table_rate_setpoint", r::kTableRateSetpoint, RegisterKind::Holding, DataType::Float32, WordOrder::ABCD,
       1.0, 0.0, true, -3.5, 3.5},
      {"shaker_enable", r::kShakerEnable, RegisterKind::Holding, DataType::UInt16, WordOrder::ABCD, 1.0, 0.0, true,
       0.0, 1.0},
      {"temperature", r::kTemperature, RegisterKind::Input, DataType::Int16, WordOrder::ABCD, 0.01, 0.0, false,
       -inf, inf},
      {"peltier_power", r::kPeltierPower, RegisterKind::Input, DataType::Int16, WordOrder::ABCD, 0.1, 0.0, false,
       -inf, inf},
      {"table_angle", r::kTableAngle, RegisterKind::Input, DataType::Float32, WordOrder::CDAB, 1.0, 0.0, false,
       -inf, inf},
      {"table_rate", r::kTableRate, RegisterKind::Input, DataType::Float32, WordOrder::BADC, 1.0, 0.0, false,
       -inf, inf},
      {"shaker_status", r::kShakerStatus, RegisterKind::Input, DataType::UInt16, WordOrder::ABCD, 1.0, 0.0, false,
       -inf, inf},
      {"shaker_frequency", r::kShakerFrequency, RegisterKind::Input, DataType::UInt32, WordOrder::DCBA, 0.001, 0.0,
       false, -inf, inf},
      {"table_turns", r::kTableTurns, RegisterKind::Input, DataType::Int32, WordOrder::ABCD, 1.0, 0.0, false, -inf,
       inf},
  }};
}

std::unique_ptr<BenchControllerServer> BenchControllerServer::start(int port, std::string* why,
                                                                    const BenchControllerState& initial) {
  ModbusServerOptions options;
  options.port = port;
  return start_with(options, why, initial);
}

std::unique_ptr<BenchControllerServer> BenchControllerServer::start_rtu(const std::string& link, int slave_id,
                                                                        std::string* why,
                                                                        const BenchControllerState& initial) {
  ModbusServerOptions options;
  options.rtu_link = link;
  options.rtu_slave_id = slave_id;
  return start_with(options, why, initial);
}

std::unique_ptr<BenchControllerServer> BenchControllerServer::start_with(ModbusServerOptions options, std::string* why,
                                                                         const BenchControllerState& initial) {
  std::unique_ptr<BenchControllerServer> sim(new BenchControllerServer());
  sim->state_ = initial;
  options.holding_start = r::kHoldingStart;
  options.holding_count = r::kHoldingCount;
  options.input_start = r::kInputStart;
  options.input_count = r::kInputCount;
  BenchControllerServer* self = sim.get();
  sim->server_ = ModbusTcpServer::start(
      options, [self](modbus_mapping_t& regs, double dt) { self->tick(regs, dt); }, why);
  if (!sim->server_) return nullptr;
  sim->server_->on_written([self](modbus_mapping_t& regs, int address, int count, const std::uint16_t* before) {
    self->written(regs, address, count, before);
  });
  sim->server_->with_registers([&](modbus_mapping_t& regs) {
    std::lock_guard lock(sim->state_mutex_);
    publish(sim->state_, regs, true);
    sim->published_ = true;
  });
  return sim;
}

void BenchControllerServer::update(const std::function<void(BenchControllerState&)>& change) {
  server_->with_registers([&](modbus_mapping_t& regs) {
    std::lock_guard lock(state_mutex_);
    change(state_);
    publish(state_, regs, true);  // the hook may change setpoints too
  });
}

BenchControllerState BenchControllerServer::state() {
  BenchControllerState copy;
  server_->with_registers([&](modbus_mapping_t&) {
    std::lock_guard lock(state_mutex_);
    copy = state_;
  });
  return copy;
}

void BenchControllerServer::take_setpoints(BenchControllerState& s, const modbus_mapping_t& regs) {
  auto& m = const_cast<modbus_mapping_t&>(regs);
  s.temperature_setpoint_degC = static_cast<std::int16_t>(*holding(m, r::kTemperatureSetpoint)) * 0.01;
  s.table_rate_setpoint_rad_s = bits_float(get32(holding(m, r::kTableRateSetpoint), WordOrder::ABCD));
  s.table_angle_setpoint_rad = bits_float(get32(holding(m, r::kTableAngleSetpoint), WordOrder::ABCD));
  s.shaker_enable = *holding(m, r::kShakerEnable) != 0;
  s.shaker_profile = *holding(m, r::kShakerProfile);
  s.heartbeat = *holding(m, r::kHeartbeat);
}

// The controllers' communication-loss action: every machine to rest, latched.
void BenchControllerServer::watch_heartbeat(BenchControllerState& s, std::int64_t now_ns) {
  if (!(s.heartbeat_timeout_s > 0.0) || s.heartbeat_ns == 0 || s.comm_lost) return;
  if (static_cast<double>(now_ns - s.heartbeat_ns) * 1e-9 < s.heartbeat_timeout_s) return;
  s.comm_lost = true;
  s.comm_lost_ns = now_ns;
  s.table_rate_setpoint_rad_s = 0.0;
  s.table_position_mode = false;
  s.shaker_enable = false;
  s.temperature_setpoint_degC = s.comm_loss_temperature_degC;
}

void BenchControllerServer::written(modbus_mapping_t& regs, int address, int count, const std::uint16_t* before) {
  std::lock_guard lock(state_mutex_);
  BenchControllerState& s = state_;
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  const std::int64_t now_ns = static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
  for (int i = 0; i < count; ++i) {
    const int offset = address + i - r::kHoldingStart;
    if (offset < 0 || offset >= r::kHoldingCount) continue;
    if ((s.ignore_writes >> offset) & 1u) {
      *holding(regs, address + i) = before[i];  // answered, not taken
      continue;
    }
    s.written_ns[static_cast<std::size_t>(offset)] = now_ns;
  }
  // The last setpoint written chooses the table's mode, as on rate tables with a rate and a
  // position loop.
  auto touches = [&](int reg, int words) { return address < reg + words && reg < address + count; };
  const std::uint16_t beat_before = s.heartbeat;
  if (touches(r::kTableAngleSetpoint, 2) && ((s.ignore_writes >> (r::kTableAngleSetpoint - r::kHoldingStart)) & 1u) == 0)
    s.table_position_mode = true;
  if (touches(r::kTableRateSetpoint, 2) && ((s.ignore_writes >> (r::kTableRateSetpoint - r::kHoldingStart)) & 1u) == 0)
    s.table_position_mode = false;
  take_setpoints(s, regs);
  if (touches(r::kHeartbeat, 1) && ((s.ignore_writes >> (r::kHeartbeat - r::kHoldingStart)) & 1u) == 0 &&
      (s.heartbeat != beat_before || s.heartbeat_ns == 0)) {
    s.heartbeat_ns = now_ns;
    s.comm_lost = false;
  }
  publish(s, regs, false);  // status words judge the new setpoint from the first read on
}

void BenchControllerServer::tick(modbus_mapping_t& regs, double dt) {
  std::lock_guard lock(state_mutex_);
  BenchControllerState& s = state_;
  if (!published_) return;  // the first ticks may come before start() wrote the registers
  take_setpoints(s, regs);  // as the clients left them
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  const bool was_lost = s.comm_lost;
  watch_heartbeat(s, static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec);
  if (s.comm_lost && !was_lost) publish(s, regs, true);   // the safe setpoints in the registers too
  if (s.frozen) return;

  const double error = s.temperature_setpoint_degC - s.temperature_degC;
  s.peltier_power_w = std::clamp(s.peltier_gain_w_per_k * error, -s.peltier_max_w, s.peltier_max_w);
  s.temperature_degC += error * std::min(1.0, dt / s.thermal_time_constant_s);

  constexpr double kTwoPi = 6.283185307179586;
  const double accel = s.table_max_accel_rad_s2;
  double wanted_rate = s.table_rate_setpoint_rad_s;
  if (s.table_position_mode) {
    // To the target on the braking curve (v^2 = 2 a d), landing on it in the last tick.
    const double to_go = s.table_angle_setpoint_rad - (s.table_turns * kTwoPi + s.table_angle_rad);
    const double speed = std::min({s.table_max_rate_rad_s, std::sqrt(2.0 * accel * std::abs(to_go)), std::abs(to_go) / dt});
    wanted_rate = to_go >= 0.0 ? speed : -speed;
  }
  const double dv = std::clamp(wanted_rate - s.table_rate_rad_s, -accel * dt, accel * dt);
  s.table_rate_rad_s += dv;
  s.table_angle_rad += s.table_rate_rad_s * dt;
  while (s.table_angle_rad >= kTwoPi) { s.table_angle_rad -= kTwoPi; ++s.table_turns; }
  while (s.table_angle_rad < 0.0) { s.table_angle_rad += kTwoPi; --s.table_turns; }

  s.shaker_enabled_for_s = s.shaker_enable ? s.shaker_enabled_for_s + dt : 0.0;
  if (s.shaker_enable && (s.shaker_status & r::kShakerFault) == 0 && s.shaker_enabled_for_s >= s.shaker_start_s) {
    s.shaker_status |= r::kShakerRunning;
    s.shaker_frequency_hz = 10.0 * s.shaker_profile;  // each stored profile runs at its own frequency
  }
  if (!s.shaker_enable) {
    s.shaker_status &= static_cast<std::uint16_t>(~r::kShakerRunning);
    s.shaker_frequency_hz = 0.0;
  }
  publish(s, regs, false);
}

void BenchControllerServer::publish(const BenchControllerState& s, modbus_mapping_t& regs, bool setpoints) {
  if (setpoints) {
    *holding(regs, r::kTemperatureSetpoint) = s16(s.temperature_setpoint_degC * 100.0);
    put32(holding(regs, r::kTableRateSetpoint), float_bits(static_cast<float>(s.table_rate_setpoint_rad_s)),
          WordOrder::ABCD);
    *holding(regs, r::kShakerEnable) = s.shaker_enable ? 1 : 0;
    put32(holding(regs, r::kTableAngleSetpoint), float_bits(static_cast<float>(s.table_angle_setpoint_rad)),
          WordOrder::ABCD);
    *holding(regs, r::kShakerProfile) = s.shaker_profile;
    *holding(regs, r::kHeartbeat) = s.heartbeat;
  }
  *input(regs, r::kCommStatus) = s.comm_lost ? r::kCommLost : 0;
  constexpr double kTwoPi = 6.283185307179586;
  const double position = s.table_turns * kTwoPi + s.table_angle_rad;
  std::uint16_t table_status = 0;
  if (!s.table_position_mode && std::abs(s.table_rate_rad_s - s.table_rate_setpoint_rad_s) < r::kTableRateTolerance)
    table_status |= r::kTableAtRate;
  if (s.table_position_mode && std::abs(position - s.table_angle_setpoint_rad) < r::kTablePositionTolerance &&
      std::abs(s.table_rate_rad_s) < r::kTableRateTolerance)
    table_status |= r::kTableInPosition;
  *input(regs, r::kTableStatus) = table_status;
  *input(regs, r::kThermalStatus) =
      std::abs(s.temperature_degC - s.temperature_setpoint_degC) < r::kThermalTolerance ? r::kThermalAtSetpoint : 0;
  put32(input(regs, r::kTablePosition), float_bits(static_cast<float>(position)), WordOrder::ABCD);
  *input(regs, r::kTemperature) = s16(s.temperature_degC * 100.0);
  *input(regs, r::kPeltierPower) = s16(s.peltier_power_w * 10.0);
  put32(input(regs, r::kTableAngle), float_bits(static_cast<float>(s.table_angle_rad)), WordOrder::CDAB);
  put32(input(regs, r::kTableRate), float_bits(static_cast<float>(s.table_rate_rad_s)), WordOrder::BADC);
  *input(regs, r::kShakerStatus) = s.shaker_status;
  put32(input(regs, r::kShakerFrequency),
        static_cast<std::uint32_t>(std::llround(std::max(0.0, s.shaker_frequency_hz) * 1000.0)), WordOrder::DCBA);
  put32(input(regs, r::kTableTurns), static_cast<std::uint32_t>(s.table_turns), WordOrder::ABCD);
}

}  // namespace inertia::hal::wire_sim
