// The bench file's test plan: the cases ([[case]], also from included files) and their phases
// ([[case.phase]]), which phases each facility can run, and the fixture slots a case's
// orientation names. The loader (bench_config.cpp) calls read_cases (bench_config_readers.hpp)
// for the bench file's [[case]] tables.
#include <cmath>
#include <numbers>
#include <optional>
#include <set>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/config/bench_config_readers.hpp"
#include "common/config/toml_reader.hpp"
#include "common/units.hpp"

namespace inertia::config {

namespace detail {

namespace {

// Which phases make physical sense on which facility.
bool phase_allowed(CaseKind c, PhaseKind p) {
  if (p == PhaseKind::Dwell || p == PhaseKind::ThermalStep) return true;
  switch (c) {
    case CaseKind::RotationTable: return p == PhaseKind::Rotation;
    case CaseKind::Shaker: return p == PhaseKind::Sine || p == PhaseKind::Random || p == PhaseKind::Shock;
    case CaseKind::Thermal:
    case CaseKind::Static: return false;
  }
  return false;
}

Phase read_phase(const TableReader& t, CaseKind case_kind, double sample_rate_hz) {
  Phase p;
  p.where = t.where();
  p.command_at = p.where;
  p.kind = static_cast<PhaseKind>(
      t.choice("kind", {"dwell", "rotation", "sine", "random", "shock", "thermal_step"}));
  if (!phase_allowed(case_kind, p.kind)) {
    t.fail_key("kind", std::string("a ") + to_string(p.kind) + " phase cannot run in a " +
                           to_string(case_kind) + " case");
  }
  p.duration_s = t.positive("duration_s");
  if (p.duration_s * sample_rate_hz < 1.0) t.fail_key("duration_s", "is shorter than one sample period");
  const double nyquist = sample_rate_hz / 2.0;
  switch (p.kind) {
    case PhaseKind::Dwell: break;
    case PhaseKind::Rotation:
      p.axis = t.nonzero_vec3("axis").normalized();
      if (t.has("rate_deg_s") == t.has("angle_deg")) {
        t.fail_here("a rotation needs exactly one of rate_deg_s or angle_deg");
      }
      if (t.has("rate_deg_s")) p.rate_rad_s = deg_to_rad(t.number("rate_deg_s"));
      if (t.has("angle_deg")) p.angle_rad = deg_to_rad(t.number("angle_deg"));
      p.command_at = t.where(t.has("rate_deg_s") ? "rate_deg_s" : "angle_deg");
      break;
    case PhaseKind::Sine:
      p.frequency_hz = t.positive("frequency_hz");
      if (p.frequency_hz >= nyquist) t.fail_key("frequency_hz", "must be below the Nyquist frequency");
      p.amplitude_mps2 = g_to_mps2(t.positive("amplitude_g"));
      p.ramp_cycles = t.number_in("ramp_cycles", p.ramp_cycles, 0.0, 1e6);
      if (2.0 * p.ramp_cycles / p.frequency_hz > p.duration_s) {
        t.fail_key("ramp_cycles", "the two ramps are longer than duration_s");
      }
      break;
    case PhaseKind::Random:
      p.f1_hz = t.positive("f1_hz");
      p.f2_hz = t.positive("f2_hz");
      if (!(p.f1_hz < p.f2_hz)) t.fail_key("f2_hz", "must be greater than f1_hz");
      if (p.f2_hz >= nyquist) t.fail_key("f2_hz", "must be below the Nyquist frequency");
      p.rms_mps2 = g_to_mps2(t.positive("grms"));
      p.ramp_s = t.number_in("ramp_s", p.ramp_s, 0.0, 1e6);
      if (2.0 * p.ramp_s >= p.duration_s) t.fail_key("ramp_s", "the two tapers are longer than duration_s");
      if (p.f1_hz * p.duration_s < 2.0) {
        t.fail_key("f1_hz", "the phase must span at least two periods of f1_hz");
      }
      // The synthesis puts equal amplitudes on the FFT bins of the band (spacing <= 1/duration).
      if ((p.f2_hz - p.f1_hz) * p.duration_s < 4.0) {
        t.fail_key("f2_hz", "the band f1_hz..f2_hz must hold at least 4 frequency bins (width >= 4/duration_s)");
      }
      break;
    case PhaseKind::Shock:
      p.peak_mps2 = g_to_mps2(t.number("peak_g"));
      if (p.peak_mps2 == 0.0) t.fail_key("peak_g", "must not be 0");
      p.pulse_s = t.positive("pulse_s");
      p.compensation = t.number_in("compensation", p.compensation, 1.0, 1e3);
      if (p.pulse_s * (1.0 + 2.0 * p.compensation) > p.duration_s) {
        t.fail_key("pulse_s", "pulse plus compensating pulses (pulse_s*(1 + 2*compensation)) exceed duration_s");
      }
      if (p.pulse_s * sample_rate_hz < 4.0) t.fail_key("pulse_s", "needs at least 4 samples");
      break;
    case PhaseKind::ThermalStep:
      if (!t.has("setpoint_c")) t.fail_here("missing key 'setpoint_c' (expected a number)");
      p.setpoint_c = t.number_in("setpoint_c", 0.0, -100.0, 200.0);
      p.command_at = t.where("setpoint_c");
      break;
  }
  if (p.kind == PhaseKind::Sine || p.kind == PhaseKind::Random || p.kind == PhaseKind::Shock) {
    if (t.has("profile")) {
      p.profile = static_cast<int>(t.integer_in("profile", 0, 0, 65535));
      p.command_at = t.where("profile");
    }
  }
  t.finish();
  return p;
}

TestCase read_case(const TableReader& t, double alpha_rad, double sample_rate_hz) {
  TestCase c;
  c.where = t.where();
  c.name = t.string("name");
  if (c.name.empty() || c.name.find_first_of("/\\ ") != std::string::npos) {
    t.fail_key("name", "must be a non-empty name without '/', '\\' or spaces (it names a file)");
  }
  c.kind = static_cast<CaseKind>(t.choice("kind", {"rotation_table", "shaker", "thermal", "static"}));
  if (t.has("orientation") == t.has("m_ec")) {
    t.fail_here("a case needs exactly one of orientation (\"IA\", \"PA\", \"OA\": Fig. 2 slot) or m_ec");
  }
  if (t.has("orientation")) {
    c.orientation = static_cast<Orientation>(t.choice("orientation", {"IA", "PA", "OA"}));
    c.m_ec = slot_orientation(*c.orientation, alpha_rad);
  } else {
    c.m_ec = t.mat3("m_ec");
    if (!frames::is_rotation(c.m_ec, 1e-6)) t.fail_key("m_ec", "must be a rotation (orthonormal, det +1)");
  }
  c.mounting = t.string_or("mounting", "");
  c.fixture_misalignment = read_axis_angle(t, "fixture_misalignment");
  c.case_misalignment = read_axis_angle(t, "case_misalignment");
  c.start_attitude = read_axis_angle(t, "start_attitude");
  if (t.has("placement_error_deg")) {
    const double deg = t.number("placement_error_deg");
    if (!(deg >= 0.0 && deg <= 10.0)) t.fail_key("placement_error_deg", "must be within 0..10 degrees");
    c.placement_error_rad = deg * std::numbers::pi / 180.0;
  }
  if (c.kind != CaseKind::RotationTable && t.has("start_attitude")) {
    t.fail_key("start_attitude", "only a rotation_table case has a table attitude");
  }
  for (const TableReader& p : t.tables("phase")) c.phases.push_back(read_phase(p, c.kind, sample_rate_hz));
  if (c.phases.empty()) t.fail_here("a case needs at least one [[case.phase]]");
  t.finish();
  return c;
}

}  // namespace

void read_cases(const TableReader& root, BenchConfig& cfg, std::set<std::string>& names, int depth,
                const SourceFetch& fetch) {
  for (const TableReader& c : root.tables("case")) {
    TestCase tc = read_case(c, cfg.alpha_rad, cfg.sample_rate_hz);
    if (!names.insert(tc.name).second) c.fail_key("name", "duplicate case name '" + tc.name + "'");
    cfg.cases.push_back(std::move(tc));
  }
  if (!root.has("include")) return;
  const toml::node* inc = root.node("include");
  const toml::array* list = inc->as_array();
  if (list == nullptr) root.fail(*inc, "include must be an array of file names");
  if (depth > 4) root.fail(*inc, "include nested too deeply (a cycle?)");
  const std::filesystem::path base = std::filesystem::path(root.file()).parent_path();
  for (const toml::node& e : *list) {
    const auto name = e.value_exact<std::string>();
    if (!name) root.fail(e, "include must list file names (strings)");
    const std::filesystem::path path = base / *name;
    std::optional<std::string> text = fetch(path);
    if (!text) root.fail(e, "included file '" + path.string() + "' not found");
    const toml::table sub = parse_toml_text(*text, path.string());
    cfg.sources.push_back({path, std::move(*text)});
    // An included file holds a test plan only: [[case]] tables and further includes.
    const TableReader reader(sub, "", path.string());
    read_cases(reader, cfg, names, depth + 1, fetch);
    reader.finish();
  }
}

}  // namespace detail

frames::Dcm slot_orientation(Orientation orientation, double alpha_rad) {
  const double c = std::cos(alpha_rad), s = std::sin(alpha_rad);
  const int k = static_cast<int>(orientation);
  frames::Dcm m;
  m.row(k) << c, s, 0.0;
  m.row((k + 1) % 3) << 0.0, 0.0, 1.0;
  m.row((k + 2) % 3) << s, -c, 0.0;   // = row k x row k+1: right-handed (det +1)
  return m;
}

frames::Dcm unit_axis_frame(int unit_axis) {
  frames::Dcm m = frames::Dcm::Zero();
  if (unit_axis < 0) return frames::Dcm::Identity();
  for (int row = 0; row < 3; ++row) m(row, (unit_axis + row) % 3) = 1.0;   // a cyclic turn: det +1
  return m;
}

frames::Dcm nominal_m_ec(const TestCase& test_case, int unit_axis) { return unit_axis_frame(unit_axis) * test_case.m_ec; }

frames::Dcm nominal_m_ec(const TestCase& test_case, const SensorUnderTest& sensor) {
  return nominal_m_ec(test_case, sensor.unit_axis);
}

const char* to_string(PhaseKind kind) {
  switch (kind) {
    case PhaseKind::Dwell: return "dwell";
    case PhaseKind::Rotation: return "rotation";
    case PhaseKind::Sine: return "sine";
    case PhaseKind::Random: return "random";
    case PhaseKind::Shock: return "shock";
    case PhaseKind::ThermalStep: return "thermal_step";
  }
  return "?";
}

const char* to_string(Orientation orientation) {
  switch (orientation) {
    case Orientation::IA: return "IA";
    case Orientation::PA: return "PA";
    case Orientation::OA: return "OA";
  }
  return "?";
}

}  // namespace inertia::config
