#include "daq/controller_port.hpp"

#include <chrono>
#include <sstream>

#include "hal/device.hpp"

namespace inertia::daq {

ControllerPort::ControllerPort(std::string device, std::vector<SafeValue> safe_values)
    : device_(std::move(device)), safe_values_(std::move(safe_values)) {}

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

void ControllerPort::request_safe_state() {
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
    safe_pending_ = true;
    safe_ = SafeState{};
    safe_.requested = true;
    safe_.requested_ns = hal::monotonic_now_ns();
  }
  posted_.notify_one();
}

ControllerPort::SafeState ControllerPort::safe_state() const {
  std::lock_guard lock(mutex_);
  return safe_;
}

ControllerPort::Poll ControllerPort::latest() const {
  std::lock_guard lock(mutex_);
  return poll_;
}

void ControllerPort::serve(hal::modbus::ModbusController& controller) {
  // The safe state first: it never waits behind a queued command.
  bool safe = false;
  {
    std::lock_guard lock(mutex_);
    safe = safe_pending_;
    safe_pending_ = false;
  }
  if (safe) {
    std::vector<std::string> written, failures;
    for (const SafeValue& v : safe_values_) {
      const hal::modbus::WriteResult r = controller.write(v.register_index, v.value, hal::modbus::Ramp::Immediate);
      const auto& spec = controller.config().map.registers[v.register_index];
      std::ostringstream line;
      if (r.status == hal::modbus::WriteStatus::Written) {
        line << spec.name << " = " << r.written;
        written.push_back(line.str());
      } else {
        line << spec.name << ": " << hal::modbus::to_string(r.status);
        if (!controller.link().health().last_error.empty() && r.status == hal::modbus::WriteStatus::LinkError)
          line << " (" << controller.link().health().last_error << ")";
        failures.push_back(line.str());
      }
    }
    std::lock_guard lock(mutex_);
    safe_.written = std::move(written);
    safe_.failures = std::move(failures);
    safe_.done = true;
    safe_.done_ns = hal::monotonic_now_ns();
  }
  for (;;) {
    Command c{};
    {
      std::lock_guard lock(mutex_);
      if (queue_.empty() || safe_pending_) return;
      c = queue_.front();
      queue_.pop_front();
    }
    Outcome out;
    out.result = controller.write(c.register_index, c.value, hal::modbus::Ramp::Limited);
    out.t_ns = hal::monotonic_now_ns();
    std::lock_guard lock(mutex_);
    outcomes_[c.ticket] = out;
  }
}

void ControllerPort::wait_until(std::int64_t until_ns) {
  std::unique_lock lock(mutex_);
  const std::int64_t left = until_ns - hal::monotonic_now_ns();
  if (left <= 0) return;
  posted_.wait_for(lock, std::chrono::nanoseconds(left), [this] { return safe_pending_ || !queue_.empty(); });
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
