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
#include "analyzer/unit/unit_files.hpp"
#include "analyzer/unit/unit_inverse.hpp"
#include "analyzer/unit/unit_model.hpp"
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

std::vector<dataset::Dataset> unit_records(const unit::UnitModel& unit, const std::filesystem::path& dataset_dir,
                                           const std::filesystem::path& event_log) {
  const bool from_log = !event_log.empty();
  std::vector<dataset::Dataset> data;
  for (const model::ModelFile& m : unit.members) {
    if (from_log) {
      data.push_back(fusion::log_dataset(event_log, m.name, std::cerr));
    } else {
      const std::filesystem::path dir = dataset_dir / m.name;
      if (!std::filesystem::is_directory(dir))
        throw InputError(fmt::format("{} has no dataset of unit {}'s member '{}' (expected the folder {})", dataset_dir.string(),
                                     unit.unit, m.name, dir.string()));
      data.push_back(dataset::read_dataset(dir));
    }
    check_record(m, data.back(), (unit.file.parent_path() / unit::member_file_name(m.name)).string(),
                 from_log ? event_log.string() : data.back().dir.string());
  }
  const std::string data_label = (from_log ? event_log : dataset_dir).string();
  for (const dataset::Dataset& d : data) {
    bool same = d.cases.size() == data.front().cases.size();
    for (std::size_t c = 0; same && c < d.cases.size(); ++c) same = d.cases[c].name == data.front().cases[c].name;
    if (!same)
      throw InputError(fmt::format("the members' records in {} hold different cases ('{}' and '{}'): a unit is compensated on "
                                   "one record of all its outputs",
                                   data_label, data.front().sensor_name, d.sensor_name));
  }
  return data;
}

namespace {

/// Each compensated CSV row at its longest: each number at 24 characters (the longest a double's
/// shortest round trip takes), the flag at 16, and the separators.
std::uintmax_t csv_bytes(const std::vector<const dataset::Dataset*>& records, std::uintmax_t numbers) {
  constexpr std::uintmax_t kLongestNumber = 24, kLongestFlag = 16;
  std::uintmax_t bytes = 0;
  for (const dataset::CaseData& c : records.front()->cases)
    bytes += static_cast<std::uintmax_t>(c.size()) * (c.name.size() + numbers * (kLongestNumber + 1) + kLongestFlag + 2);
  return bytes;
}

void require_room_for(const CompensateOptions& options, std::uintmax_t bytes) {
  require_free_space(options.out.parent_path().empty() ? std::filesystem::path(".") : options.out.parent_path(), bytes,
                     fmt::format("compensated samples {}", options.out.string()));
}

/// The median of the finite values (NaN when none).
double finite_median(std::vector<double> values) {
  values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return !std::isfinite(v); }), values.end());
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

