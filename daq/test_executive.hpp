#pragma once
// The test executive of a real bench: the plan's cases and phases run on the bench's
// controllers, or marked by the operator, with the same INERTIA_EVENT markers a simulated bench
// publishes.
//
// Nothing moves until an operator arms it. The executive starts disarmed, whatever started the
// daemon (boot, a restart after a crash, by hand): it holds every controller's safe state
// (daq/controller_port.hpp), journals how the previous run ended (daq/run_record.hpp) and what it
// finds on the controllers, and acquires and publishes. executive = "plan": an operator's arm
// (`inertia-daqd arm`, or `--arm` on the command line for an attended start) runs the plan once
// from its first case; its end or any abort holds the safe state again and disarms. The daemon
// never resumes or reruns a plan by itself. An arm while a controller the plan commands is
// faulted (link down, silent, a fault bit set, its safe state not confirmed) is refused, with
// the reason.
//
// Running the plan: for each phase, the commands of config/controller_plan.hpp go to the
// controllers one after another over Modbus: each write rate-limited (ramped in steps every
// kRampTickS), clamped, and confirmed by reading the register back; then the executive waits
// until the controller reports settled (the register's `measured` reading within `tolerance`, or
// its `settled_by` status bits, continuously for `settle_s`) or gives up after
// `settle_timeout_s`. The phase starts (MARK_PHASE_START) at the CLOCK_MONOTONIC of the poll that
// confirmed the last settling (the clock of the sample blocks), lasts its duration_s, and ends
// (MARK_PHASE_END) when the next phase is commanded. A command not confirmed or not settled in
// time: MARK_PHASE_FAILED, the safe state, MARK_ABORT of the case; the plan stops.
// executive = "operator": the operator moves the bench and marks phases with `inertia-daqd mark`;
// the executive turns each accepted request into markers stamped at its receipt.
//
// Aborts: the daemon stopping (SIGTERM, --duration), `mark --stop`, and while the plan runs a
// controller fault (a `role = "fault"` register's bits, a commanded controller silent or its
// link down). Every abort holds the safe state on every device with writes enabled: written at
// once (not ramped), read back, retried until confirmed for as long as the daemon runs. The time
// from the abort to the last confirmation is on the journal; a case that was running gets
// MARK_ABORT. An operator stop is acknowledged as soon as every controller has been commanded,
// and answered again when the safe state is confirmed (or known not to be). A safe state not
// confirmed is the daemon fault `safe-state-unconfirmed:<device>` on INERTIA_STATUS, and a
// journal entry repeated every kUnconfirmedRepeatS until it is confirmed.
//
// Thread: start()/stop()/faults()/armed() on the control thread (the daemon's supervisor) or the
// publisher (faults()); the plan, the command channel and the markers on the executive's own
// thread, the only producer of the publisher's marker ring on a real bench. Not real-time.
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
#include "daq/command_auth.hpp"
#include "daq/command_socket.hpp"
#include "daq/controller_port.hpp"
#include "daq/publisher.hpp"
#include "daq/run_record.hpp"
#include "inertia/plan_command_t.hpp"
#include "inertia/signed_command_t.hpp"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace inertia::daq {

struct ExecutiveOptions {
  std::string lcm_url;            // where signed requests arrive from other machines (the daemon's URL)
  std::unique_ptr<CommandSocket> socket;   // requests from this machine (daq/command_socket.hpp)
  std::vector<CommandKey> keys;   // the operators' keys for signed requests (none: every one refused)
  std::string operator_group = "inertia-operators";
  bool arm_at_start = false;      // --arm: an attended start, the plan armed by whoever started the daemon
  std::string armed_by;           // who that is ("uid 1000 (ana), --arm")
  RunRecorder* record = nullptr;  // this run's record (none: not kept)
  SpscRing<OperatorRecord>* operator_records = nullptr;   // accepted requests, for INERTIA_OPERATOR
};

