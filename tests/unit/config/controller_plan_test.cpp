// The plan in terms of the controllers: registers with a role, what each phase
// commands, and a plan beyond a controller's limits refused at load with the plan key's
// file:line:column; with executive = "plan", the roles and writes the plan needs.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/config/controller_plan.hpp"
#include "common/input_error.hpp"
#include "tests/unit/config/bench_file_test.hpp"

namespace {

using inertia::InputError;
using namespace inertia::config;
namespace fs = std::filesystem;

constexpr double kDeg = std::numbers::pi / 180.0;

std::string replace_once(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}
std::string replace_rate(const std::string& plan, const std::string& rate_line) {
  return replace_once(plan, "rate_deg_s = 90.0", rate_line);
}

std::string bench_head(const std::string& executive) {
  return "[bench]\nname = \"r\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n" +
         (executive.empty() ? std::string() : "executive = \"" + executive + "\"\n");
}

/// The controller's communication-loss watchdog register (common/config/machine_safety.hpp).
std::string heartbeat(int address) {
  return "[[modbus_device.register]]\nname = \"watchdog\"\naddress = " + std::to_string(address) +
         "\nkind = \"holding\"\nwritable = true\nmin = 0\nmax = 65535\nrole = \"heartbeat\"\ntimeout_s = 2.0\nstop_s = 1.0\n";
}

/// The table: rate and angle setpoints, their readings, a status word, the heartbeat.
std::string table(const std::string& writes = "true", const std::string& rate_extra = "") {
  return "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\nwrites_enabled = " + writes +
         "\n"
         "[[modbus_device.register]]\nname = \"rate_setpoint\"\naddress = 1\nkind = \"holding\"\ntype = \"f32\"\nunit = \"rad/s\"\n"
         "writable = true\nmin = -3.5\nmax = 3.5\nrole = \"table_rate\"\nmax_rate = 2.0\nsafe = 0.0\nmeasured = \"rate\"\n"
         "tolerance = 0.01\nsettle_s = 0.5\n" + rate_extra +
         "[[modbus_device.register]]\nname = \"angle_setpoint\"\naddress = 4\nkind = \"holding\"\ntype = \"f32\"\nunit = \"rad\"\n"
         "writable = true\nmin = -7.0\nmax = 7.0\nrole = \"table_angle\"\nmax_rate = 1.0\nstopped_by = \"rate_setpoint\"\n"
         "settled_by = \"status\"\nsettled_mask = 2\n"
         "[[modbus_device.register]]\nname = \"rate\"\naddress = 4\nkind = \"input\"\ntype = \"f32\"\n"
         "[[modbus_device.register]]\nname = \"status\"\naddress = 11\nkind = \"input\"\ntype = \"u16\"\n" + heartbeat(7);
}

std::string shaker() {
  return "[[modbus_device]]\nname = \"shaker\"\nrole = \"shaker\"\nwrites_enabled = true\n"
         "[[modbus_device.register]]\nname = \"run\"\naddress = 3\nkind = \"holding\"\nwritable = true\nmin = 0\nmax = 1\n"
         "role = \"shaker_run\"\nsafe = 0\nsettled_by = \"status\"\nsettled_mask = 1\n"
         "[[modbus_device.register]]\nname = \"profile\"\naddress = 6\nkind = \"holding\"\nwritable = true\nmin = 1\nmax = 8\n"
         "role = \"shaker_profile\"\n"
         "[[modbus_device.register]]\nname = \"status\"\naddress = 6\nkind = \"input\"\nrole = \"fault\"\nfault_mask = 2\n" +
         heartbeat(7);
}

std::string thermal() {
  return "[[modbus_device]]\nname = \"thermal\"\nrole = \"thermal\"\nwrites_enabled = true\n"
         "[[modbus_device.register]]\nname = \"setpoint\"\naddress = 0\nkind = \"holding\"\ntype = \"i16\"\nscale = 0.01\n"
         "unit = \"degC\"\nwritable = true\nmin = 10.0\nmax = 60.0\nrole = \"thermal_setpoint\"\nmax_rate = 0.5\nsafe = 25.0\n" +
         heartbeat(7);
}

const std::string kRotationCase =
    "[[case]]\nname = \"turn\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
    "[[case.phase]]\nkind = \"dwell\"\nduration_s = 1.0\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nrate_deg_s = 90.0\nduration_s = 2.0\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nangle_deg = 180.0\nduration_s = 2.0\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nangle_deg = 90.0\nduration_s = 2.0\n";
const std::string kShakerCase =
    "[[case]]\nname = \"shake\"\nkind = \"shaker\"\norientation = \"IA\"\n"
    "[[case.phase]]\nkind = \"sine\"\nfrequency_hz = 20.0\namplitude_g = 1.0\nprofile = 2\nduration_s = 1.0\n";
const std::string kThermalCase =
    "[[case]]\nname = \"warm\"\nkind = \"thermal\"\norientation = \"IA\"\n"
    "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 40.0\nduration_s = 1.0\n";

using ControllerPlan = inertia::config::testing::BenchFileTest;

TEST_F(ControllerPlan, RolesAndSettlingKeysLoadAndEachPhaseCommandsItsRoles) {
  const std::string text = bench_head("plan") + table() + shaker() + thermal() + kRotationCase + kShakerCase + kThermalCase;
  const BenchConfig b = load_bench_config(write(text));
  EXPECT_EQ(b.executive, Executive::Plan);
  const ModbusRegister& rate = b.modbus_devices[0].registers[0];
  EXPECT_EQ(rate.role, RegisterRole::TableRate);
  EXPECT_DOUBLE_EQ(rate.max_rate, 2.0);
  EXPECT_EQ(rate.measured, "rate");
  EXPECT_DOUBLE_EQ(rate.tolerance, 0.01);
  EXPECT_DOUBLE_EQ(rate.settle_s, 0.5);
  EXPECT_DOUBLE_EQ(*rate.safe, 0.0);
  EXPECT_EQ(rate.role_at.line, line_of(text, "role = \"table_rate\""));
  EXPECT_EQ(b.modbus_devices[0].registers[1].settled_mask, 2u);
  EXPECT_FALSE(b.modbus_devices[0].registers[1].safe.has_value());
  EXPECT_EQ(b.modbus_devices[1].registers[2].role, RegisterRole::Fault);
  EXPECT_EQ(b.modbus_devices[1].registers[2].fault_mask, 2u);
  ASSERT_TRUE(find_role(b, RegisterRole::ThermalSetpoint));
  EXPECT_EQ(find_role(b, RegisterRole::ThermalSetpoint)->device, 2u);

  auto roles = [](const std::vector<PhaseCommand>& v) {
    std::vector<std::pair<RegisterRole, double>> out;
    for (const auto& c : v) out.emplace_back(c.role, c.value);
    return out;
  };
  using P = std::pair<RegisterRole, double>;
  const TestCase& turn = b.cases[0];
  EXPECT_EQ(roles(phase_commands(turn, 0)), (std::vector<P>{{RegisterRole::TableRate, 0.0}, {RegisterRole::ShakerRun, 0.0}}));
  EXPECT_EQ(roles(phase_commands(turn, 1)),
            (std::vector<P>{{RegisterRole::ShakerRun, 0.0}, {RegisterRole::TableRate, 90.0 * kDeg}}));
  // Angle targets add up from the table's zero within the case.
  const auto third = phase_commands(turn, 2);
  ASSERT_EQ(third.size(), 3u);
  EXPECT_EQ(third[2].role, RegisterRole::TableAngle);
  EXPECT_NEAR(third[2].value, 180.0 * kDeg, 1e-12);
  EXPECT_NEAR(phase_commands(turn, 3)[2].value, 270.0 * kDeg, 1e-12);
  EXPECT_EQ(third[2].where.line, line_of(text, "angle_deg = 180.0"));
  EXPECT_EQ(roles(phase_commands(b.cases[1], 0)),
            (std::vector<P>{{RegisterRole::TableRate, 0.0}, {RegisterRole::ShakerRun, 0.0}, {RegisterRole::ShakerProfile, 2.0},
                            {RegisterRole::ShakerRun, 1.0}}));
  EXPECT_EQ(roles(phase_commands(b.cases[2], 0)),
            (std::vector<P>{{RegisterRole::TableRate, 0.0}, {RegisterRole::ShakerRun, 0.0}, {RegisterRole::ThermalSetpoint, 40.0}}));
}

TEST_F(ControllerPlan, ARateBeyondTheRegisterIsRefusedAtItsPlanLine) {
  const std::string text = bench_head("operator") + table() + replace_rate(kRotationCase, "rate_deg_s = 250.0");
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "rate_deg_s = 250.0")) << e.what();
  EXPECT_NE(std::string(e.what()).find("bench.toml:" + std::to_string(line_of(text, "rate_deg_s = 250.0")) + ":14: case 'turn': "
                                       "rate_deg_s = 250 asks the table_rate register to 4.36332 rad/s, beyond its limits [-3.5, 3.5 rad/s] "
                                       "(register 'rate_setpoint' of device 'table', line " +
                                       std::to_string(line_of(text, "name = \"rate_setpoint\"") - 1) + ")"),
            std::string::npos)
      << e.what();
}

