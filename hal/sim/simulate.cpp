#include "hal/sim/simulate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <fstream>
#include <iterator>
#include <ostream>
#include <stdexcept>
#include <string>

#include "common/config/phase_label.hpp"
#include "common/dataset/bench_dataset.hpp"
#include "common/dataset/dataset.hpp"
#include "common/disk_space.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"
#include "hal/sim/sensor_truth.hpp"

namespace inertia::sim {

namespace {

std::filesystem::path sensor_dir(const config::BenchConfig& bench, std::size_t s, const std::filesystem::path& out) {
  return bench.sensors.size() == 1 ? out : out / bench.sensors[s].name;
}

toml::table axis_angle_table(const config::AxisAngle& a) {
  const Eigen::Vector3d u = a.axis.normalized();
  return toml::table{{"axis", toml::array{u.x(), u.y(), u.z()}}, {"angle_deg", rad_to_deg(a.angle_rad)}};
}

void write_truth(const config::BenchConfig& bench, const BenchSimulation& sim, std::size_t s,
                 const std::filesystem::path& file) {
  const config::SensorUnderTest& sensor = bench.sensors[s];
  toml::table root;
  root.insert_or_assign("sensor", sensor.type == config::SensorType::Accelerometer ? "accelerometer" : "gyroscope");
  root.insert_or_assign("name", sensor.name);
  root.insert_or_assign("sensor_name", sensor.name);   // the model file's key for it
  root.insert_or_assign("output_unit", sensor.output_unit);
  root.insert_or_assign("bench", bench.name);
  root.insert_or_assign("seed", static_cast<std::int64_t>(sensor.seed));
  root.insert_or_assign("t_ref", bench.t_ref_c);
  root.insert_or_assign("sample_period_s", 1.0 / bench.sample_rate_hz);
  const frames::Dcm m_cs = sim.cases.empty() ? frames::Dcm::Identity() : sim.cases.front().sensors[s].m_cs;
  root.insert_or_assign("m_cs", to_toml(m_cs));
  toml::table notes, noise;
  if (const auto* acc = std::get_if<AccelerometerParams>(&sim.params[s])) {
    root.insert_or_assign("terms", model_terms(*acc, &notes));
    root.insert_or_assign("params", to_toml(*acc));
    // The model file holds one corner for the squares' high pass (eq. 12): written when the
    // squares the sensor has share it.
    std::vector<double> corners;
    for (const auto& [k, b] : {std::pair{acc->k_ii, acc->b_ii_rad_s}, {acc->k_pp, acc->b_pp_rad_s}, {acc->k_oo, acc->b_oo_rad_s}}) {
      if (k != 0.0) corners.push_back(b);
    }
    if (!corners.empty() && std::all_of(corners.begin(), corners.end(), [&](double b) { return b == corners.front(); }))
      root.insert_or_assign("square_highpass_rad_s", corners.front());
    // Output-unit noise levels: the model multiplies every input-referred term by K_i.
    noise.insert_or_assign("white_sd", std::abs(acc->k_i) * acc->white_sd_g);
    noise.insert_or_assign("pink_sd", std::abs(acc->k_i) * acc->pink_sd_g);
    noise.insert_or_assign("brown_sd", std::abs(acc->k_i) * acc->brown_sd_g);
  } else {
    const FogParams& fog = std::get<FogParams>(sim.params[s]);
    root.insert_or_assign("terms", model_terms(fog, &notes));
    root.insert_or_assign("params", to_toml(fog));
    noise.insert_or_assign("white_sd", fog.noise_sd_rad_s / fog.s0);
  }
  root.insert_or_assign("term_notes", std::move(notes));
  root.insert_or_assign("noise", std::move(noise));
  toml::array cases;
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    const config::TestCase& tc = bench.cases[c];
    const SensorCase& sc = sim.cases[c].sensors[s];
    const frames::Dcm m_es = sc.m_cs * sc.mounting.true_m_ec;
    toml::table t{{"name", tc.name},
                  {"kind", config::to_string(tc.kind)},
                  {"m_ec_nominal", to_toml(sc.mounting.nominal_m_ec)},
                  {"m_ec_true", to_toml(sc.mounting.true_m_ec)},
                  {"m_es_true", to_toml(m_es)},
                  {"fixture_misalignment", axis_angle_table(tc.fixture_misalignment)},
                  {"case_misalignment", axis_angle_table(tc.case_misalignment)},
                  {"slot_case_misalignment", axis_angle_table(sensor.case_misalignment)},
                  {"case_misalignment_total_deg",
                   rad_to_deg(frames::angle_between(sc.mounting.nominal_m_ec, sc.mounting.true_m_ec))},
                  {"sensor_misalignment_total_deg",
                   rad_to_deg(frames::angle_between(sc.mounting.nominal_m_ec, m_es))}};
    if (tc.orientation) t.insert_or_assign("orientation", config::to_string(*tc.orientation));
    cases.push_back(std::move(t));
  }
  root.insert_or_assign("case", std::move(cases));
  std::ofstream os(file);
  os << "# Truth of a simulated bench (inertia-analyze simulate). [terms]: model-file form of design.md,\n"
        "# coefficients in output unit per SI input unit (from g with g0 = 9.80665 m/s^2).\n"
     << toml::toml_formatter(root, toml::toml_formatter::default_flags & ~toml::format_flags::allow_literal_strings)
     << '\n';
  if (!os) throw std::runtime_error("cannot write " + file.string());
}

/// A unit's truth: each member's true input axis in the unit's housing frame, n = T' R_slot' m_cs'
/// e_i (T the member's unit_axis_frame, R_slot its [[sensor]] case_misalignment, m_cs its true
/// M_C^S), the non-orthogonality of each pair, asin(n_j . n_k), and per case the housing's true
/// orientation.
void write_unit_truth(const config::BenchConfig& bench, const BenchSimulation& sim, const config::Unit& unit,
                      const std::filesystem::path& file) {
  toml::table root{{"unit", unit.name}, {"serial", unit.serial}, {"part", unit.part}};
  for (const auto& [key, members] : {std::pair{"accelerometers", &unit.accelerometers}, std::pair{"gyroscopes", &unit.gyroscopes}}) {
    std::array<std::optional<Eigen::Vector3d>, 3> axes;
    toml::table triad;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const std::string& name = (*members)[axis];
      if (name.empty()) continue;
      const auto s = static_cast<std::size_t>(
          std::find_if(bench.sensors.begin(), bench.sensors.end(), [&](const config::SensorUnderTest& x) { return x.name == name; }) -
          bench.sensors.begin());
      const config::SensorUnderTest& sensor = bench.sensors[s];
      const frames::Dcm m_cs = sim.cases.empty() ? frames::Dcm::Identity() : sim.cases.front().sensors[s].m_cs;
      const Eigen::Vector3d n = config::unit_axis_frame(sensor.unit_axis).transpose() *
                                sensor.case_misalignment.dcm().transpose() * m_cs.row(0).transpose();
      axes[axis] = n.normalized();
      triad.insert_or_assign(std::string(1, static_cast<char>('x' + axis)),
                             toml::table{{"sensor", name}, {"axis", toml::array{(*axes[axis])(0), (*axes[axis])(1), (*axes[axis])(2)}}});
    }
    toml::table angles;
    for (std::size_t pair = 0; pair < 3; ++pair) {
      const auto& a = axes[pair];
      const auto& b = axes[(pair + 1) % 3];
      if (a && b) angles.insert_or_assign(std::string(1, static_cast<char>('x' + pair)) + static_cast<char>('x' + (pair + 1) % 3),
                                          std::asin(a->dot(*b)));
    }
    if (triad.empty()) continue;
    triad.insert_or_assign("non_orthogonality_rad", std::move(angles));
    root.insert_or_assign(key, std::move(triad));
  }
  // The housing's true orientation per case, M_E^U = T' R_slot' (true M_E^C of any member): the
  // plan's m_ec with the case's placement error and the housing's misalignment. The input a unit
  // senses is M_E^U a_E.
  const auto first = std::find_if(bench.sensors.begin(), bench.sensors.end(), [&](const config::SensorUnderTest& x) {
    return x.unit == unit.name;
  });
  if (first != bench.sensors.end()) {
    const auto s = static_cast<std::size_t>(first - bench.sensors.begin());
    toml::array cases;
    for (std::size_t c = 0; c < bench.cases.size(); ++c) {
      const frames::Dcm m_eu = config::unit_axis_frame(first->unit_axis).transpose() * first->case_misalignment.dcm().transpose() *
                               sim.cases[c].sensors[s].mounting.true_m_ec;
      cases.push_back(toml::table{{"name", bench.cases[c].name}, {"m_eu_true", to_toml(m_eu)}});
    }
    root.insert_or_assign("case", std::move(cases));
  }
  std::ofstream os(file);
  os << "# Truth of a simulated unit (inertia-analyze simulate): each member's input axis in the unit's housing frame,\n"
        "# asin(n_j . n_k) of each pair, the angle by which two axes are closer than 90 deg, and per case the housing's\n"
        "# true orientation m_eu_true (the input the unit senses is m_eu_true a_E).\n"
     << toml::toml_formatter(root, toml::toml_formatter::default_flags & ~toml::format_flags::allow_literal_strings) << '\n';
  if (!os) throw std::runtime_error("cannot write " + file.string());
}

