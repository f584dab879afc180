#pragma once
// The test executive's way to one Modbus controller (issue 13). Every request to a device goes
// out from that device's polling thread (ModbusSampler): a libmodbus context is single-threaded
// and an RTU line has one master. The executive posts a command here and later takes its
// outcome; the polling thread executes commands between polls, woken at once rather than at its
// next poll, so an abort reaches the controllers within milliseconds (plus one request in
// flight). The polling thread also leaves the newest poll here for the executive to judge
// settling and faults.
//
// Thread: post(), request_safe_state(), take_outcome(), safe_state(), latest(): the executive
// (any one thread); serve(), wait_until(), publish(): the device's polling thread. Not
// real-time: a mutex and a condition variable (neither thread is on the sample path).
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hal/modbus/modbus_controller.hpp"

namespace inertia::daq {

class ControllerPort {
 public:
  /// A register's safe value (written on request_safe_state, at once and confirmed).
  struct SafeValue {
    std::size_t register_index = 0;
    double value = 0.0;
  };
  struct Outcome {
    hal::modbus::WriteResult result;
    std::int64_t t_ns = 0;           // CLOCK_MONOTONIC when the read back answered
  };
  /// The newest poll of every register of the device.
  struct Poll {
    std::uint64_t count = 0;         // polls so far (0: none yet)
    std::int64_t t_ns = 0;           // CLOCK_MONOTONIC of the answers
    bool connected = false;
    std::vector<double> values;      // SI, per register
    std::vector<bool> valid;
    std::int64_t last_valid_ns = 0;  // the newest poll with any valid value
  };
  struct SafeState {
    bool requested = false;
    bool done = false;
    std::int64_t requested_ns = 0, done_ns = 0;
    std::vector<std::string> written;   // "rate_setpoint = 0 rad/s" per register confirmed
    std::vector<std::string> failures;  // "rate_setpoint: link error" per register that failed
  };

  ControllerPort(std::string device, std::vector<SafeValue> safe_values);
  ControllerPort(const ControllerPort&) = delete;
  ControllerPort& operator=(const ControllerPort&) = delete;

  [[nodiscard]] const std::string& device() const noexcept { return device_; }
  [[nodiscard]] bool has_safe_state() const noexcept { return !safe_values_.empty(); }

  /// Queues a rate-limited write (hal::modbus::Ramp::Limited); returns its ticket.
  std::uint64_t post(std::size_t register_index, double value);
  /// The outcome of a ticket once executed (then forgotten), else nullopt.
  std::optional<Outcome> take_outcome(std::uint64_t ticket);
  /// Drops queued commands and has the polling thread write every safe value next, at once.
  /// Each call starts a new round (an abort after a plan's normal end writes them again).
  void request_safe_state();
  [[nodiscard]] SafeState safe_state() const;
  [[nodiscard]] Poll latest() const;

  /// Polling thread: executes the safe state if requested, then the queued commands.
  void serve(hal::modbus::ModbusController& controller);
  /// Polling thread: sleeps until `until_ns` (CLOCK_MONOTONIC) or until something is posted.
  void wait_until(std::int64_t until_ns);
  /// Polling thread: the newest poll's values.
  void publish(std::span<const hal::modbus::PolledValue> values, bool connected);

 private:
  struct Command {
    std::uint64_t ticket;
    std::size_t register_index;
    double value;
  };
  const std::string device_;
  const std::vector<SafeValue> safe_values_;
  mutable std::mutex mutex_;
  std::condition_variable posted_;
  std::deque<Command> queue_;
  std::map<std::uint64_t, Outcome> outcomes_;
  std::uint64_t next_ticket_ = 1;
  bool safe_pending_ = false;
  SafeState safe_;
  Poll poll_;
};

}  // namespace inertia::daq
