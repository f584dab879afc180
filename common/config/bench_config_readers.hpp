#pragma once
// The bench file's readers that more than one of its source files calls (internal to
// common/config): the loader (bench_config.cpp) reads the top-level tables through the readers of
// the sensors (bench_sensors.cpp), the devices (bench_devices.cpp) and the test plan
// (bench_plan.cpp). Each reader takes one table and checks what it holds; nothing here is part of
// the bench_config.hpp contract.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/toml_reader.hpp"
#include "common/units.hpp"

namespace inertia::config::detail {

// ---- shared by the sensors', the plan's and the loader's readers ----

inline AxisAngle read_axis_angle(const TableReader& parent, std::string_view key) {
  AxisAngle out;
  const auto t = parent.optional_table(key);
  if (!t) return out;
  out.axis = t->nonzero_vec3("axis");
  out.angle_rad = deg_to_rad(t->number("angle_deg"));
  t->finish();
  return out;
}

inline std::uint64_t read_seed(const TableReader& t, std::string_view key, std::uint64_t fallback) {
  return static_cast<std::uint64_t>(
      t.integer_in(key, static_cast<std::int64_t>(fallback), 0, std::numeric_limits<std::int64_t>::max()));
}

// ---- bench_sensors.cpp: the sensors under test and the references ----

void read_thermal(const TableReader& t, ThermalController& th);
/// `named` false: the control accelerometer, whose name defaults to "control".
MonitorAccelerometer read_monitor(const TableReader& t, bool named);
Encoder read_encoder(const TableReader& t, std::string_view resolution_key, bool simulated);
SensorUnderTest read_sensor(const TableReader& t, std::size_t index, std::uint64_t bench_seed);
/// A [[unit]]: its members must be `sensors` of the right type, in no other unit; each gets its
/// unit, axis, and the unit's serial and part.
Unit read_unit(const TableReader& t, std::vector<SensorUnderTest>& sensors);

// ---- bench_devices.cpp: a real bench's devices and the daemon ----

CanDevice read_can_device(const TableReader& t);
GpiodEncoder read_gpiod_encoder(const TableReader& t);
DaemonSettings read_daemon(const TableReader& t);
ModbusDevice read_modbus_device(const TableReader& t);
/// Throws InputError when two Modbus RTU devices share a serial line.
void check_one_master_per_serial_line(const std::vector<ModbusDevice>& devices);

// ---- bench_plan.cpp: the test plan ----

// Where the loader gets a file's text: the disk, or the texts carried by INERTIA_BENCH.
// nullopt when the file does not exist there.
using SourceFetch = std::function<std::optional<std::string>(const std::filesystem::path&)>;

/// The [[case]] tables of `root` and of the files it includes (`depth`: include nesting so far).
void read_cases(const TableReader& root, BenchConfig& cfg, std::set<std::string>& names, int depth,
                const SourceFetch& fetch);

}  // namespace inertia::config::detail
