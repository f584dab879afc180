#include "analyzer/unit/unit_files.hpp"

#include <fmt/format.h>

#include <cmath>
#include <map>

#include "analyzer/unit/kalibr_intrinsics.hpp"
#include "analyzer/unit/unit_covariance.hpp"
#include "analyzer/unit/unit_model.hpp"
#include "common/input_error.hpp"
#include "common/toml_text.hpp"

namespace inertia::unit {

const TriadFrame& Triads::any() const { return accelerometer ? *accelerometer : *gyroscope; }

Triads triads_of(const std::vector<model::ModelFile>& members) {
  Triads t;
  for (const model::ModelFile& m : members) (m.sensor == dataset::SensorKind::Gyroscope ? t.gyroscopes : t.accelerometers).push_back(m);
  if (!t.accelerometers.empty()) t.accelerometer = triad_frame(t.accelerometers);
  if (!t.gyroscopes.empty()) t.gyroscope = triad_frame(t.gyroscopes);
  if (t.accelerometer && t.gyroscope && (t.accelerometer->unit != t.gyroscope->unit || t.accelerometer->serial != t.gyroscope->serial))
    throw InputError(fmt::format("unit: the accelerometers are of unit '{}', the gyroscopes of '{}'", t.accelerometer->unit, t.gyroscope->unit));
  if (!t.accelerometer && !t.gyroscope) throw InputError("unit: no member given");
  return t;
}

namespace {

std::string row_text(const Eigen::Vector3d& v) { return fmt::format("[{}, {}, {}]", toml_float(v(0)), toml_float(v(1)), toml_float(v(2))); }

std::string matrix_text(const Eigen::Matrix3d& m) {
  return fmt::format("[{}, {}, {}]", row_text(m.row(0)), row_text(m.row(1)), row_text(m.row(2)));
}

/// One triad's table in unit.toml, [accelerometer] or [gyroscope].
std::string triad_toml(const TriadFrame& f) {
  const bool gyro = f.kind == dataset::SensorKind::Gyroscope;
  const std::string table = dataset::to_string(f.kind);
  std::string s = fmt::format("\n[{}]\n", table);
  if (!f.output_unit.empty()) s += "output_unit = " + toml_quote(f.output_unit) + "\n";
  s += fmt::format("input_unit = \"{}\"\n", gyro ? "rad/s" : "m/s^2");
  s += fmt::format("members = [{}, {}, {}]\n", toml_quote(f.axes[0].sensor), toml_quote(f.axes[1].sensor), toml_quote(f.axes[2].sensor));
  s += fmt::format("K = {}            # the diagonal of K: |s_k|\nK_sd = {}\n", row_text(f.scale), row_text(f.scale_sd));
  s += fmt::format("R = {}   # rows: the sensitive axes\n", matrix_text(f.misalignment));
  s += fmt::format("b = {}\nb_sd = {}\n", row_text(f.bias), row_text(f.bias_sd));
  if (gyro) s += fmt::format("K_ga = {}   # output unit per m/s^2: the offset is K_ga a + b\n", matrix_text(f.g_sensitivity));
  s += fmt::format("\n[{}.non_orthogonality]   # asin(n_j . n_k), rad: how much closer than 90 deg\n", table);
  for (std::size_t p = 0; p < 3; ++p) {
    s += fmt::format("{0} = {1}\n{0}_sd = {2}\n", kAxisPairs[p], toml_float(f.non_orthogonality[p]), toml_float(f.non_orthogonality_sd[p]));
    if (std::isfinite(f.non_orthogonality_dof[p])) s += fmt::format("{}_dof = {}\n", kAxisPairs[p], toml_float(f.non_orthogonality_dof[p]));
    s += fmt::format("{}_interval95 = [{}, {}]\n", kAxisPairs[p], toml_float(f.non_orthogonality[p] - f.non_orthogonality_half_width[p]),
                     toml_float(f.non_orthogonality[p] + f.non_orthogonality_half_width[p]));
  }
  for (std::size_t k = 0; k < 3; ++k) {
    const TriadAxis& a = f.axes[k];
    s += fmt::format("\n[{}.axis.{}]\nsensor = {}\nmodel = {}\nsensitivity = {}\ncovariance = {}\nangles_estimated = {}\n", table,
                     static_cast<char>('x' + k), toml_quote(a.sensor), toml_quote(member_file_name(a.sensor)), row_text(a.sensitivity), matrix_text(a.covariance),
                     a.angles_estimated ? "true" : "false");
  }
  return s;
}

nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
  nlohmann::json j = nlohmann::json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    j.push_back(std::move(row));
  }
  return j;
}

