#pragma once
// Modbus client link, TCP or RTU (serial line): one owning wrapper of libmodbus' modbus_t
// that reconnects by itself. Recovery is ours, not libmodbus':
// MODBUS_ERROR_RECOVERY_LINK makes 3.1.x loop "until successful" inside a call (libmodbus
// issues #39, #199, #618), so the mode stays NONE and a dropped link is closed, then
// reconnected on a later call after an exponential, capped back-off. Calls never wait for the
// back-off: they fail at once (ENOTCONN).
// On a serial line there is no connection to lose: a controller that stops answering shows as
// timeouts, and after timeouts_before_reconnect of them the port is closed and opened again
// (a USB adapter unplugged and plugged back gets a new descriptor; /dev/serial/by-id names it).
// Thread: one thread (the daemon's Modbus thread; libmodbus contexts are not thread-safe).
// Not real-time: every call may block up to the response timeout. Never in a sampling thread.
#include <modbus/modbus.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "hal/modbus/register_map.hpp"

namespace inertia::hal::modbus {

/// Modbus RTU: the serial line (libmodbus modbus_new_rtu). An empty device means Modbus TCP.
struct SerialLine {
  std::string device;                 // e.g. /dev/ttyUSB0; empty: TCP
  int baud = 19200;
  char parity = 'E';                  // 'N', 'E' or 'O' (libmodbus' letters)
  int data_bits = 8;                  // 5..8
  int stop_bits = 1;                  // 1 or 2
};

struct ModbusConfig {
  std::string name = "modbus";        // device name; values are "<name>.<register>"
  std::string host = "127.0.0.1";     // TCP: IPv4 literal (modbus_new_tcp)
  int port = 502;
  SerialLine serial;                  // RTU when serial.device is set (host and port unused)
  int unit_id = 1;                    // TCP unit identifier; RTU slave address (1..247)
  double response_timeout_s = 0.5;    // also bounds connect()
  double reconnect_initial_s = 0.5;   // first back-off after the link drops
  double reconnect_max_s = 8.0;       // back-off doubles up to this
  int timeouts_before_reconnect = 3;  // consecutive timeouts that mean the link is dead
  bool writes_enabled = false;        // setpoint writes are off unless the bench config says so
  RegisterMap map;
  bool is_valid(std::string* why) const;
  [[nodiscard]] bool is_rtu() const noexcept { return !serial.device.empty(); }
  /// "127.0.0.1:502" or "/dev/ttyUSB0 19200 8E1", for messages.
  [[nodiscard]] std::string endpoint() const;
};

struct ModbusHealth {
  std::uint64_t requests = 0, errors = 0;
  std::uint64_t timeouts = 0;         // ETIMEDOUT
  std::uint64_t exceptions = 0;       // the device answered with a Modbus exception (EMBX*)
  std::uint64_t protocol_errors = 0;  // bad data, bad transaction id, too many data ...
  std::uint64_t disconnects = 0;      // link dropped by us after a connection-level error
  std::uint64_t reconnect_attempts = 0, reconnects = 0;
  int last_errno = 0;
  std::string last_error;             // modbus_strerror(last_errno)
};

class ModbusLink {
 public:
  using Clock = std::chrono::steady_clock;

  /// Opens the TCP connection or the serial port; nullptr with the reason ("modbus
  /// 127.0.0.1:1502: connect: Connection refused", "modbus /dev/ttyUSB0 19200 8E1: connect: No
  /// such file or directory") when it cannot.
  static std::unique_ptr<ModbusLink> connect(const ModbusConfig& config, std::string* why);
  ~ModbusLink();
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  /// FC3/FC4 into out (at most 125 words). Count read, or -1 with errno (ENOTCONN while the
  /// link is down and the back-off has not elapsed).
  [[nodiscard]] int read_registers(RegisterKind kind, int address, std::span<std::uint16_t> out);
  /// FC6 (one word) or FC16. Count written, or -1 with errno.
  [[nodiscard]] int write_registers(int address, std::span<const std::uint16_t> words);

  [[nodiscard]] bool connected() const noexcept { return connected_; }
  [[nodiscard]] const ModbusHealth& health() const noexcept { return health_; }
  /// Back-off before the next reconnect attempt (grows while attempts fail).
  [[nodiscard]] Clock::duration backoff() const noexcept { return backoff_; }
  /// The next call tries to reconnect at once, whatever is left of the back-off (a safe state
  /// that must go out as soon as the controller answers again).
  void reconnect_now() noexcept { next_attempt_ = Clock::time_point{}; }

 private:
  ModbusLink(modbus_t* ctx, const ModbusConfig& config);
  template <class Call>
  int call(Call&& request);
  bool try_reconnect();
  void drop_link();
  void record_error(int err);

  modbus_t* ctx_;
  Clock::duration initial_backoff_, max_backoff_, backoff_;
  Clock::time_point next_attempt_{};
  int timeouts_before_reconnect_;
  int consecutive_timeouts_ = 0;
  bool connected_ = true;
  ModbusHealth health_;
};

}  // namespace inertia::hal::modbus
