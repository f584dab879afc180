#pragma once
// The test plan in terms of a real bench's controllers: which Modbus register each
// command role is mapped to, what every phase commands, and whether the plan stays within the
// registers' limits. One meaning of a phase for the loader, which refuses a plan beyond the
// limits with the plan key's file:line, and for the daemon's test executive, which sends exactly
// these commands (daq/test_executive.hpp).
//
// What a phase commands, in the order the executive sends them (roles the bench does not map
// are left out; those the phase needs must be mapped when [bench] executive = "plan"):
//   dwell          table_rate 0, shaker_run 0                           (the bench at rest)
//   rotation rate  shaker_run 0, table_rate = rate_deg_s                (needs table_rate)
//   rotation angle shaker_run 0, table_rate 0, table_angle = target     (needs table_angle)
//   sine, random,  table_rate 0, shaker_run 0, shaker_profile = profile, shaker_run 1
//   shock                                                               (needs shaker_run)
//   thermal_step   table_rate 0, shaker_run 0, thermal_setpoint = setpoint_c (needs thermal_setpoint)
// A shaker is stopped before a profile is loaded, as controllers require. The angle target is
// absolute: the angle_deg of a case's rotation phases add up from the table's zero (the first
// one goes to angle_deg, the next to the sum of both, ...), so a plan's every target is known
// at load and checked against the register's [min, max]. The executive skips a command whose
// value the register already holds from a confirmed write.
#include <cstddef>
#include <optional>
#include <vector>

#include "common/config/bench_config.hpp"

namespace inertia::config {

/// A register of the bench: indices into BenchConfig::modbus_devices and its registers.
struct RegisterRef {
  std::size_t device = 0;
  std::size_t reg = 0;
};

/// The register mapped to `role`, if any (the loader allows at most one per role).
std::optional<RegisterRef> find_role(const BenchConfig& bench, RegisterRole role);

/// A register of `device` by name, if any.
std::optional<std::size_t> find_register(const ModbusDevice& device, const std::string& name);

struct PhaseCommand {
  RegisterRole role = RegisterRole::None;
  double value = 0.0;         // SI, as the register's min/max
  bool needed = false;        // the phase's own motion (not just "the rest of the bench at rest")
  SourcePosition where;       // the plan key that asks for it (the phase table for rest commands)
};

/// The commands of phase `phase` of `test_case`, in order (see the table above), for every role.
std::vector<PhaseCommand> phase_commands(const TestCase& test_case, std::size_t phase);

/// Throws InputError at the plan key (file:line:column) when a phase asks a mapped register for a
/// value outside its [min, max], and at the register's role when two registers share one. With
/// executive = "plan", also when there is no plan, when a phase needs a role the bench does not
/// map (or a shaker profile it does not give), and when a mapped setpoint's device has
/// writes_enabled = false. Called by the loader.
void check_plan_against_controllers(const BenchConfig& bench);

}  // namespace inertia::config
