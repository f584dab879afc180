#include "daq/test_executive.hpp"

#include <poll.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <lcm/lcm-cpp.hpp>
#include <sstream>

#include "common/config/phase_label.hpp"
#include "common/lcm/channels.hpp"
#include "daq/journal.hpp"
#include "hal/device.hpp"
#include "inertia/plan_event_t.hpp"

namespace inertia::daq {
namespace {

using config::RegisterRole;

constexpr std::int64_t kNsPerS = 1'000'000'000;


std::string ms_text(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) * 1e-6 << " ms";
  return s.str();
}

std::string s_text(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << static_cast<double>(ns) * 1e-9 << " s";
  return s.str();
}

std::uint32_t bits_of(double reading) { return static_cast<std::uint32_t>(std::llround(std::max(0.0, reading))); }

/// A phase named by the operator: its 0-based index, a kind of the bench file (rotation,
/// thermal_step) or a marker label (static, thermal). The first such phase after `after`.
std::optional<std::size_t> find_phase(const config::TestCase& c, const std::string& name, std::optional<std::size_t> after) {
  if (!name.empty() && std::all_of(name.begin(), name.end(), [](char ch) { return ch >= '0' && ch <= '9'; })) {
    const std::size_t i = std::stoul(name);
    return i < c.phases.size() ? std::optional<std::size_t>(i) : std::nullopt;
  }
  const std::size_t from = after ? *after + 1 : 0;
  for (std::size_t pass = 0; pass < 2; ++pass) {  // after the open phase first, then from the start
    for (std::size_t i = pass == 0 ? from : 0; i < c.phases.size(); ++i) {
      const config::PhaseKind k = c.phases[i].kind;
      if (name == config::to_string(k) || name == config::phase_label(k)) return i;
    }
  }
  return std::nullopt;
}

}  // namespace

TestExecutive::TestExecutive(const config::BenchConfig& bench, std::map<std::string, std::shared_ptr<ControllerPort>> ports,
                             SpscRing<PlanMark>& marks, ExecutiveOptions options)
    : bench_(bench),
      ports_(std::move(ports)),
      marks_(marks),
      options_(std::move(options)),
      verifier_(options_.keys),
      operator_gid_(operator_group_id(options_.operator_group)) {
  for (const config::ModbusDevice& device : bench_.modbus_devices) {
    const auto port = ports_.find(device.name);
    for (std::size_t r = 0; r < device.registers.size(); ++r) {
      const config::ModbusRegister& reg = device.registers[r];
      if (reg.role == RegisterRole::None || reg.role == RegisterRole::Heartbeat) continue;
      Binding b{&device, &reg, r, port == ports_.end() ? nullptr : port->second};
      if (reg.role == RegisterRole::Fault) {
        if (b.port) faults_.push_back(b);
      } else {
        bindings_[reg.role] = b;
      }
    }
  }
}

TestExecutive::~TestExecutive() { stop("daemon stopping"); }

bool TestExecutive::ready(std::string* why) const {
  if (bench_.executive != config::Executive::Plan) return true;
  for (const auto& [role, b] : bindings_) {
    if (b.port) continue;
    if (why)
      *why = b.reg->role_at.file + ":" + std::to_string(b.reg->role_at.line) + ": executive = \"plan\" commands register '" +
             b.reg->name + "' (role = \"" + config::to_string(role) + "\") of device '" + b.device->name +
             "', which did not open: the plan cannot run without it (make the device available, or run with "
             "executive = \"operator\")";
    return false;
  }
  return true;
}

void TestExecutive::start() {
  thread_ = std::thread([this] { run(); });
}

