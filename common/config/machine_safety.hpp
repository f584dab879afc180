#pragma once
// What makes a real bench safe to command, whatever becomes of the daemon: a controller that can
// move or heat machinery stops by itself when the daemon's heartbeat stops (its own
// communication-loss action: a PLC watchdog, a drive's communication-loss stop), and the
// heartbeat of a healthy daemon is never late enough to trip it. Part of the bench file loader,
// kept apart because it is one concept. Not real-time: used at load and by --check.
#include <optional>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/toml_reader.hpp"

namespace inertia::config {

/// The device's heartbeat register, if it has one.
std::optional<std::size_t> heartbeat_register(const ModbusDevice& device);

/// How late a healthy daemon's heartbeat may reach the controller: its period, plus one poll
/// interval and two response timeouts (the polling thread writes it between requests, and one
/// request may time out on a link that works). A link that stays down trips the controller, which
/// is what the heartbeat is for.
double heartbeat_worst_gap_s(const ModbusDevice& device, const ModbusRegister& heartbeat);

/// Throws InputError at the key (file:line and the fix) when device `d` with writes enabled can
/// move machinery (register_role.hpp, moves_machinery) but has no heartbeat register, has two,
/// or has one whose timeout_s exceeds DaemonLimits::kWatchdogS or is shorter than
/// heartbeat_worst_gap_s; and when a device whose readings the executive judges (a register with
/// a role) may take longer than kWatchdogS for one poll (poll_interval_ms + 2 response_timeout_s).
/// `device_table` is d's table, `register_tables[i]` that of d.registers[i].
void check_machine_safety(const TableReader& device_table, const std::vector<TableReader>& register_tables,
                          const ModbusDevice& d);

}  // namespace inertia::config