TEST_F(ControllerPlan, AnAngleWhoseSumLeavesTheRangeAThermalSetpointAndAProfileAreRefused) {
  // 180 + 90 + 180 = 450 deg = 7.85 rad > 7: the third angle phase is refused, not the first.
  const std::string angles = kRotationCase + "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nangle_deg = 180.0\nduration_s = 2.0\n";
  std::string text = bench_head("") + table() + angles;
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "angle_deg = 180.0", 2)) << e.what();
  EXPECT_NE(std::string(e.what()).find("takes the table_angle register to 7.85398 rad"), std::string::npos) << e.what();

  text = bench_head("") + thermal() + "[[case]]\nname = \"warm\"\nkind = \"thermal\"\norientation = \"IA\"\n"
                                       "[[case.phase]]\nkind = \"thermal_step\"\nsetpoint_c = 85.0\nduration_s = 1.0\n";
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "setpoint_c = 85.0")) << e.what();
  EXPECT_NE(std::string(e.what()).find("setpoint_c = 85 asks the thermal_setpoint register to 85 degC, beyond its limits [10, 60 degC]"),
            std::string::npos)
      << e.what();

  text = bench_head("") + shaker() + "[[case]]\nname = \"shake\"\nkind = \"shaker\"\norientation = \"IA\"\n"
                                     "[[case.phase]]\nkind = \"random\"\nf1_hz = 20.0\nf2_hz = 200.0\ngrms = 1.0\nprofile = 9\nduration_s = 1.0\n";
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "profile = 9")) << e.what();
}

