#include "common/config/controller_plan.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

namespace inertia::config {
namespace {

constexpr RegisterRole kCommandRoles[] = {RegisterRole::TableRate, RegisterRole::TableAngle, RegisterRole::ShakerRun,
                                          RegisterRole::ShakerProfile, RegisterRole::ThermalSetpoint};

bool is_shaker(PhaseKind kind) {
  return kind == PhaseKind::Sine || kind == PhaseKind::Random || kind == PhaseKind::Shock;
}

/// "6.98 rad/s" with the register's unit when the bench file gives one.
std::string with_unit(double value, const ModbusRegister& reg) {
  std::ostringstream s;
  s << value;
  if (!reg.unit.empty()) s << " " << reg.unit;
  return s.str();
}

/// What a phase key asks for, in the bench file's own terms, for messages.
std::string asked(const Phase& phase, const PhaseCommand& command) {
  std::ostringstream s;
  switch (command.role) {
    case RegisterRole::TableRate: s << "rate_deg_s = " << phase.rate_rad_s.value_or(0.0) * 180.0 / std::numbers::pi << " asks"; break;
    case RegisterRole::TableAngle: s << "angle_deg = " << phase.angle_rad.value_or(0.0) * 180.0 / std::numbers::pi << " takes"; break;
    case RegisterRole::ThermalSetpoint: s << "setpoint_c = " << phase.setpoint_c << " asks"; break;
    case RegisterRole::ShakerProfile: s << "profile = " << phase.profile.value_or(0) << " asks"; break;
    default: s << "the phase asks"; break;
  }
  return s.str();
}

const char* needed_role_text(const Phase& phase) {
  switch (phase.kind) {
    case PhaseKind::Rotation:
      return phase.rate_rad_s ? "a rotation at a rate needs a register with role = \"table_rate\""
                              : "a rotation through an angle needs a register with role = \"table_angle\"";
    case PhaseKind::Sine:
    case PhaseKind::Random:
    case PhaseKind::Shock: return "a shaker phase needs a register with role = \"shaker_run\"";
    case PhaseKind::ThermalStep: return "a thermal_step needs a register with role = \"thermal_setpoint\"";
    case PhaseKind::Dwell: break;
  }
  return "";
}

}  // namespace

std::optional<RegisterRef> find_role(const BenchConfig& bench, RegisterRole role) {
  for (std::size_t d = 0; d < bench.modbus_devices.size(); ++d) {
    const auto& regs = bench.modbus_devices[d].registers;
    for (std::size_t r = 0; r < regs.size(); ++r)
      if (regs[r].role == role) return RegisterRef{d, r};
  }
  return std::nullopt;
}

std::optional<std::size_t> find_register(const ModbusDevice& device, const std::string& name) {
  for (std::size_t r = 0; r < device.registers.size(); ++r)
    if (device.registers[r].name == name) return r;
  return std::nullopt;
}

std::vector<PhaseCommand> phase_commands(const TestCase& test_case, std::size_t phase) {
  const Phase& p = test_case.phases.at(phase);
  std::vector<PhaseCommand> out;
  auto rest = [&](RegisterRole role) { out.push_back({role, 0.0, false, p.where}); };
  switch (p.kind) {
    case PhaseKind::Dwell:
      rest(RegisterRole::TableRate);
      rest(RegisterRole::ShakerRun);
      break;
    case PhaseKind::Rotation:
      rest(RegisterRole::ShakerRun);
      if (p.rate_rad_s) {
        out.push_back({RegisterRole::TableRate, *p.rate_rad_s, true, p.command_at});
      } else {
        rest(RegisterRole::TableRate);
        // Absolute target: the case's angle moves add up from the table's zero.
        double target = 0.0;
        for (std::size_t i = 0; i <= phase; ++i) {
          const Phase& q = test_case.phases[i];
          if (q.kind == PhaseKind::Rotation && q.angle_rad) target += *q.angle_rad;
        }
        out.push_back({RegisterRole::TableAngle, target, true, p.command_at});
      }
      break;
    case PhaseKind::Sine:
    case PhaseKind::Random:
    case PhaseKind::Shock:
      rest(RegisterRole::TableRate);
      rest(RegisterRole::ShakerRun);  // a controller loads a profile only while stopped
      if (p.profile) out.push_back({RegisterRole::ShakerProfile, static_cast<double>(*p.profile), true, p.command_at});
      out.push_back({RegisterRole::ShakerRun, 1.0, true, p.where});
      break;
    case PhaseKind::ThermalStep:
      rest(RegisterRole::TableRate);
      rest(RegisterRole::ShakerRun);
      out.push_back({RegisterRole::ThermalSetpoint, p.setpoint_c, true, p.command_at});
      break;
  }
  return out;
}

void check_plan_against_controllers(const BenchConfig& bench) {
  // One register per role: the executive must know which one to command.
  for (RegisterRole role : {RegisterRole::TableRate, RegisterRole::TableAngle, RegisterRole::ShakerRun,
                            RegisterRole::ShakerProfile, RegisterRole::ThermalSetpoint}) {
    const auto first = find_role(bench, role);
    if (!first) continue;
    for (std::size_t d = 0; d < bench.modbus_devices.size(); ++d) {
      for (std::size_t r = 0; r < bench.modbus_devices[d].registers.size(); ++r) {
        const ModbusRegister& reg = bench.modbus_devices[d].registers[r];
        if (reg.role != role || (d == first->device && r == first->reg)) continue;
        const ModbusRegister& other = bench.modbus_devices[first->device].registers[first->reg];
        throw InputError(reg.role_at, std::string("role = \"") + to_string(role) + "\" is already register '" + other.name +
                                          "' of device '" + bench.modbus_devices[first->device].name + "' (line " +
                                          std::to_string(other.where.line) + "): one register per role");
      }
    }
  }

  const bool plan = bench.executive == Executive::Plan;
  if (plan && bench.cases.empty())
    throw InputError(bench.executive_at, "executive = \"plan\" but the bench file has no test plan ([[case]] tables)");
  if (plan) {
    for (RegisterRole role : kCommandRoles) {
      const auto ref = find_role(bench, role);
      if (!ref) continue;
      const ModbusDevice& device = bench.modbus_devices[ref->device];
      if (!device.writes_enabled)
        throw InputError(device.registers[ref->reg].role_at,
                         std::string("executive = \"plan\" commands this ") + to_string(role) + " register, but device '" +
                             device.name + "' has writes_enabled = false (set it true, or executive = \"operator\")");
    }
  }

  for (const TestCase& c : bench.cases) {
    for (std::size_t i = 0; i < c.phases.size(); ++i) {
      const Phase& phase = c.phases[i];
      if (plan && is_shaker(phase.kind)) {
        const auto profile_register = find_role(bench, RegisterRole::ShakerProfile);
        if (profile_register && !phase.profile) {
          const ModbusRegister& reg = bench.modbus_devices[profile_register->device].registers[profile_register->reg];
          throw InputError(phase.where, "case '" + c.name + "': this " + to_string(phase.kind) +
                                            " phase needs profile = N: the shaker controller runs stored profiles (register '" +
                                            reg.name + "', line " + std::to_string(reg.where.line) + ")");
        }
        if (!profile_register && phase.profile)
          throw InputError(phase.command_at, "profile: no register has role = \"shaker_profile\" to load it into");
      }
      for (const PhaseCommand& command : phase_commands(c, i)) {
        const auto ref = find_role(bench, command.role);
        if (!ref) {
          if (plan && command.needed)
            throw InputError(phase.where, "case '" + c.name + "': " + needed_role_text(phase) +
                                              " for executive = \"plan\" to command it (or run the bench with executive = \"operator\")");
          continue;
        }
        const ModbusDevice& device = bench.modbus_devices[ref->device];
        const ModbusRegister& reg = device.registers[ref->reg];
        if (command.value >= reg.min && command.value <= reg.max) continue;
        std::ostringstream what;
        what << "case '" << c.name << "': " << asked(phase, command) << " the " << to_string(command.role) << " register to "
             << with_unit(command.value, reg) << ", beyond its limits [" << reg.min << ", " << with_unit(reg.max, reg)
             << "] (register '" << reg.name << "' of device '" << device.name << "', line " << reg.where.line << ")";
        throw InputError(command.where, what.str());
      }
    }
  }
}

}  // namespace inertia::config
