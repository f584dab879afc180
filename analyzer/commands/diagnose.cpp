#include "analyzer/commands/diagnose.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>

#include "analyzer/diagnose/diagnose_report.hpp"
#include "analyzer/diagnose/discrepancy.hpp"
#include "analyzer/fusion/log_dataset.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"

namespace inertia::commands {
namespace {

// Per case and phase: the detail that sits beside the contract's residual_rms number
// (docs/design.md, "Command line": residual_rms is the overall RMS, never an object).
nlohmann::json rms_by_case_json(const diagnose::DiagnoseResult& r, const diagnose::ResidualSummary& s) {
  nlohmann::json cases = nlohmann::json::object();
  for (std::size_t c = 0; c < r.case_names.size(); ++c) {
    nlohmann::json phases = nlohmann::json::object();
    for (const diagnose::SegmentStats& seg : s.segments) {
      if (seg.case_index != c) continue;
      phases[seg.phase] = {{"rms", seg.rms}, {"samples", seg.samples}, {"ratio", seg.ratio},
                           {"p_value", seg.p_value}, {"excess", seg.excess}};
    }
    cases[r.case_names[c]] = {{"rms", s.per_case[c]}, {"phases", phases}};
  }
  return cases;
}

/// `residual_rms` (the free-run residual's overall RMS, output unit) and `residual_rms_by_case`
/// into `step`.
void put_rms(nlohmann::json& step, const diagnose::DiagnoseResult& r, const diagnose::ResidualSummary& s) {
  step["residual_rms"] = s.overall;
  step["residual_rms_by_case"] = rms_by_case_json(r, s);
}

/// location.bands / location.conditions: baseline and final side by side (same bands and bins).
nlohmann::json location_json(const diagnose::DiagnoseResult& r) {
  const diagnose::Location& b = r.location_before;
  const diagnose::Location& a = r.location_after;
  nlohmann::json bands = nlohmann::json::array();
  for (std::size_t c = 0; c < b.bands.size() && c < a.bands.size(); ++c) {
    nlohmann::json list = nlohmann::json::array();
    for (std::size_t k = 0; k < b.bands[c].bands.size() && k < a.bands[c].bands.size(); ++k) {
      auto one = [](const diagnose::BandTest& t) {
        return nlohmann::json{{"residual_psd", t.residual_psd}, {"model_psd", t.model_psd}, {"ratio", t.ratio},
                              {"dof", t.dof}, {"p_value", t.p_value}, {"excess", t.excess}};
      };
      const diagnose::BandTest& t = b.bands[c].bands[k];
      list.push_back({{"f_lo_hz", t.f_lo_hz}, {"f_hi_hz", t.f_hi_hz}, {"bins", t.bins},
                      {"baseline", one(t)}, {"final", one(a.bands[c].bands[k])}});
    }
    bands.push_back({{"case", r.case_names[b.bands[c].case_index]}, {"sample_rate_hz", b.bands[c].sample_rate_hz},
                     {"segment_length", b.bands[c].segment_length}, {"segments", b.bands[c].segments},
                     {"bands", list}});
  }
  nlohmann::json conditions = nlohmann::json::array();
  for (std::size_t k = 0; k < b.conditions.size() && k < a.conditions.size(); ++k) {
    auto one = [](const diagnose::ConditionBin& t) {
      return nlohmann::json{{"rms", t.rms}, {"expected_rms", t.expected_rms}, {"ratio", t.ratio}, {"dof", t.dof},
                            {"p_value", t.p_value}, {"excess", t.excess}};
    };
    const diagnose::ConditionBin& t = b.conditions[k];
    conditions.push_back({{"quantity", t.quantity}, {"unit", t.quantity == "T" ? "degC" : "g"}, {"lo", t.lo},
                          {"hi", t.hi > 1e299 ? nlohmann::json(nullptr) : nlohmann::json(t.hi)}, {"samples", t.samples},
                          {"baseline", one(t)}, {"final", one(a.conditions[k])}});
  }
  return {{"bands", bands}, {"conditions", conditions}, {"verdict", {{"baseline", b.verdict}, {"final", a.verdict}}}};
}

}  // namespace

int run_diagnose(const DiagnoseCommandOptions& options, std::ostream& out) {
  const auto start = std::chrono::steady_clock::now();
  const model::ModelFile model = model::read_model(options.model);
  std::ostringstream warnings;
  if (options.dataset.empty() == options.event_log.empty())
    throw InputError("diagnose: give exactly one of --dataset DIR and --log FILE");
  const dataset::Dataset data = options.event_log.empty()
                                    ? dataset::read_dataset(options.dataset, warnings)
                                    : fusion::log_dataset(options.event_log, options.sensor, warnings);
  const std::filesystem::path source = options.event_log.empty() ? options.dataset : options.event_log;
  const std::string label = source.filename().empty() ? source.parent_path().filename().string()
                                                      : source.stem().string();
  diagnose::DiagnoseOptions d;
  d.alpha = options.alpha;
  const diagnose::DiagnoseResult r = diagnose::diagnose(data, model, d, label);

  const std::filesystem::path model_dir =
      options.report.empty() ? options.json.parent_path() : options.report;
  if (!model_dir.empty()) std::filesystem::create_directories(model_dir);
  const std::filesystem::path model_out = model_dir / "model-augmented.toml";
  model::write_model(model_out, r.final_model);

  nlohmann::json j;
  j["model"] = options.model.string();
  j["dataset"] = source.string();
  j["output_unit"] = data.output_unit;
  j["noise_reference"] = r.noise_reference;
  j["location_test"] = r.location_test;
  j["alpha"] = options.alpha;
  j["library"] = r.library;
  j["held_fixed"] = r.held_fixed;
  put_rms(j["baseline"], r, r.steps.front());
  put_rms(j["final"], r, r.steps.back());
  if (r.refit_only) put_rms(j["refit_only"], r, *r.refit_only);
  j["final"]["model_file"] = model_out.string();
  j["location"] = location_json(r);
  j["findings"] = nlohmann::json::array();
  for (const diagnose::Finding& f : r.findings) {
    j["findings"].push_back({{"term", f.term}, {"effect", f.effect}, {"coefficient", f.coefficient}, {"std", f.std},
                             {"t", f.t}, {"final_coefficient", f.final_coefficient}, {"final_std", f.final_std}, {"p_value", f.p_value}, {"p_needed", f.threshold_p}, {"err", f.err},
                             {"delta_aic", f.delta_aic}, {"ar_order", f.ar_order},
                             {"where", {{"case", f.where_case}, {"phase", f.where_phase}, {"rms", f.where_rms}}}});
  }
  j["case_misalignments"] = nlohmann::json::array();
  for (const diagnose::Finding& f : r.case_misalignments) {
    j["case_misalignments"].push_back({{"mounting", f.mounting}, {"cases", f.mounting_cases},
                                       {"axis", std::string(1, "xyz"[f.axis])}, {"effect", f.effect},
                                       {"angle_deg", f.angle_deg}, {"angle_std_deg", f.angle_std_deg}, {"t", f.t},
                                       {"p_value", f.p_value}, {"p_needed", f.threshold_p}});
  }
  j["steps"] = nlohmann::json::array();
  for (const diagnose::ResidualSummary& s : r.steps) {
    nlohmann::json step = {{"label", s.label}};
    put_rms(step, r, s);
    j["steps"].push_back(step);
  }
  if (!options.json.parent_path().empty()) std::filesystem::create_directories(options.json.parent_path());
  {
    std::ofstream f(options.json);
    if (!f) throw std::runtime_error("cannot write " + options.json.string());
    f << j.dump(2) << '\n';
  }

  std::ostringstream log;
  log << warnings.str();
  fmt::print(log, "dataset {}: {} case(s), {} model terms, {} library candidates\n", source.string(),
             data.cases.size(), model.terms.size(), r.library.size());
  fmt::print(log, "residual RMS overall: baseline {:.5g} {}, final {:.5g} {} (noise reference {:.4g})\n",
             r.steps.front().overall, data.output_unit, r.steps.back().overall, data.output_unit, r.noise_reference);
  fmt::print(log, "location (baseline): {}\n", r.location_before.verdict);
  fmt::print(log, "location (final): {}\n", r.location_after.verdict);
  if (r.findings.empty()) fmt::print(log, "no significant missing effect\n");
  if (r.estimated_square_corner_rad_s) {
    fmt::print(log, "the squares act through eq. 12's high pass s/(s+b): b = {:.4g} rad/s estimated (the model had none)\n",
               *r.estimated_square_corner_rad_s);
  }
  for (const diagnose::Finding& f : r.findings) {
    fmt::print(log, "found {:<14} ({}): {:.6g} +- {:.3g}, t = {:.1f}, acts most in {}/{}; final model {:.6g} +- {:.3g}\n",
               f.term, f.effect, f.coefficient, f.std, f.t, f.where_case, f.where_phase, f.final_coefficient, f.final_std);
  }
  for (const diagnose::Finding& f : r.case_misalignments) {
    fmt::print(log, "found {} about case {}: {:.4f} +- {:.2g} deg, t = {:.1f}\n", f.effect, "xyz"[f.axis], f.angle_deg,
               f.angle_std_deg, f.t);
  }
  fmt::print(log, "wrote {}, {}\n", options.json.string(), model_out.string());
  if (!options.report.empty()) {
    fmt::print(log, "wrote {}\n",
               diagnose::write_diagnose_report(data, r, label, options.report, options.plots).string());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print(log, "diagnose took {:.2f} s\n", seconds);
  out << log.str();
  if (!options.log.empty()) std::ofstream(options.log) << log.str();
  return kExitOk;
}

}  // namespace inertia::commands
