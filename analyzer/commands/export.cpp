#include "analyzer/commands/export.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <fmt/ranges.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <sstream>

#include "analyzer/commands/compensate.hpp"
#include "analyzer/compensate/c_export.hpp"
#include "analyzer/unit/kalibr_intrinsics.hpp"
#include "analyzer/unit/unit_covariance.hpp"
#include "analyzer/unit/unit_files.hpp"
#include "analyzer/unit/unit_inverse.hpp"
#include "analyzer/unit/unit_model.hpp"
#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/compensate/static_response.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/atomic_file.hpp"
#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {

using ident::FactorFunction;
using ident::Variable;

namespace {

using compensate::static_output;
using compensate::static_sensitivity;
using Values = compensate::InputValues;

struct Omission {
  std::vector<std::string> terms;   // left out, with the largest error each costs alone
  std::vector<double> each;
  double together = 0.0;            // the largest error of all of them together
};

/// What a format that keeps only the ideal response S x of the sensed input x (and, where
/// `keeps_bias`, the bias) leaves out, in the sensed input's unit over the characterized range: a
/// grid of 5 points per input the [range] states (other inputs at 0).
Omission omission(const model::ModelFile& model, Variable sensed, bool keeps_bias) {
  Omission o;
  const double s = static_sensitivity(model, sensed);
  std::vector<Variable> axes;
  for (const auto& [v, span] : model.range) axes.push_back(v);
  const auto points = static_cast<long>(std::pow(5.0, static_cast<double>(axes.size())));
  const auto ideal_term = [&](const ident::Term& t) {
    const auto& f = t.factors();
    if (t.is_bias()) return keeps_bias;
    return f.size() == 1 && f[0].power == 1 && f[0].function == FactorFunction::Plain &&
           (f[0].variable == sensed || (f[0].variable == Variable::Y && f[0].lag > 0));
  };
  for (const model::ModelTerm& t : model.terms) {
    if (!t.term.is_noise_term() && !ideal_term(t.term)) o.terms.push_back(t.term.to_string());
  }
  o.each.assign(o.terms.size(), 0.0);
  for (long p = 0; p < points; ++p) {
    Values values{};
    long rest = p;
    for (Variable v : axes) {
      const auto& span = model.range.at(v);
      values[static_cast<std::size_t>(v)] = span.lowest + (span.highest - span.lowest) * static_cast<double>(rest % 5) / 4.0;
      rest /= 5;
    }
    const double full = static_output(model, values, [](const ident::Term&) { return true; });
    const double kept = static_output(model, values, ideal_term);
    o.together = std::max(o.together, std::abs(full - kept) / std::abs(s));
    for (std::size_t i = 0; i < o.terms.size(); ++i) {
      const ident::Term out = ident::parse_term(o.terms[i]);
      const double without = static_output(model, values, [&](const ident::Term& t) { return !(t == out); });
      o.each[i] = std::max(o.each[i], std::abs(full - without) / std::abs(s));
    }
  }
  return o;
}

std::string omission_text(const Omission& o, const char* unit, const std::string& comment) {
  if (o.terms.empty()) return comment + " every term of the model is kept\n";
  std::string s = fmt::format("{} left out (largest error over the box of the characterized ranges, {}): all together {:.3g}\n", comment,
                              unit, o.together);
  for (std::size_t i = 0; i < o.terms.size(); ++i) s += fmt::format("{}   {}: {:.3g}\n", comment, o.terms[i], o.each[i]);
  return s;
}

nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json model_json(const model::ModelFile& m) {
  nlohmann::json j;
  j["schema"] = "inertia-model-1";
  j["sensor"] = dataset::to_string(m.sensor);
  if (!m.name.empty()) j["sensor_name"] = m.name;
  if (!m.output_unit.empty()) j["output_unit"] = m.output_unit;
  if (m.t_ref) j["t_ref"] = *m.t_ref;
  if (m.sample_period_s) j["sample_period_s"] = *m.sample_period_s;
  j["m_cs"] = matrix_json(m.m_cs);
  if (m.square_highpass_rad_s) j["square_highpass_rad_s"] = *m.square_highpass_rad_s;
  j["terms"] = nlohmann::json::array();
  for (const model::ModelTerm& t : m.terms) {
    nlohmann::json term{{"term", t.term.to_string()},
                        {"coefficient", t.coefficient},
                        {"physical_name", ident::physical_name(t.term, m.sensor)},
                        {"denominator", t.term.is_output_multiplied()},
                        {"noise", t.term.is_noise_term()}};
    if (t.std) term["std"] = *t.std;
    j["terms"].push_back(term);
  }
  if (m.covariance.size() > 0) j["covariance"] = matrix_json(m.covariance);
  j["range"] = nlohmann::json::object();
  for (const auto& [v, span] : m.range) j["range"][ident::variable_name(v)] = {span.lowest, span.highest};
  j["case_frames"] = nlohmann::json::array();
  for (const auto& f : m.case_frames) j["case_frames"].push_back({{"case", f.case_name}, {"m_es", matrix_json(f.m_es)}});
  nlohmann::json noise = nlohmann::json::object();
  if (m.white_sd) noise["white_sd"] = *m.white_sd;
  if (m.output_sd) noise["output_sd"] = *m.output_sd;
  for (std::size_t i = 0; i < model::ModelFile::NoiseTerms::kKeys.size(); ++i) {
    if (!m.noise.values[i]) continue;
    nlohmann::json term{{"value", *m.noise.values[i]}};
    if (m.noise.sd[i]) term["std"] = *m.noise.sd[i];
    noise[model::ModelFile::NoiseTerms::kKeys[i]] = term;
  }
  j["noise"] = noise;
  return j;
}

}  // namespace

