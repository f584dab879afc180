// The bench file's sensors: the sensors under test ([[sensor]], with their simulated truth), the
// reference instruments ([[monitor]], [control_accelerometer], the linear and table encoders) and
// the fixture's thermal controller, and the sensors' seeds. The loader (bench_config.cpp) calls
// these readers (bench_config_readers.hpp) for its top-level tables.
#include <fmt/format.h>

#include <algorithm>
#include <tuple>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/config/bench_config_readers.hpp"
#include "common/config/toml_reader.hpp"
#include "common/units.hpp"

namespace inertia::config {

namespace detail {

namespace {

std::vector<TruthValue> read_truth(const TableReader& t) {
  std::vector<TruthValue> out;
  for (const auto& [key, node] : t.entries()) {
    TruthValue v;
    v.name = key;
    v.where = position_of(*node, t.file());
    if (const toml::array* a = node->as_array()) {
      v.is_array = true;
      for (const toml::node& e : *a) {
        const auto d = e.value<double>();
        if (!d) t.fail(e, t.key_name(key) + " must hold numbers only");
        v.values.push_back(*d);
      }
    } else if (const auto d = node->value<double>(); d && !node->is_boolean()) {
      v.values.push_back(*d);
    } else {
      t.fail(*node, t.key_name(key) + " must be a number or an array of numbers");
    }
    out.push_back(std::move(v));
  }
  return out;
}

}  // namespace

void read_thermal(const TableReader& t, ThermalController& th) {
  th.ambient_c = t.number_in("ambient_c", th.ambient_c, -100.0, 200.0);
  th.initial_c = t.number_in("initial_c", th.initial_c, -100.0, 200.0);
  th.tau_s = t.positive_or("tau_s", th.tau_s);
  th.heat_rate_max_c_per_s = t.positive_or("heat_rate_max_c_per_s", th.heat_rate_max_c_per_s);
  th.kp_per_c = t.number_in("kp_per_c", th.kp_per_c, 0.0, 1e6);
  th.ki_per_c_s = t.number_in("ki_per_c_s", th.ki_per_c_s, 0.0, 1e6);
  th.sensor_noise_sd_c = t.number_in("sensor_noise_sd_c", th.sensor_noise_sd_c, 0.0, 100.0);
  th.channel = t.string_or("channel", "");
  t.finish();
}

MonitorAccelerometer read_monitor(const TableReader& t, bool named) {
  MonitorAccelerometer m;
  m.name = named ? t.string("name") : t.string_or("name", "control");
  if (m.name.empty() || m.name.find_first_of(",\" \t") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without commas, quotes or spaces (it heads a CSV column)");
  }
  m.axis = t.has("axis") ? t.nonzero_vec3("axis").normalized() : Eigen::Vector3d::UnitX();
  m.bias_mps2 = g_to_mps2(t.number_or("bias_g", 0.0));
  m.scale_error = t.number_in("scale_error", 0.0, -0.5, 0.5);
  m.misalignment = read_axis_angle(t, "misalignment");
  m.noise_sd_mps2 = g_to_mps2(t.number_in("noise_sd_g", 0.0, 0.0, 1e3));
  m.channel = t.string_or("channel", "");
  t.finish();
  return m;
}

Encoder read_encoder(const TableReader& t, std::string_view resolution_key, bool simulated) {
  Encoder e;
  e.present = true;
  e.resolution = t.positive(resolution_key);
  e.channel = t.string_or("channel", "");
  if (t.has("wire") && !simulated)
    t.fail_key("wire", "is for simulated benches: a real bench's encoder is wired by its [[gpiod_encoder]] or "
                       "[[can_device]], named in `channel`");
  e.wire = t.choice_or("wire", {"gpio", "can"}, 0) == 0 ? EncoderWire::Gpio : EncoderWire::Can;
  t.finish();
  return e;
}

SensorUnderTest read_sensor(const TableReader& t, std::size_t index, std::uint64_t bench_seed) {
  SensorUnderTest s;
  s.where = t.where();
  s.name = t.string("name");
  if (s.name.empty() || s.name.find_first_of("/\\ ") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without '/', '\\' or spaces (it names a folder)");
  }
  s.type = t.choice("type", {"accelerometer", "gyroscope"}) == 0 ? SensorType::Accelerometer
                                                                   : SensorType::Gyroscope;
  s.output_unit = t.string_or("output_unit", s.output_unit);
  s.slot = t.string_or("slot", "");
  s.serial = t.string_or("serial", "");
  s.part = t.string_or("part", "");
  s.position_m = t.vec3_or("position_m", Eigen::Vector3d::Zero());
  s.seed = read_seed(t, "seed", derived_sensor_seed(bench_seed, index));
  s.channel = t.string_or("channel", "");
  s.case_misalignment = read_axis_angle(t, "case_misalignment");
  if (const auto truth = t.optional_table("truth")) s.truth = read_truth(*truth);
  // An aging sensor: at calibration n each [sensor.aging] drift is added n times to the truth
  // value of the same name (the simulator's sensor as it would be at its n-th calibration).
  s.calibration = static_cast<int>(t.integer_in("calibration", 0, 0, 1000000));
  if (const auto aging = t.optional_table("aging")) {
    for (const TruthValue& drift : read_truth(*aging)) {
      const auto it = std::find_if(s.truth.begin(), s.truth.end(), [&](const TruthValue& v) { return v.name == drift.name; });
      if (it == s.truth.end() || it->is_array || drift.is_array) {
        aging->fail(*aging->node(drift.name),
                    aging->key_name(drift.name) + " ages a scalar of [sensor.truth]: give it there (its value at calibration 0)");
      }
      it->values.front() += static_cast<double>(s.calibration) * drift.values.front();
    }
  }
  t.finish();
  return s;
}

Unit read_unit(const TableReader& t, std::vector<SensorUnderTest>& sensors) {
  Unit u;
  u.where = t.where();
  u.name = t.string("name");
  if (u.name.empty() || u.name.find_first_of("/\\ ") != std::string::npos)
    t.fail_key("name", "must be a non-empty name without '/', '\\' or spaces");
  u.serial = t.string_or("serial", "");
  u.part = t.string_or("part", "");
  bool any = false;
  for (const auto& [key, type, members] : {std::tuple{"accelerometers", SensorType::Accelerometer, &u.accelerometers},
                                           std::tuple{"gyroscopes", SensorType::Gyroscope, &u.gyroscopes}}) {
    const toml::node* n = t.node(key);
    if (n == nullptr) continue;
    const toml::array* a = n->as_array();
    if (a == nullptr || a->size() != 3)
      t.fail_key(key, "must be three sensor names, along the unit's x, y and z (\"\" where the unit has none)");
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const auto* name = (*a)[axis].as_string();
      if (name == nullptr) t.fail_key(key, "must be three sensor names (strings)");
      (*members)[axis] = name->get();
      if (name->get().empty()) continue;
      const auto sensor = std::find_if(sensors.begin(), sensors.end(), [&](const SensorUnderTest& s) { return s.name == name->get(); });
      if (sensor == sensors.end()) t.fail_key(key, fmt::format("no [[sensor]] named '{}'", name->get()));
      if (sensor->type != type) t.fail_key(key, fmt::format("sensor '{}' is a {}", name->get(), to_string(sensor->type)));
      if (!sensor->unit.empty()) t.fail_key(key, fmt::format("sensor '{}' is already in unit '{}'", name->get(), sensor->unit));
      for (const auto& [field, value] : {std::pair{&sensor->serial, &u.serial}, std::pair{&sensor->part, &u.part}}) {
        if (!field->empty() && !value->empty() && *field != *value)
          t.fail_key(key, fmt::format("sensor '{}' states '{}', the unit '{}'", name->get(), *field, *value));
        if (field->empty()) *field = *value;
      }
      sensor->unit = u.name;
      sensor->unit_axis = static_cast<int>(axis);
      any = true;
    }
  }
  if (!any) t.fail_here("a [[unit]] needs accelerometers or gyroscopes (three names along x, y, z)");
  t.finish();
  return u;
}

}  // namespace detail

std::uint64_t derived_sensor_seed(std::uint64_t bench_seed, std::size_t index) {
  return bench_seed * 1000003u + 17u * (index + 1);
}

void reseed(BenchConfig& bench, std::uint64_t seed) {
  bench.seed = seed;
  for (std::size_t i = 0; i < bench.sensors.size(); ++i) bench.sensors[i].seed = derived_sensor_seed(seed, i);
}

const char* to_string(SensorType type) {
  return type == SensorType::Accelerometer ? "accelerometer" : "gyroscope";
}

}  // namespace inertia::config
