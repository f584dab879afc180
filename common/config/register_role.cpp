#include "common/config/register_role.hpp"

#include <algorithm>
#include <utility>

namespace inertia::config {

bool is_command(RegisterRole role) { return role != RegisterRole::None && role != RegisterRole::Fault; }

// A command role is a setpoint: it must be writable (so it has [min, max]); a continuous one
// moves at a bounded rate; a motion that must stop on an abort has a safe value; settling is
// judged on one reading of the same device.
void read_register_role(const TableReader& r, ModbusRegister& reg) {
  if (r.has("role")) {
    reg.role_at = r.where("role");
    reg.role = static_cast<RegisterRole>(1 + r.choice("role", {"table_rate", "table_angle", "shaker_run", "shaker_profile",
                                                                 "thermal_setpoint", "fault"}));
  }
  const bool command = is_command(reg.role);
  for (const char* key : {"safe", "max_rate", "measured", "tolerance", "settled_by", "settled_mask", "settle_s", "settle_timeout_s"})
    if (r.has(key) && !command)
      r.fail_key(key, "applies to a setpoint the test executive commands (role = \"table_rate\", \"table_angle\", "
                      "\"shaker_run\", \"shaker_profile\" or \"thermal_setpoint\")");
  if (r.has("fault_mask") && reg.role != RegisterRole::Fault) r.fail_key("fault_mask", "applies to a register with role = \"fault\"");
  if (reg.role == RegisterRole::Fault) {
    reg.fault_mask = static_cast<std::uint32_t>(r.integer_in("fault_mask", 0, 0, 0xFFFFFFFF));
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
  if (r.has("safe")) {
    reg.safe = r.number("safe");
    if (*reg.safe < reg.min || *reg.safe > reg.max) r.fail_key("safe", "must lie within [min, max]");
  } else if (reg.role == RegisterRole::TableRate || reg.role == RegisterRole::ShakerRun ||
             reg.role == RegisterRole::ThermalSetpoint) {
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
    for (const auto& [key, target] : {std::pair{"measured", d.registers[i].measured}, std::pair{"settled_by", d.registers[i].settled_by}}) {
      if (target.empty()) continue;
      // A named copy: clang 14 (the fuzz build) cannot capture a structured binding.
      const std::string& name = target;
      const bool known = std::any_of(d.registers.begin(), d.registers.end(), [&name](const ModbusRegister& x) { return x.name == name; });
      if (!known) tables[i].fail_key(key, "names no register of device '" + d.name + "' ('" + target + "')");
    }
  }
}

}  // namespace inertia::config