void TestExecutive::stop(const std::string& reason) {
  {
    std::lock_guard lock(stop_mutex_);
    if (stop_reason_.empty()) {
      stop_reason_ = reason;
      stop_ns_ = hal::monotonic_now_ns();
    }
  }
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

// ---------------------------------------------------------------------------------------------
// The thread

void TestExecutive::run() noexcept {
  ::pthread_setname_np(::pthread_self(), "executive");
  // Whatever started the daemon, the bench starts at rest: the safe state is held from here until
  // an operator arms the plan.
  hold_safe_state();
  record("disarmed, safe state held");
  lcm_ = std::make_unique<lcm::LCM>(options_.lcm_url);
  if (lcm_->good()) {
    // Raw: bytes that do not decode are counted and dropped here, not printed by LCM.
    lcm_->subscribe(std::string(channels::kCommand), &TestExecutive::on_unsigned, this);
    lcm_->subscribe(std::string(channels::kCommandSigned), &TestExecutive::on_signed, this);
  } else {
    journal_plan({"refused", "plan: LCM did not start on '" + options_.lcm_url + "': signed requests from other machines are not heard", 4});
  }
  if (!operator_gid_)
    journal_plan({"start", "plan: the system has no group '" + options_.operator_group + "': only root and the daemon's own user are "
                                                                                          "operators on this machine",
                  4});
  try {
    report_start(wait_for_first_polls());
    if (options_.arm_at_start) {
      // An attended start arms once the safe state the daemon starts in is accounted for.
      while (account_) pump(false);
      const auto [ok, detail] = operator_arm(options_.armed_by);
      journal_plan({ok ? "arm" : "refused", "plan: " + std::string(ok ? "" : "not armed: ") + detail, ok ? 5 : 4});
    }
    while (!stop_.load(std::memory_order_acquire)) {
      try {
        pump(false);
        if (arm_pending_) {
          arm_pending_ = false;
          for (const auto& [name, port] : ports_) lapses_at_start_[name] = port->heartbeat().lapses;
          run_plan();
          plan_finished_.store(true, std::memory_order_release);
          hold_safe_state();
          armed_.store(false, std::memory_order_release);
          record("disarmed after the plan's end, safe state held");
          account_safe_state("plan: finished: every case ran; disarmed", std::string(), 6, hal::monotonic_now_ns(), std::nullopt);
        }
      } catch (const Aborted& a) {
        abort(a.reason, a.t_ns);
      }
    }
  } catch (const Aborted& a) {
    abort(a.reason, a.t_ns);
  } catch (const std::exception& e) {
    abort(std::string("error in the test executive: ") + e.what(), hal::monotonic_now_ns());
  }
  close_safe_state_account(true);
  lcm_.reset();
}

std::vector<std::string> TestExecutive::wait_for_first_polls() {
  // Settling, faults and the start's report are judged on polls: every controller answers first.
  std::set<ControllerPort*> needed;
  for (const auto& [name, port] : ports_) needed.insert(port.get());
  const std::int64_t deadline = hal::monotonic_now_ns() + 10 * kNsPerS;
  for (;;) {
    std::vector<std::string> silent;
    for (ControllerPort* p : needed)
      if (p->latest().last_valid_ns == 0) silent.push_back(p->device());
    if (silent.empty() || hal::monotonic_now_ns() > deadline) return silent;
    pump(false);
  }
}

void TestExecutive::report_start(const std::vector<std::string>& silent) {
  const RunRecorder* recorder = options_.record;
  if (recorder != nullptr && !recorder->previous_error().empty()) {
    journal_plan({"start", "plan: the previous run's record is unreadable (" + recorder->previous_error() + ")", 4});
  } else if (recorder != nullptr && recorder->previous()) {
    const RunRecord& r = *recorder->previous();
    const std::string run = "the previous run (pid " + std::to_string(r.pid) + ", bench " + r.bench + ", started " + r.started + ")";
    if (r.ended)
      journal_plan({"start", "plan: " + run + " ended at " + r.updated + ": " + r.activity, 6});
    else
      journal_plan({"start", "plan: " + run + " did not end: it was killed or crashed after " + r.updated + ", when it was " +
                                 (r.armed ? "ARMED: " : "disarmed: ") + r.activity + "; this run starts disarmed", r.armed ? 3 : 4});
  }
  // What the controllers report now: every reading a command role is judged by.
  std::ostringstream found;
  for (const auto& [role, b] : bindings_) {
    if (!b.port) continue;
    const ControllerPort::Poll poll = b.port->latest();
    for (const std::string& name : {b.reg->measured, b.reg->settled_by}) {
      const auto r = name.empty() ? std::nullopt : config::find_register(*b.device, name);
      if (!r || *r >= poll.valid.size()) continue;
      found << (found.tellp() > 0 ? ", " : "") << b.device->name << "." << name << " = ";
      if (!poll.valid[*r]) found << "no valid reading";
      else if (name == b.reg->settled_by) found << "0x" << std::hex << bits_of(poll.values[*r]) << std::dec;
      else found << value_text(b, poll.values[*r]);
    }
  }
  std::string text = "plan: started disarmed";
  if (found.tellp() > 0) text += "; found " + found.str();
  for (const std::string& d : silent) text += "; device '" + d + "' gave no valid reading in 10 s";
  text += bench_.executive == config::Executive::Plan ? "; the plan waits for an operator's arm (inertia-daqd arm)"
                                                      : "; phases are marked by the operator (inertia-daqd mark)";
  journal_plan({"start", text, silent.empty() ? 6 : 4});
  account_safe_state("plan: daemon start", std::string(), 6, hal::monotonic_now_ns(), std::nullopt);
}

void TestExecutive::run_plan() {
  journal_plan({"plan-start", "plan: running the plan of bench " + bench_.name + " (" + std::to_string(bench_.cases.size()) +
                                  " cases) on its controllers (executive = \"plan\")"});
  for (std::size_t c = 0; c < bench_.cases.size(); ++c) {
    begin_case(c, hal::monotonic_now_ns());
    const config::TestCase& tc = bench_.cases[c];
    for (std::size_t p = 0; p < tc.phases.size(); ++p) {
      pump(true);
      const std::int64_t commanded = hal::monotonic_now_ns();
      if (open_->phase) end_phase(commanded);
      std::int64_t start = commanded;
      record("case " + tc.name + ", phase " + std::to_string(p) + " (" + config::to_string(tc.phases[p].kind) + ") commanded");
      try {
        for (const config::PhaseCommand& command : config::phase_commands(tc, p))
          if (bindings_.count(command.role) != 0) start = std::max(start, execute(command, c, p, commanded));
      } catch (const PhaseFailed& f) {
        const std::int64_t now = hal::monotonic_now_ns();
        mark(plan_event_t::MARK_PHASE_FAILED, c, static_cast<std::int32_t>(p), now, commanded, now);
        journal_plan({"phase-failed", "plan: phase failed: " + phase_text(c, p) + ": " + f.reason + "; the plan stops", 4, tc.name,
                      std::to_string(p) + " " + config::phase_label(tc.phases[p].kind), f.device});
        throw Aborted{"phase failed: " + f.reason, now};
      }
      begin_phase(p, start);
      journal_plan({"phase-start", "plan: " + phase_text(c, p) + " started" +
                                       (start > commanded ? ", settled " + s_text(start - commanded) + " after its command" : ""),
                    6, tc.name, std::to_string(p) + " " + config::phase_label(tc.phases[p].kind)});
      const std::int64_t end = start + hal::seconds_to_ns(tc.phases[p].duration_s);
      while (hal::monotonic_now_ns() < end) pump(true);
    }
    end_case(hal::monotonic_now_ns());
  }
}

std::int64_t TestExecutive::execute(const config::PhaseCommand& command, std::size_t c, std::size_t p, std::int64_t commanded_ns) {
  const Binding& b = bindings_.at(command.role);
  const auto held = holds_.find(command.role);
  if (held != holds_.end() && held->second == command.value) return commanded_ns;  // already there, settled
  holds_.erase(command.role);
  const std::string what = b.device->name + "." + b.reg->name + " = " + value_text(b, command.value);
  const std::int64_t answer_ns = hal::seconds_to_ns(b.device->response_timeout_s * 3 + kAnswerMarginS);
  int steps = 0;
  ControllerPort::Outcome outcome;
  for (;;) {
    const std::int64_t posted = hal::monotonic_now_ns();
    const std::uint64_t ticket = b.port->post(b.index, command.value);
    std::optional<ControllerPort::Outcome> answer;
    while (!(answer = b.port->take_outcome(ticket))) {
      if (hal::monotonic_now_ns() - posted > answer_ns)
        throw PhaseFailed{what + ": the controller's polling thread gave no answer in " + s_text(answer_ns), b.device->name};
      pump(true);
    }
    outcome = *answer;
    ++steps;
    const auto& r = outcome.result;
    if (r.status != hal::modbus::WriteStatus::Written) {
      std::string why = what + ": " + hal::modbus::to_string(r.status);
      if (r.status == hal::modbus::WriteStatus::NotConfirmed)
        why = what + ": written as " + value_text(b, r.written) + " but read back " +
              (std::isnan(r.read_back) ? std::string("nothing (the read failed)") : value_text(b, r.read_back)) +
              ": the controller did not confirm the command";
      throw PhaseFailed{why, b.device->name};
    }
    if (!r.rate_limited) break;
    // Ramping: the next step one tick after this one was posted.
    while (hal::monotonic_now_ns() < posted + hal::seconds_to_ns(kRampTickS)) pump(true);
  }
  const auto& r = outcome.result;
  std::ostringstream line;
  line << "plan: " << phase_text(c, p) << ": " << b.device->name << "." << b.reg->name << " = " << value_text(b, r.written)
       << " confirmed (read back " << value_text(b, r.read_back) << ")";
  if (steps > 1) line << ", ramped in " << steps << " steps over " << s_text(outcome.t_ns - commanded_ns);
  if (r.clamped) line << ", clamped from " << value_text(b, command.value);
  journal_plan({"command", line.str(), 6, bench_.cases[c].name, std::to_string(p), b.device->name});
  const std::int64_t settled = settle(b, r.written, outcome.t_ns, c, p);
  holds_[command.role] = command.value;
  return settled;
}

std::int64_t TestExecutive::settle(const Binding& b, double target, std::int64_t confirmed_ns, std::size_t c, std::size_t p) {
  const config::ModbusRegister& reg = *b.reg;
  std::optional<std::size_t> reading;
  if (!reg.measured.empty()) reading = config::find_register(*b.device, reg.measured);
  if (!reg.settled_by.empty()) reading = config::find_register(*b.device, reg.settled_by);
  if (!reading) return confirmed_ns;  // no settling criterion: the confirmed write is the start
  const std::string criterion =
      !reg.measured.empty()
          ? reg.measured + " within " + value_text(b, reg.tolerance) + " of " + value_text(b, target)
          : reg.settled_by + (reg.role == RegisterRole::ShakerRun ? (target != 0.0 ? " reporting running" : " reporting stopped")
                                                                   : " reporting settled");
  auto settled_now = [&](double value) {
    if (!reg.measured.empty()) return std::abs(value - target) <= reg.tolerance;
    const std::uint32_t bits = bits_of(value);
    const std::uint32_t mask = reg.settled_mask;
    // A run command's status mirrors it: the running bits set while it runs, clear once stopped.
    if (reg.role == RegisterRole::ShakerRun) return ((mask == 0 ? bits != 0 : (bits & mask) != 0)) == (target != 0.0);
    return mask == 0 ? bits != 0 : (bits & mask) == mask;
  };
  const std::int64_t deadline = confirmed_ns + hal::seconds_to_ns(reg.settle_timeout_s);
  const std::int64_t hold_ns = hal::seconds_to_ns(reg.settle_s);
  bool holding = false;            // the criterion has held since since_ns
  std::int64_t since_ns = 0;
  std::uint64_t seen = 0;
  double last = NAN;
  for (;;) {
    const ControllerPort::Poll poll = b.port->latest();
    if (poll.count != seen && poll.t_ns > confirmed_ns) {
      seen = poll.count;
      const bool valid = *reading < poll.valid.size() && poll.valid[*reading];
      if (valid) last = poll.values[*reading];
      if (valid && settled_now(last)) {
        if (!holding) since_ns = poll.t_ns;
        holding = true;
        if (poll.t_ns - since_ns >= hold_ns) {
          journal_plan({"settled", "plan: " + phase_text(c, p) + ": " + b.device->name + " settled (" + criterion + " for " +
                                       s_text(poll.t_ns - since_ns) + ") " + s_text(poll.t_ns - confirmed_ns) + " after the command",
                        6, bench_.cases[c].name, std::to_string(p), b.device->name});
          return poll.t_ns;
        }
      } else {
        holding = false;
      }
    }
    if (hal::monotonic_now_ns() > deadline) {
      std::ostringstream why;
      why << b.device->name << "." << reg.name << " = " << value_text(b, target) << " confirmed, but not settled ("
          << criterion << (reg.settle_s > 0 ? " for " + s_text(hold_ns) : std::string()) << ") within settle_timeout_s = "
          << reg.settle_timeout_s << " s; last reading of " << (reg.measured.empty() ? reg.settled_by : reg.measured) << ": ";
      if (std::isnan(last)) why << "none valid";
      else if (reg.measured.empty()) why << "0x" << std::hex << bits_of(last);
      else why << value_text(b, last);
      throw PhaseFailed{why.str(), b.device->name};
    }
    pump(true);
  }
}

void TestExecutive::pump(bool plan_running) {
  receive_commands();
  std::vector<Inbound> inbox;
  inbox.swap(inbox_);
  for (const Inbound& in : inbox) handle(in);
  watch_safe_state();
  close_safe_state_account(false);
  if (stop_.load(std::memory_order_acquire)) {
    std::lock_guard lock(stop_mutex_);
    throw Aborted{stop_reason_, stop_ns_};
  }
  if (stop_request_) throw Aborted{"operator stop by " + stop_request_->origin.who, hal::monotonic_now_ns()};
  if (plan_running) {
    // A lapsed heartbeat first: after a hang every controller also looks silent, and the lapse is the cause.
    if (auto fault = heartbeat_fault()) throw Aborted{*fault, hal::monotonic_now_ns()};
    if (auto fault = controller_fault()) throw Aborted{*fault, hal::monotonic_now_ns()};
  }
}

std::optional<std::string> TestExecutive::heartbeat_fault() const {
  const std::int64_t now = hal::monotonic_now_ns();
  for (const auto& [name, port] : ports_) {
    const ControllerPort::HeartbeatState h = port->heartbeat();
    if (!h.present) continue;
    const auto at_start = lapses_at_start_.find(name);
    const double timeout_s = static_cast<double>(h.timeout_ns) * 1e-9;
    std::ostringstream s;
    if (at_start != lapses_at_start_.end() && h.lapses > at_start->second) {
      s << "device fault: the heartbeat to controller " << name << " lapsed for " << std::setprecision(3) << h.last_lapse_s
        << " s, more than its timeout_s = " << timeout_s << " s: the controller has stopped its machine";
      return s.str();
    }
    if (h.last_written_ns != 0 && now - h.last_written_ns > h.timeout_ns) {
      s << "device fault: no heartbeat reached controller " << name << " for " << std::setprecision(3)
        << static_cast<double>(now - h.last_written_ns) * 1e-9 << " s, more than its timeout_s = " << timeout_s
        << " s: the controller has stopped its machine" << (h.last_failure.empty() ? "" : " (last write: " + h.last_failure + ")");
      return s.str();
    }
  }
  return std::nullopt;
}

std::optional<std::string> TestExecutive::controller_fault() const {
  for (const Binding& f : faults_) {
    const ControllerPort::Poll poll = f.port->latest();
    if (f.index >= poll.valid.size() || !poll.valid[f.index]) continue;
    const std::uint32_t bits = bits_of(poll.values[f.index]);
    const std::uint32_t set = f.reg->fault_mask == 0 ? bits : bits & f.reg->fault_mask;
    if (set != 0) {
      std::ostringstream s;
      s << "device fault: " << f.device->name << "." << f.reg->name << " = 0x" << std::hex << bits << " (fault bits 0x" << set << ")";
      return s.str();
    }
  }
  const std::int64_t now = hal::monotonic_now_ns();
  for (const auto& [role, b] : bindings_) {
    if (!b.port) continue;
    const ControllerPort::Poll poll = b.port->latest();
    // Silent: no valid answer for three polls and two response timeouts (one slow request is not a fault).
    const std::int64_t silent_ns = 3 * static_cast<std::int64_t>(b.device->poll_interval_ms) * 1'000'000 +
                                   hal::seconds_to_ns(2 * b.device->response_timeout_s);
    if (!poll.connected || now - poll.last_valid_ns > silent_ns)
      return "device fault: controller " + b.device->name + (poll.connected ? " gave no valid reading for " + s_text(now - poll.last_valid_ns)
                                                                              : std::string(" link down"));
  }
  return std::nullopt;
}

std::optional<std::string> TestExecutive::arm_refusal() const {
  if (bench_.executive != config::Executive::Plan)
    return "bench " + bench_.name + " is moved by its operator (executive = \"operator\"): the daemon commands no motion, "
           "so there is nothing to arm; mark its phases with inertia-daqd mark";
  if (armed()) return std::string("already armed: the plan is running") + (open_ ? " (case " + bench_.cases[open_->index].name + ")" : "");
  if (auto fault = controller_fault()) return *fault;
  for (const auto& [name, port] : ports_) {
    const ControllerPort::SafeState st = port->safe_state();
    if (port->has_safe_state() && !st.confirmed) {
      std::string failures;
      for (const std::string& f : st.failures) failures += (failures.empty() ? "" : "; ") + f;
      return "device '" + name + "' has not confirmed its safe state" + (failures.empty() ? std::string() : " (" + failures + ")") +
             ": where it is, is not known";
    }
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Abort and safe state

void TestExecutive::hold_safe_state() {
  for (auto& [name, port] : ports_)
    if (port->has_safe_state()) port->hold_safe_state();
}

void TestExecutive::account_safe_state(std::string headline, std::string case_name, int priority, std::int64_t since_ns,
                                       std::optional<Inbound> stop_request) {
  // A new account replaces one still open (a stop during a plan's end): its operator hears the new one.
  if (account_ && account_->stop_request && !stop_request) stop_request = account_->stop_request;
  double longest_s = 0.0;
  for (const auto& d : bench_.modbus_devices) longest_s = std::max(longest_s, d.response_timeout_s);
  // Each device's thread writes at once; one with a dead link gives up a round after its response
  // timeouts (and goes on trying, which the watch reports).
  account_ = SafeStateAccount{std::move(headline), std::move(case_name), since_ns,
                              hal::monotonic_now_ns() + hal::seconds_to_ns(4 * longest_s + 1.0), priority, std::move(stop_request)};
}

void TestExecutive::close_safe_state_account(bool final) {
  if (!account_) return;
  for (;;) {
    bool all = true;
    for (const auto& [name, port] : ports_) all = all && (!port->has_safe_state() || port->safe_state().confirmed);
    if (all || hal::monotonic_now_ns() > account_->deadline_ns) break;
    if (!final) return;
    timespec ts{0, 200'000};
    ::nanosleep(&ts, nullptr);
  }
  std::int64_t last = account_->since_ns;
  bool complete = true, any = false;
  std::ostringstream parts;
  for (const auto& [name, port] : ports_) {
    if (!port->has_safe_state()) continue;
    any = true;
    const ControllerPort::SafeState st = port->safe_state();
    parts << "; " << name << ": ";
    if (st.confirmed) {
      last = std::max(last, st.confirmed_ns);
      for (std::size_t i = 0; i < st.written.size(); ++i) parts << (i ? ", " : "") << st.written[i];
    } else {
      complete = false;
      parts << "NOT CONFIRMED";
      for (const std::string& f : st.failures) parts << ", " << f;
      if (st.failures.empty()) parts << ", no answer yet";
    }
  }
  std::string account;
  int priority = account_->priority;
  if (!any) {
    account = "no controller has a safe state the daemon can write (no `safe` register on a device with writes enabled)";
  } else if (complete) {
    account = "controllers in their safe state " + ms_text(last - account_->since_ns) + " after it" + parts.str();
  } else {
    account = "SAFE STATE NOT CONFIRMED on every controller (the daemon goes on trying; check the bench by hand)" + parts.str();
    priority = 3;
  }
  journal_plan({"safe-state", account_->headline + ": " + account, priority, account_->case_name});
  if (account_->stop_request)
    reply(*account_->stop_request, complete ? plan_command_t::STATUS_DONE : plan_command_t::STATUS_REFUSED, account);
  account_.reset();
}

void TestExecutive::watch_safe_state() {
  const std::int64_t now = hal::monotonic_now_ns();
  std::vector<std::string> faults;
  for (const auto& [name, port] : ports_) {
    if (!port->has_safe_state()) continue;
    const ControllerPort::SafeState st = port->safe_state();
    UnconfirmedWatch& w = unconfirmed_[name];
    const bool unconfirmed = st.held && !st.confirmed && !st.failures.empty();
    if (unconfirmed) {
      faults.push_back("safe-state-unconfirmed:" + name);
      if (!w.raised || now - w.journalled_ns >= hal::seconds_to_ns(kUnconfirmedRepeatS)) {
        std::string failures;
        for (const std::string& f : st.failures) failures += (failures.empty() ? "" : "; ") + f;
        journal_plan({"safe-state", std::string("plan: SAFE STATE NOT CONFIRMED on device '") + name + "'" +
                                        (w.raised ? " (still, " + s_text(now - st.held_ns) + " after it was commanded)" : "") + ": " +
                                        failures + "; retrying every " + s_text(hal::seconds_to_ns(ControllerPort::kSafeRetryS)),
                      3, std::string(), std::string(), name});
        w.journalled_ns = now;
      }
      w.raised = true;
    } else if (w.raised && st.confirmed) {
      journal_plan({"safe-state", "plan: safe state confirmed on device '" + name + "' " + s_text(st.confirmed_ns - st.held_ns) +
                                      " after it was commanded (" + std::to_string(st.attempts) + " attempts)",
                    5, std::string(), std::string(), name});
      w.raised = false;
    }
  }
  std::lock_guard lock(faults_mutex_);
  faults_now_ = std::move(faults);
}

std::vector<std::string> TestExecutive::faults() const {
  std::lock_guard lock(faults_mutex_);
  return faults_now_;
}

void TestExecutive::abort(const std::string& reason, std::int64_t t_ns) {
  // An operator stop commanded the safe state when it arrived; everything else does it here.
  if (!stop_request_) hold_safe_state();
  const bool was_armed = armed_.exchange(false, std::memory_order_acq_rel);
  arm_pending_ = false;
  int priority = open_ ? 4 : 6;
  std::string where = "no case was running";
  std::string case_name;
  if (open_) {
    const config::TestCase& tc = bench_.cases[open_->index];
    case_name = tc.name;
    where = open_->phase ? phase_text(open_->index, *open_->phase) : "case " + tc.name;
    mark(plan_event_t::MARK_ABORT, open_->index, open_->phase ? static_cast<std::int32_t>(*open_->phase) : -1, t_ns,
         open_->start_ns, t_ns);
  }
  record("disarmed by an abort (" + reason + ") during " + where + ", safe state held");
  account_safe_state((open_ ? "plan: abort (" + reason + ") during " + where : "plan: " + reason + ", " + where) +
                         (was_armed ? "; disarmed" : ""),
                     case_name, priority, t_ns, stop_request_);
  open_.reset();
  holds_.clear();
  stop_request_.reset();
}

void TestExecutive::record(const std::string& activity) {
  if (options_.record == nullptr) return;
  std::string why;
  if (!options_.record->update(armed(), activity, &why))
    journal_plan({"refused", "plan: the run record could not be written (" + why + "): a crash now leaves no account", 4});
}

// ---------------------------------------------------------------------------------------------
// Markers

void TestExecutive::mark(std::int8_t what, std::size_t case_index, std::int32_t phase_index, std::int64_t t_ns,
                         std::int64_t start_ns, std::int64_t end_ns) {
  if (!marks_.try_push(PlanMark{t_ns, start_ns, end_ns, static_cast<std::int32_t>(case_index), phase_index, what}))
    journal_plan({"refused", "plan: the marker ring is full: a marker of case " + bench_.cases[case_index].name + " was lost", 3});
}

void TestExecutive::begin_case(std::size_t case_index, std::int64_t t_ns) {
  open_ = OpenCase{case_index, t_ns, std::nullopt, 0};
  mark(plan_event_t::MARK_CASE_START, case_index, -1, t_ns, t_ns, 0);  // end unknown: phases start when settled
}

void TestExecutive::begin_phase(std::size_t phase_index, std::int64_t t_ns) {
  open_->phase = phase_index;
  open_->phase_start_ns = t_ns;
  const double duration = bench_.cases[open_->index].phases[phase_index].duration_s;
  mark(plan_event_t::MARK_PHASE_START, open_->index, static_cast<std::int32_t>(phase_index), t_ns, t_ns, t_ns + hal::seconds_to_ns(duration));
}

void TestExecutive::end_phase(std::int64_t t_ns) {
  if (!open_ || !open_->phase) return;
  mark(plan_event_t::MARK_PHASE_END, open_->index, static_cast<std::int32_t>(*open_->phase), t_ns, open_->phase_start_ns, t_ns);
  open_->phase.reset();
}

void TestExecutive::end_case(std::int64_t t_ns) {
  if (!open_) return;
  end_phase(t_ns);
  mark(plan_event_t::MARK_CASE_END, open_->index, -1, t_ns, open_->start_ns, t_ns);
  journal_plan({"case-end", "plan: case " + bench_.cases[open_->index].name + " ended after " + s_text(t_ns - open_->start_ns), 6,
                bench_.cases[open_->index].name});
  open_.reset();
}

// ---------------------------------------------------------------------------------------------
// Operator commands (INERTIA_COMMAND)

void TestExecutive::receive_commands() {
  std::vector<pollfd> fds;
  const bool lcm_up = lcm_ && lcm_->good();
  if (lcm_up) fds.push_back({lcm_->getFileno(), POLLIN, 0});
  if (options_.socket) options_.socket->add_poll_fds(fds);
  if (fds.empty()) {
    timespec ts{0, static_cast<long>(kLoopS * 1e9)};
    ::nanosleep(&ts, nullptr);
    return;
  }
  (void)::poll(fds.data(), fds.size(), static_cast<int>(kLoopS * 1000));
  if (lcm_up && (fds[0].revents & POLLIN) != 0)
    while (lcm_->handleTimeout(0) > 0) {
    }
  if (!options_.socket) return;
  const uid_t daemon_uid = ::getuid();
  for (CommandSocket::Request& r : options_.socket->take_requests()) {
    Inbound in;
    in.command = std::move(r.command);
    in.connection = r.connection;
    in.origin.path = CommandOrigin::Path::Socket;
    in.origin.operator_ = is_operator(r.peer.uid, r.peer.gid, r.peer.groups, daemon_uid, operator_gid_);
    in.origin.who = describe_uid(r.peer.uid) + ", pid " + std::to_string(r.peer.pid);
    inbox_.push_back(std::move(in));
  }
}

void TestExecutive::on_unsigned(const lcm::ReceiveBuffer* rbuf, const std::string&) {
  plan_command_t command{};
  if (command.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) != static_cast<int>(rbuf->data_size)) {
    refused_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  if (command.status != plan_command_t::STATUS_REQUEST) return;
  Inbound in;
  in.command = command;
  in.origin = CommandOrigin{CommandOrigin::Path::Unsigned, false, "unsigned request claiming to be " + command.sender};
  inbox_.push_back(std::move(in));
}

void TestExecutive::on_signed(const lcm::ReceiveBuffer* rbuf, const std::string&) {
  signed_command_t decoded{};
  if (decoded.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) != static_cast<int>(rbuf->data_size)) {
    refused_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const signed_command_t* request = &decoded;
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  const std::int64_t now_us = static_cast<std::int64_t>(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
  SignedCommandVerifier::Verdict v = verifier_.verify(*request, now_us);
  Inbound in;
  in.origin = CommandOrigin{CommandOrigin::Path::Signed, true, "key " + request->key_id};
  if (v.repeat) {
    if (const auto seen = answered_.find(std::make_pair(v.command.sender, v.command.id)); seen != answered_.end() && lcm_ && lcm_->good())
      lcm_->publish(std::string(channels::kCommandReply), &seen->second);
    return;
  }
  if (v.ok) {
    if (v.command.status != plan_command_t::STATUS_REQUEST) return;
    in.command = std::move(v.command);
    inbox_.push_back(std::move(in));
    return;
  }
  // Refused before anything in it is trusted; what it names is used only to address the answer.
  (void)in.command.decode(request->command.data(), 0, request->command_size);
  in.origin.operator_ = false;
  in.origin.who = "key " + request->key_id + " (not verified)";
  reply(in, plan_command_t::STATUS_REFUSED, "refused: " + v.why);
  account_command(in, false, v.why);
}

void TestExecutive::handle(const Inbound& in) {
  const plan_command_t& command = in.command;
  if (in.connection < 0) {
    const auto key = std::make_pair(command.sender, command.id);
    if (const auto seen = answered_.find(key); seen != answered_.end()) {
      // A repeat of a request already acted on (the sender did not hear the answer): answer again.
      if (lcm_ && lcm_->good()) lcm_->publish(std::string(channels::kCommandReply), &seen->second);
      return;
    }
  }
  if (const auto why = refusal(in.origin, command.command, options_.operator_group)) {
    reply(in, plan_command_t::STATUS_REFUSED, *why);
    account_command(in, false, *why);
    return;
  }
  switch (command.command) {
    case plan_command_t::COMMAND_STOP: {
      // Every controller is commanded now, before anything else; the abort (the plan may be in
      // the middle of a phase) and the confirmation follow, the latter as a second answer.
      const std::int64_t t0 = hal::monotonic_now_ns();
      hold_safe_state();
      const std::string detail =
          "stop received: every controller commanded to its safe state " + ms_text(hal::monotonic_now_ns() - t0) + " after; its confirmation follows";
      reply(in, plan_command_t::STATUS_ACCEPTED, detail);
      account_command(in, true, detail);
      stop_request_ = in;
      return;
    }
    case plan_command_t::COMMAND_MARK:
    case plan_command_t::COMMAND_END_CASE:
    case plan_command_t::COMMAND_ARM: {
      const auto [ok, detail] = command.command == plan_command_t::COMMAND_MARK       ? operator_mark(command, in.origin.who)
                                : command.command == plan_command_t::COMMAND_END_CASE ? operator_end_case()
                                                                                      : operator_arm(in.origin.who);
      reply(in, ok ? plan_command_t::STATUS_ACCEPTED : plan_command_t::STATUS_REFUSED, detail);
      account_command(in, ok, detail);
      return;
    }
    default: {
      const std::string why = "unknown command " + std::to_string(command.command);
      reply(in, plan_command_t::STATUS_REFUSED, why);
      account_command(in, false, why);
    }
  }
}

void TestExecutive::account_command(const Inbound& in, bool accepted, const std::string& detail) {
  static const char* const kNames[] = {"none", "mark", "end", "stop", "arm"};
  const std::int8_t c = in.command.command;
  const std::string name = c >= 1 && c <= 4 ? kNames[c] : "command-" + std::to_string(c);
  const bool unsigned_request = in.origin.path == CommandOrigin::Path::Unsigned;
  const std::string result = accepted ? "accepted" : unsigned_request ? "ignored" : "refused";
  (accepted ? accepted_ : unsigned_request ? unsigned_ : refused_).fetch_add(1, std::memory_order_relaxed);
  journal_command({in.origin.who, name, result, "command: " + name + " from " + in.origin.who + ": " + result + ": " + detail,
                   accepted ? 5 : 4});
  if (!accepted || options_.operator_records == nullptr) return;
  plan_command_t record = in.command;
  record.status = plan_command_t::STATUS_ACCEPTED;
  record.sender = in.origin.who + (in.command.sender.empty() ? std::string() : " as " + in.command.sender);
  record.detail = detail;
  OperatorRecord slot;
  const int size = record.getEncodedSize();
  if (size <= 0 || static_cast<std::size_t>(size) > slot.bytes.size()) return;
  slot.size = static_cast<std::uint16_t>(size);
  (void)record.encode(slot.bytes.data(), 0, size);
  if (!options_.operator_records->try_push(slot))
    journal_plan({"refused", "plan: the operator record ring is full: who sent a request is not in the log", 3});
}

std::array<std::int64_t, 3> TestExecutive::command_counts() const {
  const std::int64_t dropped = options_.socket ? static_cast<std::int64_t>(options_.socket->dropped()) : 0;
  return {accepted_.load(std::memory_order_relaxed), refused_.load(std::memory_order_relaxed) + dropped,
          unsigned_.load(std::memory_order_relaxed)};
}

std::pair<bool, std::string> TestExecutive::operator_arm(const std::string& who) {
  if (const auto refusal = arm_refusal()) return {false, "arm refused: " + *refusal};
  for (auto& [name, port] : ports_) port->release_safe_state();
  armed_.store(true, std::memory_order_release);
  arm_pending_ = true;
  holds_.clear();
  record("armed by " + who + ": the plan starts");
  const std::string detail = "armed by " + who + ": the plan of bench " + bench_.name + " starts now (" +
                             std::to_string(bench_.cases.size()) + " cases); inertia-daqd mark --stop stops it";
  journal_plan({"arm", "plan: " + detail, 5});
  return {true, detail};
}

std::pair<bool, std::string> TestExecutive::operator_mark(const plan_command_t& command, const std::string& who) {
  if (bench_.executive == config::Executive::Plan)
    return {false, "the test executive runs this bench's plan (executive = \"plan\") and marks its phases itself; "
                   "`inertia-daqd mark --stop` aborts it"};
  std::size_t c = bench_.cases.size();
  for (std::size_t i = 0; i < bench_.cases.size(); ++i)
    if (bench_.cases[i].name == command.case_name) c = i;
  if (c == bench_.cases.size()) {
    std::string known;
    for (const auto& tc : bench_.cases) known += (known.empty() ? "" : ", ") + tc.name;
    return {false, "no case '" + command.case_name + "' in the plan of bench " + bench_.name +
                       (known.empty() ? " (it has no [[case]])" : " (cases: " + known + ")")};
  }
  std::optional<std::size_t> phase;
  if (!command.phase.empty()) {
    const std::optional<std::size_t> after = open_ && open_->index == c ? open_->phase : std::nullopt;
    phase = find_phase(bench_.cases[c], command.phase, after);
    if (!phase) {
      std::string known;
      for (std::size_t i = 0; i < bench_.cases[c].phases.size(); ++i)
        known += (i ? ", " : "") + std::to_string(i) + " " + config::to_string(bench_.cases[c].phases[i].kind);
      return {false, "case " + command.case_name + " has no phase '" + command.phase + "' (its phases: " + known + ")"};
    }
  }
  // Stamped at receipt, on the daemon's clock: the marker lines up with the samples.
  const std::int64_t now = hal::monotonic_now_ns();
  std::string detail;
  if (!open_ || open_->index != c) {
    if (open_) {
      detail = "case " + bench_.cases[open_->index].name + " ended; ";
      end_case(now);
    }
    begin_case(c, now);
    detail += "case " + command.case_name + " started";
  }
  if (phase) {
    end_phase(now);
    begin_phase(*phase, now);
    detail += std::string(detail.empty() ? "" : "; ") + phase_text(c, *phase) + " started";
  }
  if (detail.empty()) detail = "case " + command.case_name + " is already running: nothing marked";
  journal_plan({"operator-mark", "plan: operator " + who + ": " + detail, 6, command.case_name,
                phase ? std::to_string(*phase) + " " + config::phase_label(bench_.cases[c].phases[*phase].kind) : std::string()});
  return {true, detail};
}

std::pair<bool, std::string> TestExecutive::operator_end_case() {
  if (bench_.executive == config::Executive::Plan)
    return {false, "the test executive runs this bench's plan (executive = \"plan\") and ends its cases itself"};
  if (!open_) return {false, "no case is running"};
  const std::string name = bench_.cases[open_->index].name;
  end_case(hal::monotonic_now_ns());
  return {true, "case " + name + " ended"};
}

void TestExecutive::reply(const Inbound& request, std::int8_t status, const std::string& detail) {
  plan_command_t answer = request.command;
  answer.status = status;
  answer.detail = detail;
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  answer.utime = static_cast<std::int64_t>(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
  if (request.connection >= 0) {
    if (options_.socket) (void)options_.socket->reply(request.connection, answer);
    return;
  }
  answered_[std::make_pair(answer.sender, answer.id)] = answer;
  if (lcm_ && lcm_->good()) lcm_->publish(std::string(channels::kCommandReply), &answer);
}

// ---------------------------------------------------------------------------------------------

std::string TestExecutive::phase_text(std::size_t c, std::size_t p) const {
  const config::TestCase& tc = bench_.cases[c];
  return "case " + tc.name + " phase " + std::to_string(p) + " (" + config::to_string(tc.phases[p].kind) + ")";
}

std::string TestExecutive::value_text(const Binding& b, double value) const {
  std::ostringstream s;
  s << value;
  if (!b.reg->unit.empty()) s << " " << b.reg->unit;
  return s.str();
}

}  // namespace inertia::daq