/// A matrix of any shape as a TOML array of rows.
std::string toml_matrix(const Eigen::MatrixXd& m) {
  std::string s = "[";
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    s += r == 0 ? "[" : ", [";
    for (Eigen::Index c = 0; c < m.cols(); ++c) s += (c == 0 ? "" : ", ") + toml_float(m(r, c));
    s += "]";
  }
  return s + "]";
}

std::string yaml_matrix(const Eigen::Matrix3d& matrix) {
  const Eigen::Matrix3d m = matrix.array() + 0.0;   // no negative zeros
  return fmt::format("[[{}, {}, {}], [{}, {}, {}], [{}, {}, {}]]", m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1),
                     m(2, 2));
}

}  // namespace

nlohmann::json imucal_json(const Triads& triads) {
  const std::optional<TriadFrame>& acc = triads.accelerometer;
  const std::optional<TriadFrame>& gyro = triads.gyroscope;
  nlohmann::json j;
  j["acc_unit"] = acc ? nlohmann::json("m/s^2") : nlohmann::json();
  j["gyr_unit"] = gyro ? nlohmann::json("rad/s") : nlohmann::json();
  j["from_acc_unit"] = acc ? nlohmann::json(acc->output_unit) : nlohmann::json();
  j["from_gyr_unit"] = gyro ? nlohmann::json(gyro->output_unit) : nlohmann::json();
  const TriadFrame& any = triads.any();
  std::string comment = fmt::format("inertia-analyze unit: unit {}{}; the settled linear part of each member's model", any.unit,
                                    any.serial.empty() ? "" : " serial " + any.serial);
  if (!acc) comment += "; the accelerometer triad was not characterized: K_a, R_a, b_a are null";
  if (!gyro) comment += "; the gyroscope triad was not characterized: K_g, R_g, K_ga, b_g are null";
  j["comment"] = comment;
  j["K_a"] = acc ? matrix_json(acc->scale.asDiagonal().toDenseMatrix()) : nlohmann::json();
  j["R_a"] = acc ? matrix_json(acc->misalignment) : nlohmann::json();
  j["b_a"] = acc ? nlohmann::json({acc->bias(0), acc->bias(1), acc->bias(2)}) : nlohmann::json();
  j["K_g"] = gyro ? matrix_json(gyro->scale.asDiagonal().toDenseMatrix()) : nlohmann::json();
  j["R_g"] = gyro ? matrix_json(gyro->misalignment) : nlohmann::json();
  j["K_ga"] = gyro ? matrix_json(gyro->g_sensitivity) : nlohmann::json();
  j["b_g"] = gyro ? nlohmann::json({gyro->bias(0), gyro->bias(1), gyro->bias(2)}) : nlohmann::json();
  j["cal_type"] = "Ferraris";
  j["_format_version"] = "2.0.0";
  return j;
}

nlohmann::json covariance_json(const std::vector<UnitParameter>& parameters) {
  nlohmann::json j = nlohmann::json::object();
  for (const UnitParameter& p : parameters) {
    nlohmann::json entry = {{"value", p.value.cols() == 1 ? nlohmann::json(std::vector<double>(p.value.data(), p.value.data() + 3))
                                                          : matrix_json(p.value)},
                            {"covariance", matrix_json(p.covariance)}};
    if (p.rotation) entry["rotation"] = true;
    j[p.name] = std::move(entry);
  }
  return j;
}