namespace {

/// A unit's exports: its joint compensation as C (with test vectors from the members' datasets),
/// imucal's file, Kalibr's results, or the unit as JSON (its triads and each member's model).
int run_unit_export(const ExportOptions& options, std::ostream& out) {
  const unit::UnitModel unit = unit::read_unit_model(options.model);
  const unit::Triads triads = unit::triads_of(unit.members);
  std::filesystem::create_directories(options.out);
  if (options.format == "c") {
    const unit::UnitInverse inverse(unit);
    std::string prefix = options.prefix;
    if (prefix.empty()) {
      prefix = "inertia_" + unit.unit;
      std::replace_if(prefix.begin(), prefix.end(), [](char c) { return !std::isalnum(static_cast<unsigned char>(c)); }, '_');
    }
    std::vector<std::string> outputs, unknowns;
    std::optional<double> period;
    for (const model::ModelFile& m : unit.members) {
      outputs.push_back(m.name);
      if (!period) period = m.sample_period_s;
    }
    for (const Variable v : inverse.unknowns()) unknowns.emplace_back(ident::variable_name(v));
    const compensate::JointCSource c = compensate::generate_joint_c(
        inverse.joint(), outputs, unknowns, prefix, options.single_precision ? compensate::CPrecision::Float : compensate::CPrecision::Double,
        period);
    write_file_atomically(options.out / (prefix + ".h"), c.header);
    write_file_atomically(options.out / (prefix + ".c"), c.source);
    fmt::print(out, "wrote {0}/{1}.h and {0}/{1}.c ({2}): {1}_compensate(state, inputs [{3} known], y [{4}]) -> {5}\n", options.out.string(),
               prefix, options.single_precision ? "float" : "double", c.inputs.size(), fmt::join(outputs, ", "), fmt::join(unknowns, ", "));
    if (!options.vectors.empty()) {
      const std::vector<dataset::Dataset> data = unit_records(unit, options.vectors, {});
      std::vector<CompensationRecord> records;
      for (std::size_t m = 0; m < unit.members.size(); ++m)
        records.push_back(compensation_record(unit.members[m], inverse.members()[m], data[m], 0, true, false));
      const Eigen::Index n = std::min<Eigen::Index>(records.front().signals.size(), options.vector_samples);
      std::vector<ident::SignalSet> heads;
      for (const CompensationRecord& r : records) {
        ident::SignalSet head(n, r.signals.origin());
        for (int v = 0; v < ident::kVariableCount; ++v) {
          const auto variable = static_cast<Variable>(v);
          if (r.signals.has(variable)) head.set(variable, r.signals.get(variable).head(n));
        }
        heads.push_back(std::move(head));
      }
      std::vector<const ident::SignalSet*> pointers;
      for (const ident::SignalSet& h : heads) pointers.push_back(&h);
      std::ostringstream vectors;
      compensate::write_joint_test_vectors(vectors, inverse.joint(), outputs, unknowns, c.inputs, pointers,
                                           data.front().cases.front().sample_period_s);
      write_file_atomically(options.out / (prefix + "_vectors.csv"), vectors.str());
      fmt::print(out, "wrote {}/{}_vectors.csv: {} samples of case '{}' and what the analyzer makes of them\n", options.out.string(), prefix,
                 n, data.front().cases.front().name);
    }
    return kExitOk;
  }
  if (options.format == "imucal") {
    write_file_atomically(options.out / "imucal.json", unit::imucal_json(triads).dump(4) + "\n");
    fmt::print(out, "wrote {}/imucal.json (imucal's FerrarisCalibrationInfo, format 2.0.0)\n", options.out.string());
    return kExitOk;
  }
  if (options.format == "kalibr") {
    write_file_atomically(options.out / "imu.yaml", unit::kalibr_yaml(triads, unit::unit_parameters(triads)));
    fmt::print(out, "wrote {}/imu.yaml (Kalibr's scale-misalignment model and noise)\n", options.out.string());
    return kExitOk;
  }
  if (options.format == "json") {
    nlohmann::json j;
    j["schema"] = "inertia-unit-1";
    j["unit"] = unit.unit;
    if (!unit.serial.empty()) j["serial"] = unit.serial;
    j["members"] = nlohmann::json::array();
    for (const model::ModelFile& m : unit.members) {
      nlohmann::json member = model_json(m);
      member["unit_axis"] = std::string(1, static_cast<char>('x' + m.unit_axis));
      j["members"].push_back(std::move(member));
    }
    j["imucal"] = unit::imucal_json(triads);
    j["covariance"] = unit::covariance_json(unit::unit_parameters(triads));
    write_file_atomically(options.out / "unit.json", j.dump(2) + "\n");
    fmt::print(out,
               "wrote {}/unit.json (each member's model as in model.json, the triads in imucal's terms, and the covariance of "
               "imucal's and Kalibr's parameters)\n",
               options.out.string());
    return kExitOk;
  }
  throw InputError(fmt::format("--format {}: expected c, imucal, json or kalibr for a unit", options.format));
}

}  // namespace

