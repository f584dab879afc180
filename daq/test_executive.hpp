#pragma once
// The test executive of a real bench (issue 13): the plan's cases and phases run on the bench's
// controllers, or marked by the operator, with the same INERTIA_EVENT markers a simulated bench
// publishes.
//
// executive = "plan" ([bench] of the bench file): for each phase, the commands of
// config/controller_plan.hpp go to the controllers one after another over Modbus (through each
// device's polling thread, daq/controller_port.hpp): each write rate-limited (ramped in steps
// every kRampTickS), clamped, and confirmed by reading the register back; then the executive
// waits until the controller reports settled (the register's `measured` reading within
// `tolerance`, or its `settled_by` status bits, continuously for `settle_s`) or gives up after
// `settle_timeout_s`. The phase starts (MARK_PHASE_START) at the CLOCK_MONOTONIC of the poll
// that confirmed the last settling (the clock of the sample blocks), lasts its duration_s, and
// ends (MARK_PHASE_END) when the next phase is commanded. A command not confirmed or not settled
// in time: MARK_PHASE_FAILED, the safe state, MARK_ABORT of the case; the plan stops.
// executive = "operator": the operator moves the bench and marks phases with `inertia-daqd mark`
// (INERTIA_COMMAND, plan_command_t); the executive turns each accepted request into markers
// stamped at its receipt and answers on INERTIA_COMMAND_REPLY.
// Aborts: the daemon stopping (SIGTERM, --duration), `mark --stop`, and while the plan runs a
// controller fault (a `role = "fault"` register's bits, a commanded controller silent or its
// link down). Every abort writes each register's `safe` value at once (not ramped), confirmed,
// on every device with writes enabled; the time from the abort to the last confirmation is on
// the journal; a case that was running gets MARK_ABORT. The plan's normal end writes the safe
// state too, so nothing is left moving.
//
// Thread: start()/stop() on the control thread (the daemon's supervisor); the plan, the LCM
// command channel and the markers on the executive's own thread, the only producer of the
// publisher's marker ring on a real bench. Not real-time.
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/controller_plan.hpp"
#include "common/spsc_ring.hpp"
#include "daq/controller_port.hpp"
#include "daq/publisher.hpp"
#include "inertia/plan_command_t.hpp"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace inertia::daq {

class TestExecutive {
 public:
  /// Period of the executive's loop (commands, faults, settling): the bound of its reaction time.
  static constexpr double kLoopS = 0.005;
  /// A rate-limited setpoint is written again this often until it reaches its target.
  static constexpr double kRampTickS = 0.1;
  /// How long the executive waits for a port to answer a write, beyond the device's response timeout.
  static constexpr double kAnswerMarginS = 1.0;

  /// `ports`: the opened Modbus devices by name (RealBench::ports). `lcm_url`: where the
  /// operator's INERTIA_COMMAND arrives (the daemon's URL).
  TestExecutive(const config::BenchConfig& bench, std::map<std::string, std::shared_ptr<ControllerPort>> ports,
                SpscRing<PlanMark>& marks, std::string lcm_url);
  ~TestExecutive();
  TestExecutive(const TestExecutive&) = delete;
  TestExecutive& operator=(const TestExecutive&) = delete;

  /// executive = "plan": every controller the plan commands opened; false + why naming the one
  /// that did not (an `optional = true` device left out). Control thread, before start().
  bool ready(std::string* why) const;
  void start();
  /// Aborts whatever runs (safe state; MARK_ABORT when a case is open), then ends the thread.
  /// `reason` goes to the journal ("SIGTERM"). Control thread; returns when the thread has ended.
  void stop(const std::string& reason);

  [[nodiscard]] bool plan_finished() const noexcept { return plan_finished_.load(std::memory_order_acquire); }

 private:
  struct Binding {                       // a command role's register and the port to its device
    const config::ModbusDevice* device = nullptr;
    const config::ModbusRegister* reg = nullptr;
    std::size_t index = 0;               // register index in the device (and in its port's polls)
    std::shared_ptr<ControllerPort> port;
  };
  struct Aborted {                       // thrown out of the plan by pump(): an abort is pending
    std::string reason;
    std::int64_t t_ns;
  };
  struct PhaseFailed {                   // thrown by a command that was not confirmed or did not settle
    std::string reason;
    std::string device;
  };
  struct OpenCase {
    std::size_t index = 0;
    std::int64_t start_ns = 0;
    std::optional<std::size_t> phase;
    std::int64_t phase_start_ns = 0;
  };

  void run() noexcept;
  void run_plan();
  std::int64_t execute(const config::PhaseCommand& command, std::size_t case_index, std::size_t phase_index,
                       std::int64_t commanded_ns);
  std::int64_t settle(const Binding& b, double target, std::int64_t confirmed_ns, std::size_t case_index,
                      std::size_t phase_index);
  void wait_for_first_polls();
  /// One loop turn: operator commands, abort requests, controller faults (throws Aborted while a
  /// plan runs), sleeping up to kLoopS.
  void pump(bool plan_running);
  void abort(const std::string& reason, std::int64_t t_ns);
  /// Writes every safe value and waits for the confirmations; returns the journal's account.
  std::string apply_safe_state(std::int64_t since_ns, int* priority);
  std::optional<std::string> controller_fault() const;

  // markers
  void mark(std::int8_t what, std::size_t case_index, std::int32_t phase_index, std::int64_t t_ns, std::int64_t start_ns,
            std::int64_t end_ns);
  void begin_case(std::size_t case_index, std::int64_t t_ns);
  void begin_phase(std::size_t phase_index, std::int64_t t_ns);
  void end_phase(std::int64_t t_ns);
  void end_case(std::int64_t t_ns);

  // operator commands
  void on_command(const lcm::ReceiveBuffer* rbuf, const std::string& channel, const plan_command_t* command);
  void handle(const plan_command_t& command);
  std::pair<bool, std::string> operator_mark(const plan_command_t& command);
  std::pair<bool, std::string> operator_end_case();
  void reply(const plan_command_t& request, bool accepted, const std::string& detail);

  std::string phase_text(std::size_t case_index, std::size_t phase_index) const;
  std::string value_text(const Binding& b, double value) const;

  const config::BenchConfig& bench_;
  std::map<std::string, std::shared_ptr<ControllerPort>> ports_;
  SpscRing<PlanMark>& marks_;
  std::string lcm_url_;
  std::map<config::RegisterRole, Binding> bindings_;
  std::vector<Binding> faults_;          // role = "fault" registers of opened devices
  // Per command role: the value of its last confirmed and settled command (skipped when asked again).
  std::map<config::RegisterRole, double> holds_;
  std::optional<OpenCase> open_;

  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<plan_command_t> inbox_;    // filled by on_command inside pump()
  std::map<std::pair<std::string, std::int64_t>, plan_command_t> answered_;
  std::optional<plan_command_t> stop_request_;   // an operator stop being carried out

  std::thread thread_;
  std::mutex stop_mutex_;
  std::string stop_reason_;              // guarded by stop_mutex_
  std::int64_t stop_ns_ = 0;             // guarded by stop_mutex_
  std::atomic<bool> stop_{false};
  std::atomic<bool> plan_finished_{false};
};

}  // namespace inertia::daq
