#pragma once
// The test executive's keys of a [[modbus_device.register]]: `role` and, for a
// setpoint the executive commands, its rate limit, safe value and settling criterion; for a
// fault status word, its mask. Part of the bench file loader (read by bench_devices.cpp), kept apart
// because it is one concept: how a register takes part in running the plan.
// Not real-time: used once, at load.
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/toml_reader.hpp"

namespace inertia::config {

/// Whether the plan's phases write registers of this role (every role but None, Fault and
/// Heartbeat).
bool is_command(RegisterRole role);

/// Whether a command of this role can set machinery in motion or heat it (table rate and angle,
/// shaker run, thermal setpoint; a shaker profile only chooses what a run does).
bool moves_machinery(RegisterRole role);

/// Reads role, safe, max_rate, measured, tolerance, settled_by, settled_mask, settle_s,
/// settle_timeout_s, fault_mask, stopped_by, period_s, timeout_s and stop_s of register table `r`
/// into `reg` (its writable, min and max already read). Throws InputError at the key for a
/// contradiction (a command role on a register that is not writable, a continuous setpoint
/// without max_rate, a motion without safe, keys of a role on a register without one, ...).
void read_register_role(const TableReader& r, ModbusRegister& reg);

/// `measured`, `settled_by` and `stopped_by` must name registers of the same device (they may come
/// after the setpoint, so this runs once the device is read); `stopped_by` one with a safe value.
/// `tables[i]` is the table of device.registers[i].
void check_register_references(const std::vector<TableReader>& tables, const ModbusDevice& device);

}  // namespace inertia::config