class TestExecutive {
 public:
  /// Period of the executive's loop (commands, faults, settling): the bound of its reaction time.
  static constexpr double kLoopS = 0.005;
  /// A rate-limited setpoint is written again this often until it reaches its target.
  static constexpr double kRampTickS = 0.1;
  /// How long the executive waits for a port to answer a write, beyond the device's response timeout.
  static constexpr double kAnswerMarginS = 1.0;
  /// An unconfirmed safe state is journalled again this often while it lasts.
  static constexpr double kUnconfirmedRepeatS = 10.0;

  /// `ports`: the opened Modbus devices by name (RealBench::ports).
  TestExecutive(const config::BenchConfig& bench, std::map<std::string, std::shared_ptr<ControllerPort>> ports,
                SpscRing<PlanMark>& marks, ExecutiveOptions options);
  ~TestExecutive();
  TestExecutive(const TestExecutive&) = delete;
  TestExecutive& operator=(const TestExecutive&) = delete;

  /// executive = "plan": every controller the plan commands opened; false + why naming the one
  /// that did not (an `optional = true` device left out). Control thread, before start().
  bool ready(std::string* why) const;
  void start();
  /// Aborts whatever runs (safe state; MARK_ABORT when a case is open), waits for the safe state's
  /// confirmation (bounded by the controllers' response timeouts), then ends the thread. `reason`
  /// goes to the journal ("SIGTERM"). Control thread; returns when the thread has ended.
  void stop(const std::string& reason);

  [[nodiscard]] bool plan_finished() const noexcept { return plan_finished_.load(std::memory_order_acquire); }
  [[nodiscard]] bool armed() const noexcept { return armed_.load(std::memory_order_acquire); }
  /// Daemon-wide faults for INERTIA_STATUS: "safe-state-unconfirmed:<device>". Any thread.
  [[nodiscard]] std::vector<std::string> faults() const;
  /// Operator requests accepted, refused and unsigned so far (INERTIA_STATUS). Any thread.
  [[nodiscard]] std::array<std::int64_t, 3> command_counts() const;

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
  /// An operator's request and who sent it (as verified), with the way back for its answers.
  struct Inbound {
    plan_command_t command{};
    CommandOrigin origin;
    int connection = -1;                 // the command socket's connection; -1: LCM
  };
  struct OpenCase {
    std::size_t index = 0;
    std::int64_t start_ns = 0;
    std::optional<std::size_t> phase;
    std::int64_t phase_start_ns = 0;
  };
  /// A safe state commanded and not yet accounted for on the journal (and to the operator who
  /// asked for it): its account is written once every port confirms, or at its deadline.
  struct SafeStateAccount {
    std::string headline;                // "plan: abort (...) during case table phase 1 (rotation)"
    std::string case_name;
    std::int64_t since_ns = 0;
    std::int64_t deadline_ns = 0;
    int priority = 6;
    std::optional<Inbound> stop_request;   // answered STATUS_DONE / REFUSED with the account
  };
  /// Per port: the unconfirmed safe state's journal entries.
  struct UnconfirmedWatch {
    bool raised = false;
    std::int64_t journalled_ns = 0;
  };

  void run() noexcept;
  void run_plan();
  std::int64_t execute(const config::PhaseCommand& command, std::size_t case_index, std::size_t phase_index,
                       std::int64_t commanded_ns);
  std::int64_t settle(const Binding& b, double target, std::int64_t confirmed_ns, std::size_t case_index,
                      std::size_t phase_index);
  /// Waits (pumping) until every controller the executive uses has answered a poll, up to 10 s;
  /// the names of those that did not.
  std::vector<std::string> wait_for_first_polls();
  /// At start: the previous run's end and what the controllers report, on the journal.
  void report_start(const std::vector<std::string>& silent);
  /// One loop turn: operator commands, abort requests, controller faults (throws Aborted while a
  /// plan runs), the safe state's watch and account, sleeping up to kLoopS.
  void pump(bool plan_running);
  void abort(const std::string& reason, std::int64_t t_ns);
  /// Holds the safe state on every port that has one (written at once, then until confirmed).
  void hold_safe_state();
  /// Starts the journal's account of the safe state just commanded.
  void account_safe_state(std::string headline, std::string case_name, int priority, std::int64_t since_ns,
                          std::optional<Inbound> stop_request);
  /// The account, if every port confirmed or the deadline passed (or `final`: the daemon stops).
  void close_safe_state_account(bool final);
  /// Raises, repeats and clears the unconfirmed safe state per port.
  void watch_safe_state();
  std::optional<std::string> controller_fault() const;
  /// A controller whose heartbeat lapsed (or is lapsing) since the plan started: it has stopped
  /// its machine by itself, so the plan cannot go on.
  std::optional<std::string> heartbeat_fault() const;
  /// Why the plan cannot be armed now, if it cannot.
  std::optional<std::string> arm_refusal() const;
  void record(const std::string& activity);

