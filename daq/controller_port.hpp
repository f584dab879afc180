#pragma once
// The test executive's way to one Modbus controller. Every request to a device goes out from
// that device's polling thread (ModbusSampler): a libmodbus context is single-threaded and an RTU
// line has one master. The executive posts a command here and later takes its outcome; the
// polling thread executes commands between polls, woken at once rather than at its next poll, so
// an abort reaches the controllers within milliseconds (plus one request in flight). The polling
// thread also leaves the newest poll here for the executive to judge settling and faults.
//
// The safe state is held, not sent once: from the daemon's start and from every abort until the
// operator arms the plan, the polling thread writes every safe value until each is read back,
// retries the ones that fail every kSafeRetryS (reconnecting at once rather than after the link's
// back-off), and writes them again whenever the link comes back. While it is held, the plan's
// commands are refused. The heartbeat register, if the device has one, is written every period
// while the daemon's LifeSign is alive.
//
// Thread: post(), hold_safe_state(), release_safe_state(), take_outcome(), safe_state(),
// heartbeat(), latest(): the executive (any one thread); serve(), wait_until(), publish(): the
// device's polling thread. Not real-time: a mutex and a condition variable (neither thread is on
// the sample path).
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "daq/life_sign.hpp"
#include "hal/modbus/modbus_controller.hpp"

namespace inertia::daq {

class ControllerPort {
 public:
  /// A failed safe-state write is tried again after this long, as long as the safe state is held.
  static constexpr double kSafeRetryS = 0.2;

  /// A register's safe value.
  struct SafeValue {
    std::size_t register_index = 0;
    double value = 0.0;
  };
  /// The heartbeat register: written min, min + step, ..., max, min, ... every period; the
  /// controller stops its machine when no write came for timeout.
  struct Heartbeat {
    std::size_t register_index = 0;
    std::int64_t period_ns = 100'000'000;
    double min = 0.0, max = 65535.0, step = 1.0;
    std::int64_t timeout_ns = 1'000'000'000;
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
    bool held = false;
    bool confirmed = false;          // every safe value read back since the hold (or the link) began
    std::uint64_t round = 0;         // hold_safe_state() calls so far
    std::int64_t held_ns = 0;        // when the current round began
    std::int64_t confirmed_ns = 0;   // when its last value was read back
    int attempts = 0;                // write rounds in the current round
    std::vector<std::string> written;   // "rate_setpoint = 0" per register confirmed
    std::vector<std::string> failures;  // "rate_setpoint: link error (...)" per register not (yet) confirmed
  };
  struct HeartbeatState {
    bool present = false;
    std::int64_t timeout_ns = 0;
    std::uint64_t written = 0, failed = 0;
    std::int64_t last_written_ns = 0;
    std::string last_failure;
    // Gaps between two writes longer than the controller's timeout (the daemon hung, or its
    // heartbeat could not be written): the controller has stopped its machine meanwhile.
    std::uint64_t lapses = 0;
    double last_lapse_s = 0.0;
  };

  ControllerPort(std::string device, std::vector<SafeValue> safe_values, std::optional<Heartbeat> heartbeat = std::nullopt,
                 std::shared_ptr<const LifeSign> life = nullptr);
  ControllerPort(const ControllerPort&) = delete;
  ControllerPort& operator=(const ControllerPort&) = delete;

  [[nodiscard]] const std::string& device() const noexcept { return device_; }
  [[nodiscard]] bool has_safe_state() const noexcept { return !safe_values_.empty(); }

  /// Queues a rate-limited write (hal::modbus::Ramp::Limited); returns its ticket. Refused
  /// (WriteStatus::Disabled) while the safe state is held.
  std::uint64_t post(std::size_t register_index, double value);
  /// The outcome of a ticket once executed (then forgotten), else nullopt.
  std::optional<Outcome> take_outcome(std::uint64_t ticket);
  /// Drops queued commands and holds the safe state: the polling thread writes every safe value
  /// next, at once (not ramped), and until each is read back. Each call starts a new round.
  void hold_safe_state();
  /// The operator armed the plan: commands go out again.
  void release_safe_state();
  [[nodiscard]] SafeState safe_state() const;
  [[nodiscard]] HeartbeatState heartbeat() const;
  [[nodiscard]] Poll latest() const;

  /// Polling thread: the safe state while held and not confirmed, the heartbeat when due, then
  /// the queued commands.
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
  void serve_safe_state(hal::modbus::ModbusController& controller, std::int64_t now_ns);
  void serve_heartbeat(hal::modbus::ModbusController& controller, std::int64_t now_ns);

  const std::string device_;
  const std::vector<SafeValue> safe_values_;
  const std::optional<Heartbeat> heartbeat_spec_;
  const std::shared_ptr<const LifeSign> life_;
  mutable std::mutex mutex_;
  std::condition_variable posted_;
  std::deque<Command> queue_;
  std::map<std::uint64_t, Outcome> outcomes_;
  std::uint64_t next_ticket_ = 1;
  SafeState safe_;
  std::vector<bool> safe_confirmed_;     // per safe value, this round
  std::int64_t next_safe_attempt_ns_ = 0;
  std::uint64_t reconnects_seen_ = 0;    // the link's reconnects when the safe values were last confirmed
  HeartbeatState beat_;
  std::int64_t next_beat_ns_ = 0;        // polling thread only
  double beat_value_ = 0.0;              // polling thread only
  Poll poll_;
};

}  // namespace inertia::daq
