#pragma once
// Simulated bench controllers behind one Modbus TCP server (docs/design.md: thermal controller of the
// temperature-controlled fixture, rotation-table controller, shaker controller status), with
// the register map a client uses for them (bench_controller_register_map()).
//
// Holding registers (setpoints, writable)          Input registers (measurements)
//   0x1000 temperature_setpoint int16  0.01 degC     0x2000 temperature      int16   0.01 degC
//   0x1001 table_rate_setpoint  float32 ABCD rad/s   0x2001 peltier_power    int16   0.1 W
//   0x1003 shaker_enable        uint16  0/1          0x2002 table_angle      float32 CDAB rad
//   0x1004 table_angle_setpoint float32 ABCD rad     0x2004 table_rate       float32 BADC rad/s
//   0x1006 shaker_profile       uint16               0x2006 shaker_status    uint16  bits
//   0x1007 heartbeat            uint16               0x2007 shaker_frequency uint32 DCBA 0.001 Hz
//                                                    0x2009 table_turns      int32  ABCD
//                                                    0x200B table_status     uint16  bits
//                                                    0x200C thermal_status   uint16  bits
//                                                    0x200D table_position   float32 ABCD rad
//                                                    0x200F comm_status      uint16  bits
// The controllers take a setpoint the moment it is written (the server's write hook) and move
// toward it at their own rate, reporting settled in their status words, as the test executive
// (daq/test_executive.hpp) expects of real ones: table_status bit 0 at rate (rate mode), bit 1
// in position (position mode: entered by writing table_angle_setpoint, left by writing
// table_rate_setpoint); thermal_status bit 0 at setpoint; shaker_status bit 0 running (after
// shaker_start_s), bit 1 fault.
// Their communication-loss watchdog, as a PLC's or a drive's: once armed by a first write of the
// heartbeat register, a heartbeat that has not changed for heartbeat_timeout_s stops every
// machine (table rate 0 at its deceleration, position mode left, shaker disabled, thermal
// setpoint to comm_loss_temperature_degC) and latches comm_status bit 0 until the next heartbeat;
// motion then needs a new command. bench_controller_register_map() is what the simulated benches
// poll; the registers added for the executive (0x1004.., 0x200B..) are described in bench files.
// The words are composed here byte by byte from the documented order, independently of
// hal/modbus/register_map.cpp, so the client's decoding is checked against a second reading of
// the same convention. (libmodbus 3.1.6's modbus_set_float_abcd() is not used: on this machine
// it writes 0x4049 0x0FDB (pi) as 0x4940 0xDB0F, and its get_float_abcd() does not invert it.)
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "hal/modbus/register_map.hpp"
#include "hal/wire_sim/modbus_tcp_server.hpp"

