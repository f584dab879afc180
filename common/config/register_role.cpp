#include "common/config/register_role.hpp"

#include <algorithm>
#include <string_view>
#include <utility>

namespace inertia::config {

bool is_command(RegisterRole role) {
  return role != RegisterRole::None && role != RegisterRole::Fault && role != RegisterRole::Heartbeat;
}

bool moves_machinery(RegisterRole role) {
  return role == RegisterRole::TableRate || role == RegisterRole::TableAngle || role == RegisterRole::ShakerRun ||
         role == RegisterRole::ThermalSetpoint;
}

namespace {

// The heartbeat's keys: a holding register the daemon writes while alive, and what the
// controller does when the writes stop.
void read_heartbeat(const TableReader& r, ModbusRegister& reg) {
  if (!reg.writable)
    r.fail_key("role", "role = \"heartbeat\" is a register the daemon writes: it needs writable = true, min and max "
                       "(the counter's range, e.g. min = 0, max = 65535)");
  reg.heartbeat_period_s = r.number_in("period_s", reg.heartbeat_period_s, 0.01, 10.0);
  if (!r.has("timeout_s"))
    r.fail_key("role", "role = \"heartbeat\" needs timeout_s: the controller's communication-loss timeout, as configured "
                       "in the controller (a PLC watchdog or the drive's communication-loss action)");
  reg.heartbeat_timeout_s = r.positive("timeout_s");
  if (!r.has("stop_s"))
    r.fail_key("role", "role = \"heartbeat\" needs stop_s: how long the controller takes to bring the machine to rest "
                       "once its communication-loss action starts (e.g. the table's top rate over its deceleration)");
  reg.heartbeat_stop_s = r.number_in("stop_s", 0.0, 0.0, 3600.0);
}

}  // namespace

// A command role is a setpoint: it must be writable (so it has [min, max]); a continuous one
// moves at a bounded rate; a motion that must stop on an abort has a safe value; settling is
// judged on one reading of the same device.
void read_register_role(const TableReader& r, ModbusRegister& reg) {
  if (r.has("role")) {
    reg.role_at = r.where("role");
    reg.role = static_cast<RegisterRole>(1 + r.choice("role", {"table_rate", "table_angle", "shaker_run", "shaker_profile",
                                                                 "thermal_setpoint", "fault", "heartbeat"}));
  }
  const bool command = is_command(reg.role);
  // A writable register without a role may still take part in the safe state: a mode, brake or
  // enable register the plan never writes, whose `safe` value an abort writes with the others.
  if (reg.role == RegisterRole::None && r.has("safe")) {
    if (!reg.writable) r.fail_key("safe", "the safe state is written: the register needs writable = true, min and max");
    reg.safe = r.number("safe");
    if (*reg.safe < reg.min || *reg.safe > reg.max) r.fail_key("safe", "must lie within [min, max]");
  }
  for (const char* key : {"safe", "max_rate", "measured", "tolerance", "settled_by", "settled_mask", "settle_s", "settle_timeout_s"})
    if (r.has(key) && !command && !(reg.role == RegisterRole::None && std::string_view(key) == "safe"))
      r.fail_key(key, "applies to a setpoint the test executive commands (role = \"table_rate\", \"table_angle\", "
                      "\"shaker_run\", \"shaker_profile\" or \"thermal_setpoint\")");
  if (r.has("fault_mask") && reg.role != RegisterRole::Fault) r.fail_key("fault_mask", "applies to a register with role = \"fault\"");
  if (r.has("stopped_by") && reg.role != RegisterRole::TableAngle)
    r.fail_key("stopped_by", "applies to a register with role = \"table_angle\"");
  for (const char* key : {"period_s", "timeout_s", "stop_s"})
    if (r.has(key) && reg.role != RegisterRole::Heartbeat) r.fail_key(key, "applies to a register with role = \"heartbeat\"");
  if (reg.role == RegisterRole::Fault) {
    reg.fault_mask = static_cast<std::uint32_t>(r.integer_in("fault_mask", 0, 0, 0xFFFFFFFF));
    return;
  }
  if (reg.role == RegisterRole::Heartbeat) {
    read_heartbeat(r, reg);
    return;
  }
  if (!command) return;
  if (!reg.writable)
    r.fail_key("role", std::string("role = \"") + to_string(reg.role) +
                           "\" is a setpoint the test executive writes: it needs writable = true, min and max");
  const bool continuous = reg.role == RegisterRole::TableRate || reg.role == RegisterRole::TableAngle ||
                          reg.role == RegisterRole::ThermalSetpoint;
  if (continuous) {
    if (!r.has("max_rate"))
      r.fail_key("role", std::string("role = \"") + to_string(reg.role) +
                             "\" needs max_rate (the fastest the setpoint may change, SI per second: rad/s^2, rad/s, degC/s)");
    reg.max_rate = r.positive("max_rate");
  } else if (r.has("max_rate")) {
    r.fail_key("max_rate", std::string("a ") + to_string(reg.role) + " register takes discrete values: it is written in one step");
  }
  if (reg.role == RegisterRole::TableAngle) {
    // Any angle is a move: what stops one is another register (the controller's mode or stop).
    if (r.has("safe"))
      r.fail_key("safe", "an angle setpoint has no safe value (writing any angle moves the table): name the register "
                         "whose safe value stops a move in progress with stopped_by");
    if (!r.has("stopped_by"))
      r.fail_key("role", "role = \"table_angle\" needs stopped_by: the register of this device whose safe value stops a "
                         "move in progress (the controller's mode or stop register, or its rate setpoint if a rate write "
                         "leaves position mode)");
    reg.stopped_by = r.string("stopped_by");
  } else if (r.has("safe")) {
    reg.safe = r.number("safe");
    if (*reg.safe < reg.min || *reg.safe > reg.max) r.fail_key("safe", "must lie within [min, max]");
  } else if (moves_machinery(reg.role)) {
    r.fail_key("role", std::string("role = \"") + to_string(reg.role) +
                           "\" needs safe (the value an abort writes: e.g. rate 0, shaker stopped 0, a safe temperature)");
  }
  if (reg.role == RegisterRole::ShakerRun && (reg.min > 0.0 || reg.max < 1.0))
    r.fail_key("max", "a shaker_run register is written 1 (run) and 0 (stop): [min, max] must hold both");
  if (r.has("measured") && r.has("settled_by"))
    r.fail_key("settled_by", "settling is judged on one reading: measured (with tolerance) or settled_by, not both");
  if (r.has("measured")) {
    reg.measured = r.string("measured");
    if (!r.has("tolerance")) r.fail_key("measured", "needs tolerance (how close the reading must come, SI)");
    reg.tolerance = r.positive("tolerance");
  } else if (r.has("tolerance")) {
    r.fail_key("tolerance", "needs measured (the register whose reading must come within it)");
  }
  if (r.has("settled_by")) {
    reg.settled_by = r.string("settled_by");
    reg.settled_mask = static_cast<std::uint32_t>(r.integer_in("settled_mask", 0, 0, 0xFFFFFFFF));
  } else if (r.has("settled_mask")) {
    r.fail_key("settled_mask", "needs settled_by (the status register it applies to)");
  }
  reg.settle_s = r.number_in("settle_s", reg.settle_s, 0.0, 3600.0);
  reg.settle_timeout_s = r.number_in("settle_timeout_s", reg.settle_timeout_s, 0.0, 86400.0);
  if (reg.settle_timeout_s <= reg.settle_s) r.fail_key("settle_timeout_s", "must be longer than settle_s");
}

void check_register_references(const std::vector<TableReader>& tables, const ModbusDevice& d) {
  for (std::size_t i = 0; i < d.registers.size(); ++i) {
    for (const auto& [key, target] : {std::pair{"measured", d.registers[i].measured}, std::pair{"settled_by", d.registers[i].settled_by},
                                      std::pair{"stopped_by", d.registers[i].stopped_by}}) {
      if (target.empty()) continue;
      // A named copy: clang 14 (the fuzz build) cannot capture a structured binding.
      const std::string& name = target;
      const auto found = std::find_if(d.registers.begin(), d.registers.end(), [&name](const ModbusRegister& x) { return x.name == name; });
      if (found == d.registers.end()) tables[i].fail_key(key, "names no register of device '" + d.name + "' ('" + target + "')");
      if (std::string_view(key) == "stopped_by" && !found->safe)
        tables[i].fail_key(key, "register '" + target + "' has no safe value: the register that stops a move needs one "
                                "(the value that stops the table)");
    }
  }
}

}  // namespace inertia::config