void write_references(const config::BenchConfig& bench, const SimulatedCase& sc, const std::filesystem::path& file) {
  const CaseReferences& r = sc.references;
  std::string out;
  out.reserve(sc.motion.size() * 24 * (3 + bench.monitors.size()));
  auto it = std::back_inserter(out);
  fmt::format_to(it, "t");
  for (const auto& m : bench.monitors) fmt::format_to(it, ",{}", m.name);
  if (r.control.size() > 0) fmt::format_to(it, ",control");
  if (!r.linear_counts.empty()) fmt::format_to(it, ",linear_counts");
  if (!r.table_counts.empty()) fmt::format_to(it, ",table_counts");
  fmt::format_to(it, ",temp_measured\n");
  for (std::size_t k = 0; k < sc.motion.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    fmt::format_to(it, "{}", sc.motion.t[i]);
    for (Eigen::Index j = 0; j < r.monitors.cols(); ++j) fmt::format_to(it, ",{}", r.monitors(i, j));
    if (r.control.size() > 0) fmt::format_to(it, ",{}", r.control[i]);
    if (!r.linear_counts.empty()) fmt::format_to(it, ",{}", r.linear_counts[k]);
    if (!r.table_counts.empty()) fmt::format_to(it, ",{}", r.table_counts[k]);
    fmt::format_to(it, ",{}\n", r.temp_measured_c[i]);
  }
  std::ofstream os(file, std::ios::binary);
  os.write(out.data(), static_cast<std::streamsize>(out.size()));
  if (!os) throw std::runtime_error("cannot write " + file.string());
}

}  // namespace

