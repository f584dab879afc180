// Loading a bench file (bench_config.hpp): the [bench] and [fixture] tables, then each part of the
// file through its readers (bench_config_readers.hpp: sensors in bench_sensors.cpp, devices in
// bench_devices.cpp, the test plan in bench_plan.cpp), then the checks across parts (the plan
// against the controllers, a real bench's link capacity). The files come from the disk or from
// the texts an INERTIA_BENCH message carries.
#include "common/config/bench_config.hpp"

#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>

#include "common/config/bench_config_readers.hpp"
#include "common/config/controller_plan.hpp"
#include "common/config/link_capacity.hpp"
#include "common/config/toml_reader.hpp"
#include "common/units.hpp"

namespace inertia::config {

namespace {

constexpr double kDefaultAlphaDeg = 25.0;   // the paper's suggestion for Fig. 2 (section 2.3)

std::optional<std::string> read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

BenchConfig load_bench(const std::filesystem::path& path, std::string text, const detail::SourceFetch& fetch) {
  const toml::table root_table = parse_toml_text(text, path.string());
  const TableReader root(root_table, "", path.string());
  BenchConfig cfg;
  cfg.file = path;
  cfg.sources.push_back({path, std::move(text)});

  const TableReader bench = root.table("bench");
  cfg.name = bench.string("name");
  cfg.simulated = bench.choice_or("backend", {"sim", "real"}, 0) == 0;
  cfg.executive_at = bench.where("executive");
  if (bench.has("executive")) {
    if (cfg.simulated) bench.fail_key("executive", "is for real benches: a simulated bench runs its plan in the simulator");
    cfg.executive = bench.choice("executive", {"operator", "plan"}) == 0 ? Executive::Operator : Executive::Plan;
  }
  if (bench.has("stop_within_s")) {
    if (cfg.simulated) bench.fail_key("stop_within_s", "is for real benches: a simulated bench commands no machinery");
    cfg.stop_within_s = bench.positive("stop_within_s");
    cfg.stop_within_at = bench.where("stop_within_s");
  }
  cfg.sample_rate_hz = bench.positive("sample_rate_hz");
  cfg.t_ref_c = bench.number_in("t_ref_c", cfg.t_ref_c, -100.0, 200.0);
  cfg.seed = detail::read_seed(bench, "seed", cfg.seed);
  if (const auto timing = bench.optional_table("sim_timing")) {
    cfg.sim_timing.enabled = true;
    cfg.sim_timing.jitter_s = 1e-6 * timing->number_in("jitter_us", 0.0, 0.0, 1e5);
    cfg.sim_timing.clock_ppm = timing->number_in("clock_ppm", 0.0, -1000.0, 1000.0);
    cfg.sim_timing.frame_loss = timing->number_in("frame_loss", 0.0, 0.0, 0.5);
    // From a byte's counter up; a 16-bit one at 10 kHz rolls over every 6.6 s.
    cfg.sim_timing.counter_bits = static_cast<int>(timing->integer_in("counter_bits", 32, 8, 32));
    timing->finish();
  }
  bench.finish();

  cfg.alpha_rad = deg_to_rad(kDefaultAlphaDeg);
  if (const auto fixture = root.optional_table("fixture")) {
    const double alpha_deg = fixture->number_in("alpha_deg", kDefaultAlphaDeg, 0.0, 90.0);
    if (alpha_deg == 0.0 || alpha_deg == 90.0) {
      fixture->fail_key("alpha_deg", "must be strictly between 0 and 90 (section 2.3: alpha != 0)");
    }
    cfg.alpha_rad = deg_to_rad(alpha_deg);
    if (const auto th = fixture->optional_table("thermal")) detail::read_thermal(*th, cfg.thermal);
    fixture->finish();
  }

  std::set<std::string> names;
  const std::vector<TableReader> sensors = root.tables("sensor");
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    cfg.sensors.push_back(detail::read_sensor(sensors[i], i, cfg.seed));
    if (!names.insert(cfg.sensors.back().name).second) {
      sensors[i].fail_key("name", "duplicate sensor name '" + cfg.sensors.back().name + "'");
    }
  }
  if (cfg.simulated && cfg.sensors.empty()) root.fail_here("a simulated bench needs at least one [[sensor]]");
  std::set<std::string> unit_names;
  for (const TableReader& u : root.tables("unit")) {
    cfg.units.push_back(detail::read_unit(u, cfg.sensors));
    if (!unit_names.insert(cfg.units.back().name).second) u.fail_key("name", "duplicate unit name '" + cfg.units.back().name + "'");
  }

  std::set<std::string> monitor_names;
  for (const TableReader& m : root.tables("monitor")) {
    cfg.monitors.push_back(detail::read_monitor(m, true));
    if (!monitor_names.insert(cfg.monitors.back().name).second) {
      m.fail_key("name", "duplicate monitor name '" + cfg.monitors.back().name + "'");
    }
  }
  if (const auto c = root.optional_table("control_accelerometer")) cfg.control_accelerometer = detail::read_monitor(*c, false);
  if (const auto e = root.optional_table("linear_encoder")) cfg.linear_encoder = detail::read_encoder(*e, "resolution_m", cfg.simulated);
  if (const auto e = root.optional_table("table_encoder")) cfg.table_encoder = detail::read_encoder(*e, "resolution_rad", cfg.simulated);

  for (const TableReader& d : root.tables("can_device")) cfg.can_devices.push_back(detail::read_can_device(d));
  for (const TableReader& d : root.tables("gpiod_encoder")) cfg.gpiod_encoders.push_back(detail::read_gpiod_encoder(d));
  for (const TableReader& d : root.tables("modbus_device")) cfg.modbus_devices.push_back(detail::read_modbus_device(d));
  detail::check_one_master_per_serial_line(cfg.modbus_devices);
  if (const auto d = root.optional_table("daemon")) cfg.daemon = detail::read_daemon(*d);

  std::set<std::string> case_names;
  detail::read_cases(root, cfg, case_names, 0, fetch);
  if (cfg.simulated && cfg.cases.empty()) root.fail_here("a simulated bench needs a test plan ([[case]] tables)");
  root.finish();
  check_plan_against_controllers(cfg);
  if (!cfg.simulated) check_link_capacity(cfg);
  return cfg;
}

}  // namespace

BenchConfig load_bench_config(const std::filesystem::path& path) {
  std::optional<std::string> text = read_text_file(path);
  if (!text) throw InputError(SourcePosition{path.string(), 0, 0}, "file not found");
  return load_bench(path, std::move(*text), read_text_file);
}

BenchConfig load_bench_config_from_sources(const std::vector<SourceFile>& sources) {
  if (sources.empty()) throw InputError("bench config: no files (the bench file's text is missing)");
  const detail::SourceFetch fetch = [&sources](const std::filesystem::path& path) -> std::optional<std::string> {
    for (const SourceFile& f : sources)
      if (f.path.lexically_normal() == path.lexically_normal()) return f.text;
    return std::nullopt;
  };
  return load_bench(sources.front().path, sources.front().text, fetch);
}

}  // namespace inertia::config