TEST_F(ControllerPlan, ThePlanModeNeedsEveryRoleItsPhasesUseWritesEnabledAndProfiles) {
  // A rotation at a rate with no table_rate register.
  std::string text = bench_head("plan") + thermal() + kRotationCase;
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "[[case.phase]]", 2)) << e.what();
  EXPECT_NE(std::string(e.what()).find("a rotation at a rate needs a register with role = \"table_rate\""), std::string::npos) << e.what();
  // The same plan marked by the operator loads: nothing is commanded.
  EXPECT_NO_THROW((void)load_bench_config(write(bench_head("operator") + thermal() + kRotationCase)));
  // Writes off on a device whose setpoint the plan commands.
  text = bench_head("plan") + table("false") + kRotationCase;
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"table_rate\"")) << e.what();
  EXPECT_NE(std::string(e.what()).find("has writes_enabled = false"), std::string::npos) << e.what();
  // A shaker that runs stored profiles needs the phase's profile.
  text = bench_head("plan") + shaker() + "[[case]]\nname = \"shake\"\nkind = \"shaker\"\norientation = \"IA\"\n"
                                         "[[case.phase]]\nkind = \"sine\"\nfrequency_hz = 20.0\namplitude_g = 1.0\nduration_s = 1.0\n";
  e = error_of(text);
  EXPECT_NE(std::string(e.what()).find("needs profile = N"), std::string::npos) << e.what();
  // No plan at all.
  e = error_of(bench_head("plan") + thermal());
  EXPECT_NE(std::string(e.what()).find("executive = \"plan\" but the bench file has no test plan"), std::string::npos) << e.what();
  EXPECT_EQ(e.where().line, 5u) << e.what();
}

TEST_F(ControllerPlan, RoleKeysAreCheckedWhereTheyAre) {
  // A command role on a register that cannot be written.
  std::string text = bench_head("") + "[[modbus_device]]\nname = \"t\"\nrole = \"table\"\n"
                                      "[[modbus_device.register]]\nname = \"rate\"\naddress = 1\nrole = \"table_rate\"\n";
  InputError e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"table_rate\"")) << e.what();
  EXPECT_NE(std::string(e.what()).find("needs writable = true"), std::string::npos) << e.what();
  // A continuous setpoint without its rate limit, a motion without its safe value.
  e = error_of(replace_once(bench_head("") + table(), "max_rate = 2.0\n", ""));
  EXPECT_NE(std::string(e.what()).find("needs max_rate"), std::string::npos) << e.what();
  e = error_of(replace_once(bench_head("") + table(), "safe = 0.0\n", ""));
  EXPECT_NE(std::string(e.what()).find("needs safe"), std::string::npos) << e.what();
  e = error_of(replace_once(bench_head("") + table(), "safe = 0.0\n", "safe = 5.0\n"));
  EXPECT_NE(std::string(e.what()).find("safe: must lie within [min, max]"), std::string::npos) << e.what();
  // A reading that is not there, two registers for one role, keys without a role.
  text = replace_once(bench_head("") + table(), "measured = \"rate\"", "measured = \"speed\"");
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "measured = \"speed\"")) << e.what();
  EXPECT_NE(std::string(e.what()).find("names no register of device 'table' ('speed')"), std::string::npos) << e.what();
  text = bench_head("") + table() + replace_once(thermal(), "thermal_setpoint", "table_rate");
  e = error_of(text);
  EXPECT_EQ(e.where().line, line_of(text, "role = \"table_rate\"", 2)) << e.what();
  EXPECT_NE(std::string(e.what()).find("is already register 'rate_setpoint' of device 'table'"), std::string::npos) << e.what();
  e = error_of(replace_once(bench_head("") + table(), "role = \"table_angle\"\n", ""));
  EXPECT_NE(std::string(e.what()).find("max_rate: applies to a setpoint the test executive commands"), std::string::npos) << e.what();
  // executive on a simulated bench.
  e = error_of("[bench]\nname = \"s\"\nsample_rate_hz = 1000.0\nexecutive = \"plan\"\n");
  EXPECT_EQ(e.where().line, 4u) << e.what();
}

}  // namespace
