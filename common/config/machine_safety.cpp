#include "common/config/machine_safety.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "common/config/register_role.hpp"

namespace inertia::config {

std::optional<std::size_t> heartbeat_register(const ModbusDevice& device) {
  for (std::size_t r = 0; r < device.registers.size(); ++r)
    if (device.registers[r].role == RegisterRole::Heartbeat) return r;
  return std::nullopt;
}

double heartbeat_worst_gap_s(const ModbusDevice& device, const ModbusRegister& heartbeat) {
  return heartbeat.heartbeat_period_s + device.poll_interval_ms * 1e-3 + 2.0 * device.response_timeout_s;
}

void check_machine_safety(const TableReader& device_table, const std::vector<TableReader>& register_tables,
                          const ModbusDevice& d) {
  const auto has_role = [](const ModbusRegister& r) { return r.role != RegisterRole::None; };
  if (std::any_of(d.registers.begin(), d.registers.end(), has_role)) {
    const double worst_poll_s = d.poll_interval_ms * 1e-3 + 2.0 * d.response_timeout_s;
    if (worst_poll_s > DaemonLimits::kWatchdogS)
      device_table.fail_key(
          device_table.has("poll_interval_ms") ? "poll_interval_ms" : "response_timeout_s",
          fmt::format("device '{}' has registers the test executive judges, but one poll may take poll_interval_ms + 2 x "
                      "response_timeout_s = {:.3g} s, more than the daemon's watchdog ({} s): the executive would see its "
                      "faults and settling that late. Poll faster or shorten the timeout",
                      d.name, worst_poll_s, DaemonLimits::kWatchdogS));
  }
  std::optional<std::size_t> heartbeat;
  for (std::size_t r = 0; r < d.registers.size(); ++r) {
    if (d.registers[r].role != RegisterRole::Heartbeat) continue;
    if (heartbeat)
      register_tables[r].fail_key("role", fmt::format("device '{}' already has a heartbeat register ('{}', line {}): one per "
                                                      "controller",
                                                      d.name, d.registers[*heartbeat].name, d.registers[*heartbeat].where.line));
    heartbeat = r;
  }
  if (heartbeat) {
    const ModbusRegister& h = d.registers[*heartbeat];
    const TableReader& t = register_tables[*heartbeat];
    if (h.heartbeat_timeout_s > DaemonLimits::kWatchdogS)
      t.fail_key("timeout_s", fmt::format("{} s is longer than the daemon's watchdog ({} s): a hung daemon is restarted, "
                                          "disarmed, before the controller would notice; set the controller's "
                                          "communication-loss timeout to {} s or less",
                                          h.heartbeat_timeout_s, DaemonLimits::kWatchdogS, DaemonLimits::kWatchdogS));
    const double gap_s = heartbeat_worst_gap_s(d, h);
    if (gap_s >= h.heartbeat_timeout_s)
      t.fail_key("timeout_s", fmt::format("the controller would stop a healthy bench: the heartbeat may come period_s + "
                                          "poll_interval_ms + 2 x response_timeout_s = {:.3g} s apart (one slow request), "
                                          "not less than timeout_s = {:.3g} s. Lengthen the controller's timeout, or "
                                          "write the heartbeat more often, poll faster or shorten response_timeout_s",
                                          gap_s, h.heartbeat_timeout_s));
  }
  if (!d.writes_enabled || heartbeat) return;
  for (std::size_t r = 0; r < d.registers.size(); ++r) {
    if (!moves_machinery(d.registers[r].role)) continue;
    register_tables[r].fail_key(
        "role", fmt::format("device '{}' can move machinery (role = \"{}\", writes_enabled = true) but has no register with "
                            "role = \"heartbeat\": a daemon that died would leave it as it was. Configure the controller to "
                            "stop when a holding register stops changing (a PLC watchdog, the drive's communication-loss "
                            "action) and name that register with role = \"heartbeat\", timeout_s and stop_s "
                            "(config/bench-template.toml)",
                            d.name, to_string(d.registers[r].role)));
  }
}

}  // namespace inertia::config
