#include "analyzer/commands/compensate.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <fmt/ranges.h>

#include <cmath>
#include <iostream>
#include <iterator>
#include <algorithm>
#include <array>
#include <limits>

#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/fusion/log_dataset.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/atomic_file.hpp"
#include "analyzer/compensate/static_response.hpp"
#include "common/dataset/dataset.hpp"
#include "common/disk_space.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {

using ident::Variable;

namespace {

/// The record matches the model: same kind of sensor, same name where both state one, the lags'
/// sample period where the model states one.
void check_record(const model::ModelFile& model, const dataset::Dataset& data, const std::string& model_label,
                  const std::string& data_label) {
  if (model.sensor != data.sensor) {
    throw InputError(fmt::format("{} is a model of an {}, {} records a {}", model_label, dataset::to_string(model.sensor),
                                 data_label, dataset::to_string(data.sensor)));
  }
  if (!model.name.empty() && !data.sensor_name.empty() && model.name != data.sensor_name) {
    throw InputError(fmt::format("{} is the model of sensor '{}', {} records sensor '{}'", model_label, model.name, data_label,
                                 data.sensor_name));
  }
  if (!model.serial.empty() && !data.serial.empty() && model.serial != data.serial) {
    throw InputError(fmt::format("{} is the model of serial number '{}', {} records serial number '{}'", model_label, model.serial,
                                 data_label, data.serial));
  }
  if (!model.sample_period_s) return;
  for (const dataset::CaseData& c : data.cases) {
    if (std::abs(c.sample_period_s - *model.sample_period_s) > dataset::kTimeJitterTolerance * *model.sample_period_s) {
      throw InputError(fmt::format("case '{}' of {} is sampled every {:.6g} s; the lags of {} count in {:.6g} s", c.name,
                                   data_label, c.sample_period_s, model_label, *model.sample_period_s));
    }
  }
}

double rms(const Eigen::VectorXd& v) {
  double s = 0.0;
  Eigen::Index n = 0;
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    if (std::isfinite(v(k))) s += v(k) * v(k), ++n;
  }
  return n > 0 ? std::sqrt(s / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

CompensationRecord compensation_record(const model::ModelFile& model, const compensate::InverseModel& inverse,
                                       const dataset::Dataset& data, std::size_t case_index, bool frames_from_model,
                                       bool other_axes_zero) {
  const dataset::CaseData& c = data.cases.at(case_index);
  const Variable sensed = inverse.sensed();
  // The characterization's M_E^S of this case (same bench, same fixture), else the nominal one.
  const auto frame = std::find_if(model.case_frames.begin(), model.case_frames.end(), [&](const model::ModelFile::CaseFrame& f) {
    return f.case_name == c.name || f.case_name == c.plan_case();
  });
  CompensationRecord record;
  record.characterized_frame = frames_from_model && frame != model.case_frames.end();
  const frames::Dcm m_es = record.characterized_frame ? frame->m_es : frames::Dcm(model.m_cs * c.m_ec);   // M_E^S = M_C^S M_E^C
  ident::VariableSet wanted = inverse.known_inputs();
  wanted.set(static_cast<std::size_t>(Variable::Y));
  wanted.set(static_cast<std::size_t>(sensed));
  const std::string label = data.dir.empty() ? std::string() : data.dir.string();
  record.signals = ident::signals_from_case(c, m_es, model.t_ref.value_or(data.t_ref), label, wanted);
  if (other_axes_zero) {
    for (Variable v : sensed == Variable::Ai ? std::array{Variable::Ap, Variable::Ao} : std::array{Variable::Wp, Variable::Wo}) {
      if (inverse.known_inputs().test(static_cast<std::size_t>(v))) record.signals.set(v, Eigen::VectorXd::Zero(record.signals.size()));
    }
  }
  return record;
}

int run_compensate(const CompensateOptions& options, std::ostream& out) {
  if (options.dataset.empty() == options.event_log.empty())
    throw InputError("compensate: give exactly one of --dataset DIR and --log FILE");
  if (!(options.range_margin >= 0.0)) throw InputError("--range-margin must be >= 0");
  const model::ModelFile model = model::read_model(options.model);
  const compensate::InverseModel inverse(model);
  const bool from_log = !options.event_log.empty();
  const dataset::Dataset data = from_log ? fusion::log_dataset(options.event_log, options.sensor.empty() ? model.name : options.sensor, std::cerr)
                                         : dataset::read_dataset(options.dataset);
  const std::string data_label = (from_log ? options.event_log : options.dataset).string();
  check_record(model, data, options.model.string(), data_label);

  const Variable sensed = inverse.sensed();
  const char* sensed_name = ident::variable_name(sensed);
  const std::array<Variable, 2> other_axes = sensed == Variable::Ai ? std::array{Variable::Ap, Variable::Ao}
                                                                    : std::array{Variable::Wp, Variable::Wo};
  // The raw output over the settled sensitivity (every lag of the sensed input, the output's lags):
  // what a user without the model would read the output as.
  const double sensitivity = compensate::static_sensitivity(model, sensed);
  const bool has_scale = std::isfinite(sensitivity) && sensitivity != 0.0;
  // The CSV grows with the record: refused before any work when the disk cannot hold it at its
  // longest (each number at 24 characters, the longest a double's shortest round trip takes).
  {
    constexpr std::uintmax_t kLongestNumber = 24, kNumbers = 7, kLongestFlag = 16;
    std::uintmax_t bytes = 0;
    for (const dataset::CaseData& c : data.cases)
      bytes += static_cast<std::uintmax_t>(c.size()) * (c.name.size() + kNumbers * kLongestNumber + kLongestFlag + 9);
    require_free_space(options.out.parent_path().empty() ? std::filesystem::path(".") : options.out.parent_path(), bytes,
                       fmt::format("compensated samples {}", options.out.string()));
  }

  fmt::print(out, "compensate {} with {}: {} {}{}\n", data_label, options.model.string(), dataset::to_string(model.sensor),
             model.name.empty() ? "" : "'" + model.name + "'", model.output_unit.empty() ? "" : " (" + model.output_unit + ")");
  if (!model.t_ref && inverse.known_inputs().test(static_cast<std::size_t>(Variable::T)))
    fmt::print(out, "note: the model states no t_ref; T = temp - {} (the record's)\n", data.t_ref);
  if (!inverse.has_covariance())
    fmt::print(out, "note: the model has no [covariance]: u_coefficients uses each coefficient's sd alone, without correlations\n");
  if (!model.output_sd && model.white_sd)
    fmt::print(out, "note: the model states no output_sd: u_noise takes its white_sd, the innovation's, which leaves out the noise's colour\n");
  if (!model.output_sd && !model.white_sd) fmt::print(out, "note: the model states no output_sd or white_sd: u_noise is 0\n");
  if (model.range.empty()) fmt::print(out, "note: the model has no [range]: no sample is checked against the characterized range\n");
  if (options.other_axes_zero)
    fmt::print(out, "{} and {} are 0; the other inputs come from the record's references\n", ident::variable_name(other_axes[0]),
               ident::variable_name(other_axes[1]));
  fmt::print(out, "errors of the known inputs and of the estimates fed back through lagged terms are not in u\n");

  fmt::print(out, "per case: rms error against the record's reference along the sensed axis; beside it the raw output over the "
                  "settled sensitivity ({}), {}\n",
             has_scale ? fmt::format("d y / d {} = {:.6g}", sensed_name, sensitivity) : std::string("none in the model"),
             inverse.first_row() > 0 ? fmt::format("from each case's sample {} (the model's lags)", inverse.first_row())
                                     : std::string("every sample"));
  // Written in ~1 MB pieces: the compensated record never sits in memory whole.
  constexpr std::size_t kWriteChunk = std::size_t{1} << 20;
  AtomicFileWriter csv_file(options.out);
  std::string csv = fmt::format("case,t,y,{0},u,u_coefficients,u_noise,flag,{0}_reference\n", sensed_name);
  csv.reserve(kWriteChunk + 1024);
  auto it = std::back_inserter(csv);
  fmt::print(out, "  {:<20} {:>9} {:>14} {:>14} {:>9} {:>9} {:>9} {:>11} {:>13}\n", "case", "samples",
             fmt::format("rms err {}", sensed == Variable::Ai ? "m/s2" : "rad/s"), "raw y/scale err", "ratio", "median u",
             "outside", "no root", "Newton steps");
  compensate::CompensationOptions compensation;
  compensation.range_margin = options.range_margin;
  Eigen::Index flagged = 0, failed = 0, total = 0;
  std::vector<std::string> from_model, nominal;
  for (const dataset::CaseData& c : data.cases) {
    const CompensationRecord record =
        compensation_record(model, inverse, data, static_cast<std::size_t>(&c - data.cases.data()), options.case_frames_from_model,
                            options.other_axes_zero);
    const ident::SignalSet& signals = record.signals;
    (record.characterized_frame ? from_model : nominal).push_back(c.name);
    const compensate::CompensatedSignal r = inverse.compensate(signals, c.sample_period_s, compensation);
    const Eigen::Index rows = r.value.size();
    const bool has_reference = signals.has(sensed);
    Eigen::VectorXd reference = has_reference ? Eigen::VectorXd(signals.get(sensed).tail(rows))
                                              : Eigen::VectorXd::Constant(rows, std::numeric_limits<double>::quiet_NaN());
    const Eigen::VectorXd y = signals.get(Variable::Y).tail(rows);
    for (Eigen::Index k = 0; k < rows; ++k) {
      const double u = std::hypot(r.u_coefficients(k), r.u_noise(k));
      fmt::format_to(it, "{},{},{},{},{},{},{},{},{}\n", c.name, c.t(r.first_row + k), y(k), r.value(k), u, r.u_coefficients(k),
                     r.u_noise(k), compensate::to_string(r.flag[static_cast<std::size_t>(k)]), reference(k));
      if (csv.size() >= kWriteChunk) {
        csv_file.append(csv);
        csv.clear();
      }
    }
    Eigen::VectorXd u(rows);
    for (Eigen::Index k = 0; k < rows; ++k) u(k) = std::hypot(r.u_coefficients(k), r.u_noise(k));
    std::vector<double> finite;
    for (Eigen::Index k = 0; k < rows; ++k) {
      if (std::isfinite(u(k))) finite.push_back(u(k));
    }
    std::nth_element(finite.begin(), finite.begin() + static_cast<std::ptrdiff_t>(finite.size() / 2), finite.end());
    const double median_u = finite.empty() ? std::nan("") : finite[finite.size() / 2];
    const double error = has_reference ? rms(r.value - reference) : std::nan("");
    const double raw = has_reference && has_scale ? rms(y / sensitivity - reference) : std::nan("");
    fmt::print(out, "  {:<20} {:>9} {:>14.4g} {:>14.4g} {:>9.1f} {:>9.3g} {:>9} {:>11} {:>13}\n", c.name, rows, error, raw,
               raw / error, median_u, r.outside_range, r.not_converged, r.most_iterations);
    flagged += r.outside_range;
    failed += r.not_converged;
    total += rows;
  }
  if (!from_model.empty())
    fmt::print(out, "M_E^S as characterized (the model's [[case_frame]]): {}\n", fmt::join(from_model, ", "));
  if (!nominal.empty()) fmt::print(out, "M_E^S = M_C^S M_E^C with the record's nominal M_E^C: {}\n", fmt::join(nominal, ", "));
  fmt::print(out, "{} samples: {} outside the characterized range (flagged, still compensated), {} without a root (NaN)\n",
             total, flagged, failed);
  csv_file.append(csv);
  csv_file.commit();
  fmt::print(out, "wrote {}\n", options.out.string());
  return kExitOk;
}

}  // namespace inertia::commands