dataset::Dataset sensor_dataset(const config::BenchConfig& bench, const BenchSimulation& sim, std::size_t s) {
  const config::SensorUnderTest& sensor = bench.sensors.at(s);
  dataset::Dataset ds = dataset::bench_sensor_dataset(bench, s);
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    const config::TestCase& tc = bench.cases[c];
    const SimulatedCase& sc = sim.cases[c];
    dataset::CaseData cd;
    cd.name = tc.name;
    cd.kind = tc.kind;
    cd.file = tc.name + ".csv";
    cd.m_ec = config::nominal_m_ec(tc, sensor);   // nominal: the analyzer must not see the misalignments
    cd.mounting = tc.mounting;
    cd.placement_sd_rad = tc.placement_error_rad;   // the fixture's stated accuracy
    cd.sample_period_s = 1.0 / bench.sample_rate_hz;
    cd.t = sc.motion.t;
    cd.a_e = sc.sensors[s].reference(sc.motion);
    cd.w_e = sc.motion.w_e;
    cd.temp = sc.motion.temp_c;
    cd.y = sc.sensors[s].y;
    cd.phase_names = sc.motion.phase_names;
    cd.phase = sc.motion.phase;
    ds.cases.push_back(std::move(cd));
  }
  return ds;
}

void write_simulation(const config::BenchConfig& bench, const BenchSimulation& sim, const std::filesystem::path& out) {
  for (std::size_t s = 0; s < bench.sensors.size(); ++s) {
    const std::filesystem::path dir = sensor_dir(bench, s, out);
    const dataset::Dataset data = sensor_dataset(bench, sim, s);
    // Every sensor's dataset and the references hold the same rows: room for all of them is asked
    // for before the first is written, the references (monitoring and control channels, encoder
    // counts) taken as two datasets' worth.
    if (s == 0) {
      require_free_space(out, (bench.sensors.size() + 2) * dataset::csv_bytes(data), fmt::format("simulation {}", out.string()));
      std::filesystem::create_directories(out);
    }
    dataset::write_dataset(dir, data);
    write_truth(bench, sim, s, dir / "truth.toml");
  }
  std::filesystem::create_directories(out);
  for (const config::Unit& unit : bench.units) write_unit_truth(bench, sim, unit, out / ("unit-" + unit.name + "-truth.toml"));
  std::filesystem::create_directories(out / "references");
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    write_references(bench, sim.cases[c], out / "references" / (bench.cases[c].name + ".csv"));
  }
}