int run_export(const ExportOptions& options, std::ostream& out) {
  if (unit::is_unit_model(options.model)) return run_unit_export(options, out);
  if (options.format == "imucal")
    throw InputError("--format imucal describes a triad: give the unit.toml that `inertia-analyze unit` writes from its members");
  const model::ModelFile model = model::read_model(options.model);
  const compensate::InverseModel inverse(model);
  const Variable sensed = inverse.sensed();
  const char* unit = sensed == Variable::Ai ? "m/s^2" : "rad/s";
  std::filesystem::create_directories(options.out);

  if (options.format == "c") {
    std::string prefix = options.prefix;
    if (prefix.empty()) {
      prefix = model.name.empty() ? "inertia_model" : "inertia_" + model.name;
      std::replace_if(prefix.begin(), prefix.end(), [](char c) { return !std::isalnum(static_cast<unsigned char>(c)); }, '_');
    }
    const compensate::CSource c = compensate::generate_c(
        model, prefix, options.single_precision ? compensate::CPrecision::Float : compensate::CPrecision::Double);
    write_file_atomically(options.out / (prefix + ".h"), c.header);
    write_file_atomically(options.out / (prefix + ".c"), c.source);
    std::vector<std::string> names;
    for (Variable v : c.inputs) names.emplace_back(ident::variable_name(v));
    fmt::print(out, "wrote {0}/{1}.h and {0}/{1}.c ({2}): {1}_compensate(state, inputs [{3}], y) -> {4} in {5}\n",
               options.out.string(), prefix, options.single_precision ? "float" : "double", fmt::join(names, ", "),
               ident::variable_name(sensed), unit);
    if (!options.vectors.empty()) {
      const dataset::Dataset data = dataset::read_dataset(options.vectors);
      const CompensationRecord record = compensation_record(model, inverse, data, 0, true, false);
      const Eigen::Index n = std::min<Eigen::Index>(record.signals.size(), options.vector_samples);
      ident::SignalSet head(n, record.signals.origin());
      for (int v = 0; v < ident::kVariableCount; ++v) {
        const auto variable = static_cast<Variable>(v);
        if (record.signals.has(variable)) head.set(variable, record.signals.get(variable).head(n));
      }
      std::ostringstream vectors;
      compensate::write_test_vectors(vectors, model, c.inputs, head, data.cases.front().sample_period_s);
      write_file_atomically(options.out / (prefix + "_vectors.csv"), vectors.str());
      fmt::print(out, "wrote {}/{}_vectors.csv: {} samples of case '{}' and what the analyzer makes of them\n",
                 options.out.string(), prefix, n, data.cases.front().name);
    }
    return kExitOk;
  }
  if (options.format == "json") {
    write_file_atomically(options.out / "model.json", model_json(model).dump(2) + "\n");
    fmt::print(out, "wrote {}/model.json (schema tests/schema/model.schema.json)\n", options.out.string());
    return kExitOk;
  }
  if (options.format == "kalibr") {
    const double s = static_sensitivity(model, sensed);
    const bool acc = sensed == Variable::Ai;
    const std::string kind = acc ? "accelerometer" : "gyroscope";
    std::string yaml = fmt::format("# Kalibr IMU noise parameters of {} '{}' (inertia-analyze export; static sensitivity {:.9g} {} per {})\n",
                                   kind, model.name, s, model.output_unit.empty() ? "output unit" : model.output_unit, unit);
    yaml += "# One sensor output: the other sensor kind's keys are for its own model's export.\n";
    yaml += "rostopic: /imu0\n";
    if (model.sample_period_s) yaml += fmt::format("update_rate: {} # Hz\n", 1.0 / *model.sample_period_s);
    yaml += unit::kalibr_noise_yaml(kind, unit::kalibr_noise(model));
    const Omission o = omission(model, sensed, false);
    yaml += "# Kalibr's IMU model holds no deterministic terms of one output (its scale-misalignment intrinsics\n"
            "# describe a triaxial unit; it estimates the bias online as a random walk).\n";
    yaml += omission_text(o, unit, "#");
    write_file_atomically(options.out / "imu.yaml", yaml);
    fmt::print(out, "wrote {}/imu.yaml\n{}", options.out.string(), omission_text(o, unit, " "));
    return kExitOk;
  }
  throw InputError(fmt::format("--format {}: expected c, json or kalibr", options.format));
}

}  // namespace inertia::commands