/// A unit's outputs compensated together (unit/unit_inverse.hpp), from one record per member: the
/// members' dataset folders under --dataset (one per member, by its name, as simulate writes them),
/// or the members' sensors in --log.
int run_unit_compensate(const CompensateOptions& options, std::ostream& out) {
  if (options.other_axes_zero)
    throw InputError("compensate: --other-axes zero compensates one output; a unit solves all its axes together");
  const unit::UnitModel unit = unit::read_unit_model(options.model);
  const unit::UnitInverse inverse(unit);
  const bool from_log = !options.event_log.empty();
  if (!options.sensor.empty()) throw InputError("compensate: --sensor picks one output; a unit model names its members");
  std::vector<dataset::Dataset> data = unit_records(unit, options.dataset, options.event_log);
  const std::string data_label = (from_log ? options.event_log : options.dataset).string();
  const std::vector<ident::Variable>& unknowns = inverse.unknowns();
  const auto count = static_cast<Eigen::Index>(unknowns.size());
  {
    std::vector<const dataset::Dataset*> records;
    for (const dataset::Dataset& d : data) records.push_back(&d);
    require_room_for(options, csv_bytes(records, 1 + unit.members.size() + 3 * unknowns.size()));
  }
  // The raw reading a user without the model would take: each output over its sensitivity along
  // its own axis (K R's diagonal), bias and cross-axis left in.
  Eigen::VectorXd raw_scale(count);
  const unit::Triads triads = unit::triads_of(unit.members);
  for (const auto& triad : {triads.accelerometer, triads.gyroscope}) {
    if (!triad) continue;
    const Eigen::Index first = triad->kind == dataset::SensorKind::Gyroscope && triads.accelerometer ? 3 : 0;
    for (int j = 0; j < 3; ++j) raw_scale(first + j) = triad->sensitivity(j, j);
  }
  // The member along each unknown's axis, for the raw reading.
  std::vector<std::size_t> member_of(static_cast<std::size_t>(count));
  for (std::size_t m = 0; m < unit.members.size(); ++m) {
    const bool gyro = unit.members[m].sensor == dataset::SensorKind::Gyroscope;
    member_of[static_cast<std::size_t>((gyro && unit.has(dataset::SensorKind::Accelerometer) ? 3 : 0) + unit.members[m].unit_axis)] = m;
  }

  fmt::print(out, "compensate {} with {}: unit {}{}, {} outputs solved together for {}\n", data_label, options.model.string(), unit.unit,
             unit.serial.empty() ? "" : " (serial " + unit.serial + ")", unit.members.size(),
             unit.members.size() == 6 ? "the specific force (m/s^2) and the angular rate (rad/s) in the unit's frame"
                                      : (unit.has(dataset::SensorKind::Accelerometer) ? "the specific force (m/s^2) in the unit's frame"
                                                                                      : "the angular rate (rad/s) in the unit's frame"));
  if (unit.members.size() == 3)
    fmt::print(out, "{} and temperature come from the record's references\n",
               unit.has(dataset::SensorKind::Accelerometer) ? "the angular rate" : "the specific force");
  for (std::size_t m = 0; m < unit.members.size(); ++m) {
    const model::ModelFile& file = unit.members[m];
    if (!inverse.members()[m].has_covariance())
      fmt::print(out, "note: {}'s model has no [covariance]: its coefficients' sd alone, without correlations\n", file.name);
    if (!file.output_sd && !file.white_sd) fmt::print(out, "note: {}'s model states no output_sd or white_sd: its noise adds 0 to u\n", file.name);
  }
  fmt::print(out, "errors of the known inputs and of the estimates fed back through lagged terms are not in u\n");
  fmt::print(out, "per case: rms of the error vector against the record's reference in the unit frame (the plan's nominal housing "
                  "frame); beside it each raw output over its own axis's sensitivity (K R's diagonal){}\n",
             inverse.joint().first_row() > 0 ? fmt::format(", from each case's sample {} (the models' lags)", inverse.joint().first_row())
                                             : std::string());

  constexpr std::size_t kWriteChunk = std::size_t{1} << 20;
  AtomicFileWriter csv_file(options.out);
  std::string csv = "case,t";
  for (const model::ModelFile& m : unit.members) csv += ",y_" + m.name;
  for (const ident::Variable v : unknowns) csv += fmt::format(",{}", ident::variable_name(v));
  for (const ident::Variable v : unknowns) csv += fmt::format(",u_{}", ident::variable_name(v));
  csv += ",flag";
  for (const ident::Variable v : unknowns) csv += fmt::format(",{}_reference", ident::variable_name(v));
  csv += "\n";
  csv.reserve(kWriteChunk + 4096);
  auto it = std::back_inserter(csv);
  const bool both = count == 6;
  fmt::print(out, "  {:<20} {:>9} {:>10} {:>14} {:>14} {:>7} {:>10} {:>9} {:>9} {:>8}\n", "case", "samples", "quantity", "rms err",
             "raw err", "ratio", "median u", "outside", "no root", "Newton");
  compensate::CompensationOptions compensation;
  compensation.range_margin = options.range_margin;
  Eigen::Index flagged = 0, failed = 0, total = 0;
  for (std::size_t c = 0; c < data.front().cases.size(); ++c) {
    std::vector<CompensationRecord> records;
    std::vector<const ident::SignalSet*> signals;
    records.reserve(unit.members.size());
    for (std::size_t m = 0; m < unit.members.size(); ++m)
      records.push_back(compensation_record(unit.members[m], inverse.members()[m], data[m], c, options.case_frames_from_model, false));
    for (const CompensationRecord& r : records) signals.push_back(&r.signals);
    const compensate::JointCompensation r = inverse.joint().compensate(signals, data.front().cases[c].sample_period_s, compensation);
    const dataset::CaseData& reference_case = data.front().cases[c];
    // The unit's frame as the plan states it: the first member's nominal case frame turned back.
    const frames::Dcm m_eu = config::unit_axis_frame(unit.members.front().unit_axis).transpose() * reference_case.m_ec;
    const ident::SignalSet in_unit = ident::signals_from_case(reference_case, m_eu, data.front().t_ref, data_label);
    const Eigen::Index rows = r.value.rows();
    Eigen::MatrixXd reference = Eigen::MatrixXd::Constant(rows, count, std::numeric_limits<double>::quiet_NaN());
    for (Eigen::Index j = 0; j < count; ++j) {
      // The unit frame's x, y, z read as a sensor frame's i, p, o.
      const bool rate = unknowns[static_cast<std::size_t>(j)] >= ident::Variable::Wx;
      const ident::Variable along = static_cast<ident::Variable>(static_cast<int>(rate ? ident::Variable::Wi : ident::Variable::Ai) + j % 3);
      if (in_unit.has(along)) reference.col(j) = in_unit.get(along).tail(rows);
    }
    Eigen::MatrixXd raw(rows, count);
    for (Eigen::Index j = 0; j < count; ++j)
      raw.col(j) = signals[member_of[static_cast<std::size_t>(j)]]->get(ident::Variable::Y).tail(rows) / raw_scale(j);
    const Eigen::MatrixXd u = (r.u_coefficients.array().square() + r.u_noise.array().square()).sqrt().matrix();
    for (Eigen::Index k = 0; k < rows; ++k) {
      fmt::format_to(it, "{},{}", reference_case.name, reference_case.t(r.first_row + k));
      for (const ident::SignalSet* s : signals) fmt::format_to(it, ",{}", s->get(ident::Variable::Y)(r.first_row + k));
      for (Eigen::Index j = 0; j < count; ++j) fmt::format_to(it, ",{}", r.value(k, j));
      for (Eigen::Index j = 0; j < count; ++j) fmt::format_to(it, ",{}", u(k, j));
      fmt::format_to(it, ",{}", compensate::to_string(r.flag[static_cast<std::size_t>(k)]));
      for (Eigen::Index j = 0; j < count; ++j) fmt::format_to(it, ",{}", reference(k, j));
      csv += '\n';
      if (csv.size() >= kWriteChunk) {
        csv_file.append(csv);
        csv.clear();
      }
    }
    for (int q = 0; q < (both ? 2 : 1); ++q) {
      const Eigen::Index first = 3 * q;
      const auto vector_rms = [&](const Eigen::MatrixXd& v) {
        double sum = 0.0;
        Eigen::Index n = 0;
        for (Eigen::Index k = 0; k < rows; ++k) {
          const double e = (v.row(k).segment<3>(first) - reference.row(k).segment<3>(first)).squaredNorm();
          if (std::isfinite(e)) sum += e, ++n;
        }
        return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
      };
      std::vector<double> u_norm(static_cast<std::size_t>(rows));
      for (Eigen::Index k = 0; k < rows; ++k) u_norm[static_cast<std::size_t>(k)] = u.row(k).segment<3>(first).norm();
      const double error = vector_rms(r.value), raw_error = vector_rms(raw);
      const bool rate = unknowns[static_cast<std::size_t>(first)] >= ident::Variable::Wx;
      fmt::print(out, "  {:<20} {:>9} {:>10} {:>14.4g} {:>14.4g} {:>7.1f} {:>10.3g} {:>9} {:>9} {:>8}\n", q == 0 ? reference_case.name : "",
                 q == 0 ? fmt::format("{}", rows) : "", rate ? "rad/s" : "m/s2", error, raw_error, raw_error / error,
                 finite_median(u_norm), q == 0 ? fmt::format("{}", r.outside_range) : "", q == 0 ? fmt::format("{}", r.not_converged) : "",
                 q == 0 ? fmt::format("{}", r.most_iterations) : "");
    }
    flagged += r.outside_range;
    failed += r.not_converged;
    total += rows;
  }
  fmt::print(out, "{} samples: {} outside the characterized range (flagged, still compensated), {} without a root (NaN)\n", total,
             flagged, failed);
  csv_file.append(csv);
  csv_file.commit();
  fmt::print(out, "wrote {}\n", options.out.string());
  return kExitOk;
}

}  // namespace

int run_compensate(const CompensateOptions& options, std::ostream& out) {
  if (options.dataset.empty() == options.event_log.empty())
    throw InputError("compensate: give exactly one of --dataset DIR and --log FILE");
  if (!(options.range_margin >= 0.0)) throw InputError("--range-margin must be >= 0");
  if (unit::is_unit_model(options.model)) return run_unit_compensate(options, out);
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
  // longest (the case, then t, y, the input, u, its two parts and the reference).
  require_room_for(options, csv_bytes({&data}, 7));

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