void print_summary(const config::BenchConfig& bench, const BenchSimulation& sim, std::ostream& os) {
  fmt::print(os, "bench {} ({}): {} sensor(s), {} case(s), {} Hz\n", bench.name, bench.file.string(),
             bench.sensors.size(), bench.cases.size(), bench.sample_rate_hz);
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    const config::TestCase& tc = bench.cases[c];
    const CaseMotion& m = sim.cases[c].motion;
    fmt::print(os, "case {}: kind {}, {} samples, {:.3f} s\n", tc.name, config::to_string(tc.kind), m.size(),
               static_cast<double>(m.size()) / bench.sample_rate_hz);
    std::string phases;
    for (const PhaseSpan& span : m.spans) {
      phases += fmt::format("{}{} {:.3g} s", phases.empty() ? "" : ", ", config::phase_label(span.kind),
                            static_cast<double>(span.end - span.begin) / bench.sample_rate_hz);
    }
    fmt::print(os, "  phases: {}\n", phases);
    if (m.size() == 0) continue;
    const char* axes[] = {"a_x", "a_y", "a_z"};
    for (int a = 0; a < 3; ++a) {
      fmt::print(os, "  {} [{:+.4f}, {:+.4f}] g\n", axes[a], mps2_to_g(m.f_e.col(a).minCoeff()),
                 mps2_to_g(m.f_e.col(a).maxCoeff()));
    }
    fmt::print(os, "  temp [{:.3f}, {:.3f}] degC\n", m.temp_c.minCoeff(), m.temp_c.maxCoeff());
    for (std::size_t s = 0; s < bench.sensors.size(); ++s) {
      const Eigen::VectorXd& y = sim.cases[c].sensors[s].y;
      fmt::print(os, "  y[{}] [{:.6g}, {:.6g}] {}\n", bench.sensors[s].name, y.minCoeff(), y.maxCoeff(),
                 bench.sensors[s].output_unit);
    }
  }
}

int run_simulate(const std::filesystem::path& bench_path, const std::filesystem::path& out, std::ostream& summary,
                 std::optional<std::uint64_t> seed) {
  config::BenchConfig bench = config::load_bench_config(bench_path);
  if (seed) config::reseed(bench, *seed);
  if (!bench.simulated) {
    throw InputError(SourcePosition{bench_path.string(), 0, 0},
                     "bench.backend is \"real\": simulate needs a simulated bench (backend = \"sim\")");
  }
  const BenchSimulation sim = simulate_bench(bench);
  write_simulation(bench, sim, out);
  print_summary(bench, sim, summary);
  return kExitOk;
}

}  // namespace inertia::sim
