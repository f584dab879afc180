#include "daq/controller_port.hpp"

#include <chrono>
#include <cmath>
#include <sstream>

#include "hal/device.hpp"

namespace inertia::daq {
ControllerPort::ControllerPort(std::string device, std::vector<SafeValue> safe_values, std::optional<Heartbeat> heartbeat,
                               std::shared_ptr<const LifeSign> life)
    : device_(std::move(device)),
      safe_values_(std::move(safe_values)),
      heartbeat_spec_(heartbeat),
      life_(std::move(life)),
      safe_confirmed_(safe_values_.size(), false) {
  beat_.present = heartbeat_spec_.has_value();
  if (heartbeat_spec_) beat_.timeout_ns = heartbeat_spec_->timeout_ns;
  if (heartbeat_spec_) beat_value_ = heartbeat_spec_->max;   // the first write wraps to min
}

std::uint64_t ControllerPort::post(std::size_t register_index, double value) {
  std::uint64_t ticket = 0;
  {
    std::lock_guard lock(mutex_);
    ticket = next_ticket_++;
    queue_.push_back(Command{ticket, register_index, value});
  }
  posted_.notify_one();
  return ticket;
}

std::optional<ControllerPort::Outcome> ControllerPort::take_outcome(std::uint64_t ticket) {
  std::lock_guard lock(mutex_);
  const auto it = outcomes_.find(ticket);
  if (it == outcomes_.end()) return std::nullopt;
  Outcome out = it->second;
  outcomes_.erase(it);
  return out;
}

void ControllerPort::hold_safe_state() {
  {
    std::lock_guard lock(mutex_);
    // Commands still queued belong to the plan being stopped: their tickets answer "link error"
    // (never sent), so no caller waits on them.
    for (const Command& c : queue_) {
      Outcome dropped;
      dropped.result.status = hal::modbus::WriteStatus::LinkError;
      dropped.t_ns = hal::monotonic_now_ns();
      outcomes_[c.ticket] = dropped;
    }
    queue_.clear();
    const std::uint64_t round = safe_.round + 1;
    safe_ = SafeState{};
    safe_.held = true;
    safe_.round = round;
    safe_.held_ns = hal::monotonic_now_ns();
    safe_.confirmed = safe_values_.empty();
    if (safe_.confirmed) safe_.confirmed_ns = safe_.held_ns;
    safe_confirmed_.assign(safe_values_.size(), false);
    next_safe_attempt_ns_ = 0;
  }
  posted_.notify_one();
}

void ControllerPort::release_safe_state() {
  std::lock_guard lock(mutex_);
  safe_.held = false;
}

ControllerPort::SafeState ControllerPort::safe_state() const {
  std::lock_guard lock(mutex_);
  return safe_;
}

ControllerPort::HeartbeatState ControllerPort::heartbeat() const {
  std::lock_guard lock(mutex_);
  return beat_;
}

ControllerPort::Poll ControllerPort::latest() const {
  std::lock_guard lock(mutex_);
  return poll_;
}

void ControllerPort::serve_safe_state(hal::modbus::ModbusController& controller, std::int64_t now_ns) {
  std::vector<std::size_t> pending;
  {
    std::lock_guard lock(mutex_);
    if (!safe_.held) return;
    // A controller that lost its link may have lost what it was told: after a reconnect the safe
    // values go out again.
    if (safe_.confirmed && controller.link().health().reconnects != reconnects_seen_) {
      safe_.confirmed = false;
      safe_confirmed_.assign(safe_values_.size(), false);
      next_safe_attempt_ns_ = 0;
    }
    if (safe_.confirmed || now_ns < next_safe_attempt_ns_) return;
    for (std::size_t i = 0; i < safe_values_.size(); ++i)
      if (!safe_confirmed_[i]) pending.push_back(i);
    ++safe_.attempts;
  }
  // After a failure the link may be in its back-off: a safe value does not wait for it.
  if (!controller.link().connected()) controller.link().reconnect_now();
  std::vector<std::pair<std::size_t, std::string>> written, failed;
  for (std::size_t i : pending) {
    const SafeValue& v = safe_values_[i];
    const hal::modbus::WriteResult r = controller.write(v.register_index, v.value, hal::modbus::Ramp::Immediate);
    const auto& spec = controller.config().map.registers[v.register_index];
    std::ostringstream line;
    if (r.status == hal::modbus::WriteStatus::Written) {
      line << spec.name << " = " << r.written;
      written.emplace_back(i, line.str());
    } else {
      line << spec.name << ": " << hal::modbus::to_string(r.status);
      if (r.status == hal::modbus::WriteStatus::NotConfirmed && !std::isnan(r.read_back)) line << " (reads " << r.read_back << ")";
      if (!controller.link().health().last_error.empty() && r.status == hal::modbus::WriteStatus::LinkError)
        line << " (" << controller.link().health().last_error << ")";
      failed.emplace_back(i, line.str());
    }
  }
  const std::int64_t done_ns = hal::monotonic_now_ns();
  std::lock_guard lock(mutex_);
  if (!safe_.held) return;   // released while the writes went out: the plan was armed meanwhile
  for (const auto& [i, text] : written) {
    safe_confirmed_[i] = true;
    safe_.written.push_back(text);
  }
  safe_.failures.clear();
  for (const auto& [i, text] : failed) safe_.failures.push_back(text);
  if (failed.empty()) {
    safe_.confirmed = true;
    safe_.confirmed_ns = done_ns;
    reconnects_seen_ = controller.link().health().reconnects;
  } else {
    next_safe_attempt_ns_ = done_ns + hal::seconds_to_ns(kSafeRetryS);
  }
}

void ControllerPort::serve_heartbeat(hal::modbus::ModbusController& controller, std::int64_t now_ns) {
  if (!heartbeat_spec_ || now_ns < next_beat_ns_) return;
  if (life_ && !life_->alive(now_ns)) return;   // a hung daemon stops proving life
  const Heartbeat& h = *heartbeat_spec_;
  next_beat_ns_ = now_ns + h.period_ns;
  beat_value_ = beat_value_ + h.step > h.max + 0.5 * h.step ? h.min : beat_value_ + h.step;
  const hal::modbus::WriteResult r = controller.write(h.register_index, beat_value_, hal::modbus::Ramp::Immediate);
  std::lock_guard lock(mutex_);
  if (r.status == hal::modbus::WriteStatus::Written) {
    const std::int64_t written_ns = hal::monotonic_now_ns();
    if (beat_.last_written_ns != 0 && written_ns - beat_.last_written_ns > h.timeout_ns) {
      ++beat_.lapses;
      beat_.last_lapse_s = static_cast<double>(written_ns - beat_.last_written_ns) * 1e-9;
    }
    ++beat_.written;
    beat_.last_written_ns = written_ns;
  } else {
    ++beat_.failed;
    beat_.last_failure = hal::modbus::to_string(r.status);
  }
}

void ControllerPort::serve(hal::modbus::ModbusController& controller) {
  // The safe state first: it never waits behind a queued command or a heartbeat.
  serve_safe_state(controller, hal::monotonic_now_ns());
  serve_heartbeat(controller, hal::monotonic_now_ns());
  for (;;) {
    Command c{};
    bool refused = false;
    {
      std::lock_guard lock(mutex_);
      if (queue_.empty()) return;
      c = queue_.front();
      queue_.pop_front();
      refused = safe_.held;
    }
    Outcome out;
    if (refused) {
      out.result.status = hal::modbus::WriteStatus::Disabled;   // the safe state is held: nothing moves
    } else {
      out.result = controller.write(c.register_index, c.value, hal::modbus::Ramp::Limited);
    }
    out.t_ns = hal::monotonic_now_ns();
    std::lock_guard lock(mutex_);
    outcomes_[c.ticket] = out;
  }
}

void ControllerPort::wait_until(std::int64_t until_ns) {
  std::unique_lock lock(mutex_);
  const std::int64_t left = until_ns - hal::monotonic_now_ns();
  if (left <= 0) return;
  posted_.wait_for(lock, std::chrono::nanoseconds(left), [this] {
    return !queue_.empty() || (safe_.held && !safe_.confirmed && next_safe_attempt_ns_ == 0);
  });
}

void ControllerPort::publish(std::span<const hal::modbus::PolledValue> values, bool connected) {
  std::lock_guard lock(mutex_);
  ++poll_.count;
  poll_.connected = connected;
  poll_.values.resize(values.size());
  poll_.valid.resize(values.size());
  bool any = false;
  for (std::size_t i = 0; i < values.size(); ++i) {
    poll_.values[i] = values[i].value;
    poll_.valid[i] = values[i].valid;
    any = any || values[i].valid;
    poll_.t_ns = std::max(poll_.t_ns, values[i].t_ns);
  }
  if (any) poll_.last_valid_ns = poll_.t_ns;
}

}  // namespace inertia::daq
