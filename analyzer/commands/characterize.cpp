#include "analyzer/commands/characterize.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <fmt/chrono.h>

#include <chrono>
#include <ctime>

#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <ostream>

#include "analyzer/commands/noise.hpp"
#include "analyzer/commands/record.hpp"
#include "analyzer/commands/sheet.hpp"
#include "analyzer/commands/truth_file.hpp"
#include "analyzer/fusion/log_dataset.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/report/characterization_report.hpp"
#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"
#include "common/output_folder.hpp"
#include "common/units.hpp"
#include "inertia_version.hpp"

namespace inertia::commands {

procedure::PipelineOptions pipeline_options(const CharacterizeOptions& options) {
  if (options.order < 0 || options.misalignment_order < 0) throw InputError("--order must be >= 0");
  procedure::PipelineOptions p;
  p.misalignment.select = options.misalignment_model.empty();
  p.misalignment.fixed_terms = options.misalignment_model;
  p.misalignment.candidates.r = options.misalignment_order;
  p.misalignment.candidates.include_output_lags = options.misalignment_order > 0;
  if (options.fixed_model.empty()) {
    p.batch.select = true;
    p.batch.candidates.r = options.order;
  } else {
    p.batch.select = false;
    p.batch.fixed_terms = options.fixed_model;
  }
  p.batch.noise_lags = options.noise_lags < 0 ? options.order : options.noise_lags;
  p.case_weights = options.weights;
  if (!(options.mounting_tolerance_deg >= 0.0 && options.mounting_tolerance_deg <= 30.0))
    throw InputError(fmt::format("--mounting-tolerance-deg {}: expected 0..30 degrees", options.mounting_tolerance_deg));
  p.mounting_tolerance_rad = deg_to_rad(options.mounting_tolerance_deg);
  p.selection.alpha = options.alpha;
  std::string why;
  if (!p.selection.is_valid(&why)) throw InputError("--alpha: " + why);
  return p;
}

namespace {
std::string angle_text(double angle_rad, double sd_rad) {
  if (sd_rad == 0.0) return fmt::format("{:+.5f} deg (held)", rad_to_deg(angle_rad));
  return fmt::format("{:+.5f} +- {:.5f} deg", rad_to_deg(angle_rad), rad_to_deg(sd_rad));
}
// The span of each input the model reads, over every case's samples in its own M_E^S: what
// compensation may invert without extrapolating.
std::map<ident::Variable, model::ModelFile::Span> characterized_range(const dataset::Dataset& data,
                                                                     const procedure::PipelineResult& result,
                                                                     const std::vector<model::ModelTerm>& terms) {
  std::vector<ident::Term> list;
  for (const model::ModelTerm& t : terms) list.push_back(t.term);
  ident::VariableSet inputs = ident::variables_of(list);
  inputs.reset(static_cast<std::size_t>(ident::Variable::Y));
  inputs.reset(static_cast<std::size_t>(ident::Variable::E));
  std::map<ident::Variable, model::ModelFile::Span> range;
  for (std::size_t c = 0; c < data.cases.size(); ++c) {
    const ident::SignalSet signals = ident::signals_from_case(data.cases[c], result.cases[c].m_es, data.t_ref, "", inputs);
    for (int v = 0; v < ident::kVariableCount; ++v) {
      const auto variable = static_cast<ident::Variable>(v);
      if (!inputs.test(static_cast<std::size_t>(v)) || !signals.has(variable) || signals.size() == 0) continue;
      const Eigen::VectorXd& x = signals.get(variable);
      const auto [it, fresh] = range.try_emplace(variable, model::ModelFile::Span{x.minCoeff(), x.maxCoeff()});
      if (!fresh) {
        it->second.lowest = std::min(it->second.lowest, x.minCoeff());
        it->second.highest = std::max(it->second.highest, x.maxCoeff());
      }
    }
  }
  return range;
}

// The sample period the lags count in, when every case has the same one.
std::optional<double> common_sample_period(const dataset::Dataset& data) {
  if (data.cases.empty()) return std::nullopt;
  const double period = data.cases.front().sample_period_s;
  for (const dataset::CaseData& c : data.cases) {
    if (!(std::abs(c.sample_period_s - period) <= dataset::kTimeJitterTolerance * period)) return std::nullopt;
  }
  return period > 0.0 ? std::optional<double>(period) : std::nullopt;
}
}  // namespace

model::ModelFile characterized_model(const procedure::PipelineResult& result, const dataset::Dataset& data,
                                     const procedure::BatchVerification& verification,
                                     std::optional<noise::NoiseAnalysis>& noise_analysis, std::string& why_no_noise,
                                     const std::string& source) {
  // Process terms (noise terms describe the residual colour; kept, marked by e).
  model::ModelFile model;
  model.sensor = data.sensor;
  model.m_cs = result.m_cs;
  for (Eigen::Index j = 0; j < result.fit.theta.size(); ++j) {
    model.terms.push_back({ident::parse_term(result.fit.labels[static_cast<std::size_t>(j)]), result.fit.theta(j),
                           result.fit.std_dev(j)});
  }
  model.name = data.sensor_name;
  model.serial = data.serial;
  model.part = data.part;
  model.unit = data.unit;
  model.unit_axis = data.unit_axis;
  model.output_unit = data.output_unit;
  model.t_ref = data.t_ref;
  model.sample_period_s = common_sample_period(data);
  model.covariance = result.fit.covariance;
  model.range = characterized_range(data, result, model.terms);
  for (std::size_t c = 0; c < data.cases.size(); ++c) model.case_frames.push_back({data.cases[c].name, result.cases[c].m_es});
  if (!result.mountings.empty() && result.mountings.front().aligned) {
    const procedure::MountingResult& m = result.mountings.front();
    model.misalignment = model::ModelFile::Misalignment{m.angles(1), m.angles(2), m.angles_sd(1), m.angles_sd(2), m.angles_dof};
  }
  for (const procedure::UndeterminedTerm& u : result.undetermined) model.undetermined.emplace_back(u.term, u.reason);
  double duration = 0.0;
  for (const dataset::CaseData& c : data.cases) {
    duration += static_cast<double>(c.size()) * c.sample_period_s;
    model.conditions.cases.push_back(c.name);
  }
  model.conditions.duration_s = duration;
  model.conditions.source = source;
  model.conditions.software = INERTIA_VERSION_TEXT;
  model.conditions.date = fmt::format("{:%Y-%m-%dT%H:%M:%SZ}", fmt::gmtime(std::time(nullptr)));
  model.white_sd = std::sqrt(verification.innovation.variance);
  double squares = 0.0;
  Eigen::Index samples = 0;
  for (const Eigen::VectorXd& e : verification.free_run) {
    squares += e.squaredNorm();
    samples += e.size();
  }
  if (samples > 0) model.output_sd = std::sqrt(squares / static_cast<double>(samples));
  model.square_highpass_rad_s = result.square_corner_rad_s;
  // The sensor's noise terms from the plan's static stretches, as `inertia-analyze noise` reads
  // them: [noise] carries the determined ones (diagnose's band test expects them).
  noise_analysis.reset();
  why_no_noise.clear();
  try {
    noise_analysis = noise::analyse_noise(data);
    noise_terms_into(*noise_analysis, model);
  } catch (const InputError& e) {
    noise_analysis.reset();
    why_no_noise = e.what();
  }
  return model;
}

int run_characterize(const CharacterizeOptions& options, std::ostream& out) {
  if (options.dataset.empty() == options.event_log.empty())
    throw InputError("characterize: give exactly one of --dataset DIR and --log FILE");
  if (!options.dataset_out.empty() && options.event_log.empty())
    throw InputError("characterize: --dataset-out needs --log FILE (it writes the dataset converted from the log)");
  const bool from_log = !options.event_log.empty();
  // The record is opened, and the serial and part checked, before any work: a record refused
  // (damaged, newer schema, unreachable) or a serial that is not the bench's would otherwise be
  // found only after the whole characterization.
  std::optional<record::RecordStore> record;
  if (!options.record_db.empty()) record.emplace(options.record_db);
  // Everything goes to a staging folder that takes --out's place once whole (a stopped run
  // leaves --out as it was).
  OutputFolder folder(options.out, "characterize");
  dataset::Dataset data = from_log ? fusion::log_dataset(options.event_log, options.sensor, std::cerr)
                                   : dataset::read_dataset(options.dataset);
  const auto take_stated = [&](const char* what, const std::string& given, std::string& stated) {
    if (given.empty()) return;
    if (!stated.empty() && stated != given)
      throw InputError(fmt::format("characterize: --{} {} is not the bench's: {} names sensor '{}' {} {}; refused", what, given,
                                   from_log ? options.event_log.string() : options.dataset.string(), data.sensor_name, what,
                                   stated));
    stated = given;
  };
  take_stated("serial", options.serial, data.serial);
  take_stated("part", options.part, data.part);
  if (!options.dataset_out.empty()) {
    dataset::write_dataset(options.dataset_out, data);
    fmt::print(out, "wrote dataset {}\n", options.dataset_out.string());
  }
  const std::filesystem::path source = from_log ? options.event_log : options.dataset;
  const std::string label = from_log ? source.stem().string() : source.filename().string();
  const procedure::PipelineOptions p = pipeline_options(options);
  const procedure::PipelineResult result = procedure::run_pipeline(data, p, label);
  // A log has no truth.toml; a dataset folder converted from one has none either.
  const std::optional<Truth> truth = from_log ? std::nullopt : read_truth(options.dataset);

  fmt::print(out, "{} {}: {} {} case(s)\n", from_log ? "log" : "dataset", source.string(), data.cases.size(),
             dataset::to_string(data.sensor));
  for (const std::string& note : result.notes) fmt::print(out, "note: {}\n", note);
  for (const procedure::MountingResult& m : result.mountings) {
    if (m.aligned) {
      fmt::print(out, "mounting {}: algorithm 2 tried {} models, {} refinement(s); selected {}\n", m.mounting,
                 m.candidates_tried, m.refinements, fmt::join(m.s_terms, " "));
      fmt::print(out, "  angles of F_S from the nominal case frame: about p {}, about o {}\n",
                 angle_text(m.angles(1), m.angles_sd(1)), angle_text(m.angles(2), m.angles_sd(2)));
      if (!m.twist_reference.empty())
        fmt::print(out, "  about i against mounting {}: {}\n", m.twist_reference, angle_text(m.angles(0), m.angles_sd(0)));
    } else {
      fmt::print(out, "mounting {}: not aligned\n", m.mounting);
    }
    for (const std::string& h : m.held) fmt::print(out, "  {}\n", h);
    for (std::size_t index : m.cases) {
      const dataset::CaseData& c = data.cases[index];
      const frames::Dcm& m_es = result.cases[index].m_es;
      std::string score;
      if (truth && truth->m_es.count(c.name)) {
        score = fmt::format("; input axis error vs truth {:.5f} deg",
                            rad_to_deg(procedure::input_axis_error(truth->m_es.at(c.name), m_es)));
      }
      fmt::print(out, "  case {}: M_E^S input axis [{:+.6f} {:+.6f} {:+.6f}]{}\n", c.name, m_es(0, 0), m_es(0, 1),
                 m_es(0, 2), score);
    }
  }
  for (const procedure::UndeterminedTerm& u : result.undetermined) fmt::print(out, "{}: {}\n", u.term, u.reason);
  fmt::print(out, "batch model ({} rows, residual sd {:.4g} {}):\n", result.fit.residuals.size(),
             std::sqrt(procedure::batch_innovation(result).variance), data.output_unit);
  // The truth column of the summary's tables: empty without truth.toml, "-" for a term it lacks.
  const auto truth_text = [&](const std::string& term) -> std::string {
    if (!truth) return "";
    const auto it = truth->terms.find(term);
    return it == truth->terms.end() ? fmt::format(" {:>12}", "-") : fmt::format(" {:>12.5g}", it->second);
  };
  fmt::print(out, "  {:<16} {:>14} {:>12} {:>10}{}\n", "term", "coefficient", "std", "t", truth ? "      truth" : "");
  for (Eigen::Index j = 0; j < result.fit.theta.size(); ++j) {
    const std::string& name = result.fit.labels[static_cast<std::size_t>(j)];
    const double t = j < result.t_test.t.size() ? result.t_test.t(j) : result.fit.theta(j) / result.fit.std_dev(j);
    fmt::print(out, "  {:<16} {:>14.6g} {:>12.3g} {:>10.1f}{}\n", name, result.fit.theta(j), result.fit.std_dev(j), t,
               truth_text(name));
  }
  const std::vector<ident::StaticGain> gains = report::sensor_static_gains(result);
  if (!gains.empty()) {
    fmt::print(out, "static gains (a term with its lags, over 1 - sum of the y-lag coefficients):\n");
    fmt::print(out, "  {:<16} {:>14} {:>12}{}\n", "term", "gain", "std", truth ? "        truth" : "");
    for (const ident::StaticGain& g : gains) {
      fmt::print(out, "  {:<16} {:>14.6g} {:>12.3g}{}\n", g.term, g.gain, g.std_dev, truth_text(g.term));
    }
  }

  std::optional<noise::NoiseAnalysis> noise_analysis;
  std::string no_noise;
  const procedure::BatchVerification verification = procedure::batch_verification(data, result, label);
  const model::ModelFile model = characterized_model(result, data, verification, noise_analysis, no_noise, source.string());
  if (!no_noise.empty()) fmt::print(out, "noise terms not estimated: {}\n", no_noise);
  const std::filesystem::path model_file = folder.path() / "model.toml";
  report::ReportInputs in;
  in.data = &data;
  in.result = &result;
  in.verification = &verification;
  in.dataset_label = label;
  in.plots = options.plots;
  if (truth) in.truth = report::TruthForReport{truth->terms, truth->m_es};
  report::WrittenReport written = report::write_characterization_report(in, folder.path());
  const std::filesystem::path& report_file = written.file;
  if (noise_analysis) {
    std::ofstream md(report_file, std::ios::app);
    md << "\n## Noise of the static stretches\n\n";
    write_noise_section(md, out, *noise_analysis, data.output_unit, label,
                        options.plots ? folder.path() / "plots" : std::filesystem::path());
  }
  std::optional<report::ParameterSheet> sheet;
  try {
    sheet = write_sheet(model, folder.path());
  } catch (const InputError& e) {
    fmt::print(out, "no parameter sheet: {}\n", e.what());
  }
  report::finish_report_plots(written);
  model::write_model(model_file, model);
  folder.commit();
  fmt::print(out, "wrote {}: model.toml, {}{}{}\n", folder.target().string(), report_file.filename().string(),
             sheet ? ", sheet.md, sheet.html, sheet.json" : "", options.plots ? ", plots/" : "");
  if (record) {
    RecordRequest request;
    request.operator_name = options.operator_name;
    request.input = source;
    request.report_path = folder.final_path(report_file);
    request.sheet = sheet ? &*sheet : nullptr;
    const auto start = std::chrono::steady_clock::now();
    const long long id = record_characterization(*record, request, model);
    fmt::print(out, "recorded as characterization {} in {} ({:.0f} ms)\n", id, record->describe(),
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  return kExitOk;
}

}  // namespace inertia::commands