std::string kalibr_yaml(const Triads& triads, const std::vector<UnitParameter>& parameters) {
  const std::vector<model::ModelFile>& accelerometers = triads.accelerometers;
  const std::vector<model::ModelFile>& gyroscopes = triads.gyroscopes;
  const KalibrIntrinsics k = kalibr_intrinsics(triads.accelerometer, triads.gyroscope);
  const TriadFrame& any = triads.any();
  std::string yaml = fmt::format("# Kalibr's scale-misalignment IMU model of unit {} (inertia-analyze unit): the settled linear part of\n"
                                 "# each member's model. a_m = M_a C a + b_a, w_m = M_g C_gyro_i C w + A C_gyro_i C a + b_g, with a_m, w_m\n"
                                 "# the outputs in SI (their value times their unit's) and C the rotation from the unit's frame to Kalibr's IMU frame.\n",
                                 any.unit);
  // Each matrix's standard uncertainties as a comment (unit_covariance.hpp; the covariances are in
  // unit.toml and unit.json): Kalibr's format has no place for them.
  std::map<std::string, Eigen::MatrixXd> sd;
  for (const UnitParameter& p : parameters) sd[p.name] = p.sd();
  yaml += fmt::format("# C = {}\n", yaml_matrix(k.c_imu_unit));
  if (sd.count("C") != 0) yaml += fmt::format("# C's rotation vector sd: [{}, {}, {}] rad\n", sd["C"](0), sd["C"](1), sd["C"](2));
  if (!k.note.empty()) yaml += "# Left out: " + k.note + "\n";
  yaml += "imu0:\n  model: scale-misalignment\n  rostopic: /imu0\n";
  const model::ModelFile& first = accelerometers.empty() ? gyroscopes.front() : accelerometers.front();
  if (first.sample_period_s) yaml += fmt::format("  update_rate: {}\n", 1.0 / *first.sample_period_s);
  for (const auto* members : {&accelerometers, &gyroscopes}) {
    if (members->empty()) continue;
    KalibrNoise largest;
    bool all_density = true, all_walk = true;
    for (const model::ModelFile& m : *members) {
      const KalibrNoise n = kalibr_noise(m);
      all_density = all_density && n.density.has_value();
      all_walk = all_walk && n.random_walk.has_value();
      if (n.density && (!largest.density || *n.density > *largest.density)) largest.density = n.density;
      if (n.random_walk && (!largest.random_walk || *n.random_walk > *largest.random_walk)) largest.random_walk = n.random_walk;
      largest.density_from_white = largest.density_from_white || n.density_from_white;
    }
    if (!all_density) largest.density.reset();
    if (!all_walk) largest.random_walk.reset();
    std::string lines = kalibr_noise_yaml(dataset::to_string(members->front().sensor), largest);
    for (std::size_t at = 0; at < lines.size();) {
      const std::size_t end = lines.find('\n', at);
      yaml += "  " + lines.substr(at, end - at + 1);
      at = end + 1;
    }
  }
  const auto sd_comment = [&](const std::string& name, const char* what) {
    const Eigen::MatrixXd& m = sd.at(name);
    return m.cols() == 1 ? fmt::format("    # {} sd: [{}, {}, {}] rad\n", what, m(0), m(1), m(2))
                         : fmt::format("    # {} sd: {}\n", what, yaml_matrix(m));
  };
  if (k.m_accel) yaml += fmt::format("  accelerometers:\n    M: {}\n{}", yaml_matrix(*k.m_accel), sd_comment("M_a", "M"));
  if (k.m_gyro)
    yaml += fmt::format("  gyroscopes:\n    M: {}\n{}    A: {}   # (rad/s) per (m/s^2)\n{}    C_gyro_i: {}\n{}", yaml_matrix(*k.m_gyro),
                        sd_comment("M_g", "M"), yaml_matrix(*k.a_gyro), sd_comment("A", "A"), yaml_matrix(k.c_gyro_i),
                        sd_comment("C_gyro_i", "C_gyro_i's rotation vector"));
  return yaml;
}


std::string unit_toml(const Triads& triads, const std::vector<UnitParameter>& parameters) {
  const TriadFrame& any = triads.any();
  std::string toml = "# The triads of a unit in its housing's frame (inertia-analyze unit). Sensitivities in the members' output\n"
                     "# unit per input unit (m/s^2 or rad/s); input = R^-1 K^-1 (y - b) (imucal's convention); sd: standard\n"
                     "# uncertainties.\n";
  toml += "unit = " + toml_quote(any.unit) + "\n";
  if (!any.serial.empty()) toml += "serial = " + toml_quote(any.serial) + "\n";
  for (const auto& triad : {triads.accelerometer, triads.gyroscope}) {
    if (triad) toml += triad_toml(*triad);
  }
  toml += "\n[covariance]   # of each parameter: a matrix's elements row by row (9 x 9), a vector's (3 x 3), a rotation's\n"
          "               # rotation vector d, C' = exp([d]x) C (rad^2); Kalibr's M_a C M_g A C_gyro_i as in kalibr.yaml\n";
  for (const UnitParameter& p : parameters) {
    toml += fmt::format("{} = {}\n", p.name, toml_matrix(p.covariance));
  }
  return toml;
}

}  // namespace inertia::unit