  // markers
  void mark(std::int8_t what, std::size_t case_index, std::int32_t phase_index, std::int64_t t_ns, std::int64_t start_ns,
            std::int64_t end_ns);
  void begin_case(std::size_t case_index, std::int64_t t_ns);
  void begin_phase(std::size_t phase_index, std::int64_t t_ns);
  void end_phase(std::int64_t t_ns);
  void end_case(std::int64_t t_ns);

  // operator commands
  /// Waits up to kLoopS for a request (the LCM socket and the command socket) and queues each.
  void receive_commands();
  void on_unsigned(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void on_signed(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void handle(const Inbound& in);
  std::pair<bool, std::string> operator_mark(const plan_command_t& command, const std::string& who);
  std::pair<bool, std::string> operator_end_case();
  std::pair<bool, std::string> operator_arm(const std::string& who);
  void reply(const Inbound& request, std::int8_t status, const std::string& detail);
  /// The journal's entry of a request, and its count; an accepted one also goes to INERTIA_OPERATOR.
  void account_command(const Inbound& in, bool accepted, const std::string& detail);

  std::string phase_text(std::size_t case_index, std::size_t phase_index) const;
  std::string value_text(const Binding& b, double value) const;

  const config::BenchConfig& bench_;
  std::map<std::string, std::shared_ptr<ControllerPort>> ports_;
  SpscRing<PlanMark>& marks_;
  ExecutiveOptions options_;
  std::map<config::RegisterRole, Binding> bindings_;
  std::vector<Binding> faults_;          // role = "fault" registers of opened devices
  // Per command role: the value of its last confirmed and settled command (skipped when asked again).
  std::map<config::RegisterRole, double> holds_;
  std::optional<OpenCase> open_;
  bool arm_pending_ = false;             // an accepted arm: the plan starts at the next loop turn
  std::map<std::string, std::uint64_t> lapses_at_start_;   // per device: heartbeat lapses when the plan started

  std::unique_ptr<lcm::LCM> lcm_;
  SignedCommandVerifier verifier_;
  std::optional<gid_t> operator_gid_;   // the operator group's id (none: no such group here)
  std::vector<Inbound> inbox_;           // filled by receive_commands() inside pump()
  std::map<std::pair<std::string, std::int64_t>, plan_command_t> answered_;   // LCM requests, for repeats
  std::optional<Inbound> stop_request_;  // an operator stop acknowledged, its abort pending
  std::atomic<std::int64_t> accepted_{0}, refused_{0}, unsigned_{0};
  std::optional<SafeStateAccount> account_;
  std::map<std::string, UnconfirmedWatch> unconfirmed_;   // by device

  std::thread thread_;
  std::mutex stop_mutex_;
  std::string stop_reason_;              // guarded by stop_mutex_
  std::int64_t stop_ns_ = 0;             // guarded by stop_mutex_
  std::atomic<bool> stop_{false};
  std::atomic<bool> plan_finished_{false};
  std::atomic<bool> armed_{false};
  mutable std::mutex faults_mutex_;
  std::vector<std::string> faults_now_;  // guarded by faults_mutex_
};

}  // namespace inertia::daq