namespace inertia::hal::wire_sim {

struct BenchControllerState {
  bool frozen = false;                  // physics paused: registers hold exactly what was set
  // Thermal fixture: first-order plant, Peltier power proportional to the error, saturated.
  double temperature_degC = 23.0;
  double temperature_setpoint_degC = 23.0;
  double peltier_power_w = 0.0;
  double thermal_time_constant_s = 5.0;
  double peltier_gain_w_per_k = 4.0, peltier_max_w = 60.0;
  // Rotation table: the rate follows its setpoint at a bounded acceleration.
  double table_angle_rad = 0.0;
  double table_rate_rad_s = 0.0;
  double table_rate_setpoint_rad_s = 0.0;
  double table_max_accel_rad_s2 = 2.0;
  std::int32_t table_turns = 0;
  // Position mode (after a write of table_angle_setpoint): to the continuous angle
  // table_turns * 2 pi + table_angle at up to table_max_rate_rad_s, within the acceleration limit.
  bool table_position_mode = false;
  double table_angle_setpoint_rad = 0.0;
  double table_max_rate_rad_s = 3.5;
  // Shaker controller status.
  bool shaker_enable = false;
  std::uint16_t shaker_status = 0;      // bit0 running, bit1 fault, bit2 over-travel
  double shaker_frequency_hz = 0.0;
  std::uint16_t shaker_profile = 0;
  double shaker_start_s = 0.1;          // enable -> running
  double shaker_enabled_for_s = 0.0;
  // Faults of the controllers themselves: bit i set, a write to holding register
  // kHoldingStart + i is answered but not taken (the register keeps its words): a controller
  // that never confirms a command. A 32-bit setpoint has two registers (two bits).
  std::uint16_t ignore_writes = 0;
  // CLOCK_MONOTONIC (ns) of the last write taken, per holding register kHoldingStart + i: when
  // the controller got each setpoint, seen from its side.
  std::array<std::int64_t, 8> written_ns{};
  // Communication-loss watchdog (0: none): see the file comment.
  double heartbeat_timeout_s = 0.0;
  double comm_loss_temperature_degC = 25.0;
  std::uint16_t heartbeat = 0;          // the register's value, as the client last wrote it
  std::int64_t heartbeat_ns = 0;        // CLOCK_MONOTONIC of its last change (0: never written)
  bool comm_lost = false;               // the watchdog tripped (latched until the next heartbeat)
  std::int64_t comm_lost_ns = 0;        // when it tripped
};

namespace bench_registers {
inline constexpr int kHoldingStart = 0x1000, kHoldingCount = 8;
inline constexpr int kInputStart = 0x2000, kInputCount = 16;
inline constexpr int kTemperatureSetpoint = 0x1000, kTableRateSetpoint = 0x1001, kShakerEnable = 0x1003,
                     kTableAngleSetpoint = 0x1004, kShakerProfile = 0x1006, kHeartbeat = 0x1007;
inline constexpr int kTemperature = 0x2000, kPeltierPower = 0x2001, kTableAngle = 0x2002, kTableRate = 0x2004,
                     kShakerStatus = 0x2006, kShakerFrequency = 0x2007, kTableTurns = 0x2009, kTableStatus = 0x200B,
                     kThermalStatus = 0x200C, kTablePosition = 0x200D, kCommStatus = 0x200F;
// Status bits.
inline constexpr std::uint16_t kTableAtRate = 0x1, kTableInPosition = 0x2, kThermalAtSetpoint = 0x1,
                               kShakerRunning = 0x1, kShakerFault = 0x2, kCommLost = 0x1;
// Within these the controllers report settled.
inline constexpr double kTableRateTolerance = 1e-3, kTablePositionTolerance = 1e-3, kThermalTolerance = 0.05;
}  // namespace bench_registers

/// The client-side map of the simulated controllers (limits: setpoint 10..60 degC, table rate
/// +-3.5 rad/s); the bench template's [modbus] section describes the same device.
modbus::RegisterMap bench_controller_register_map();

class BenchControllerServer {
 public:
  /// port 0: a free port. nullptr with the reason on failure.
  static std::unique_ptr<BenchControllerServer> start(int port, std::string* why,
                                                      const BenchControllerState& initial = {});
  /// The same controllers on a Modbus RTU line: a pseudo-terminal whose slave side `link`
  /// names (see ModbusServerOptions::rtu_link), answering as slave `slave_id`.
  static std::unique_ptr<BenchControllerServer> start_rtu(const std::string& link, int slave_id, std::string* why,
                                                          const BenchControllerState& initial = {});
  [[nodiscard]] int port() const noexcept { return server_->port(); }
  /// The server goes away (connections closed) / comes back on the same port; state is kept.
  void stop() { server_->stop(); }
  bool restart(std::string* why) { return server_->restart(why); }
  void set_silent(bool silent) noexcept { server_->set_silent(silent); }
  /// The hook: change the simulated state (e.g. inject a shaker fault). Thread: any.
  void update(const std::function<void(BenchControllerState&)>& change);
  [[nodiscard]] BenchControllerState state();
  [[nodiscard]] ModbusTcpServer& server() noexcept { return *server_; }

 private:
  BenchControllerServer() = default;
  static std::unique_ptr<BenchControllerServer> start_with(ModbusServerOptions options, std::string* why,
                                                           const BenchControllerState& initial);
  void tick(modbus_mapping_t& registers, double dt_s);  // server thread, register lock held
  void written(modbus_mapping_t& registers, int address, int count, const std::uint16_t* before);  // likewise
  static void take_setpoints(BenchControllerState& s, const modbus_mapping_t& registers);
  static void watch_heartbeat(BenchControllerState& s, std::int64_t now_ns);
  static void publish(const BenchControllerState& s, modbus_mapping_t& registers, bool setpoints);

  std::mutex state_mutex_;             // taken inside the register lock, never the other way
  BenchControllerState state_;
  bool published_ = false;             // guarded by the register lock
  std::unique_ptr<ModbusTcpServer> server_;
};

}  // namespace inertia::hal::wire_sim
