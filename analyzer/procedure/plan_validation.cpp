#include "analyzer/procedure/plan_validation.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

std::vector<ident::Term> parse_fixed(const std::vector<std::string>& texts, const char* what) {
  if (texts.empty()) throw InputError(std::string("a fixed ") + what + " model needs at least one term");
  return ident::parse_terms(texts);
}

/// The span of the fixture temperature over the dataset (degC; NaN when a case has none).
double temperature_span(const dataset::Dataset& data) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const dataset::CaseData& c : data.cases) {
    if (!c.temp || c.temp->size() == 0) return std::nan("");
    lo = std::min(lo, c.temp->minCoeff());
    hi = std::max(hi, c.temp->maxCoeff());
  }
  return hi - lo;
}

ident::CandidateOptions with_measured_temperature(ident::CandidateOptions candidates, const dataset::Dataset& data,
                                                 const PipelineOptions& options) {
  if (options.temperature_when_measured && temperature_span(data) >= kMinTemperatureSpanC) candidates.include_temperature = true;
  return candidates;
}

/// A plan that cannot determine the scale factor determines nothing the model stands on: the
/// sensitive input (specific force, or rate for a gyroscope, along the nominal IRA) must vary on
/// its own across the cases (not only be a constant, which is the bias). Bad input, with advice.
void check_scale_excitation(const dataset::Dataset& data, std::string_view label) {
  const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;
  double sum = 0.0, sum_squares = 0.0, count = 0.0;
  std::vector<std::string> described;
  for (const dataset::CaseData& c : data.cases) {
    const auto& x = gyro ? *c.w_e : c.a_e;
    const Eigen::VectorXd along = x * c.m_ec.row(0).transpose();   // the input along the nominal IRA
    sum += along.sum();
    sum_squares += along.squaredNorm();
    count += static_cast<double>(along.size());
    described.push_back(fmt::format("'{}' ({}: {} along IRA {:+.4g} to {:+.4g})", c.name, dataset::to_string(c.kind),
                                    gyro ? "rate" : "specific force", along.minCoeff(), along.maxCoeff()));
  }
  const double varying = sum_squares - sum * sum / std::max(count, 1.0);
  if (count > 0.0 && varying >= kMinExcitationShare * sum_squares && sum_squares > 0.0) return;
  throw InputError(fmt::format(
      "dataset {}: this plan determines nothing: the {} along the sensor's input axis does not vary in any case, so the "
      "scale factor cannot be told from the bias. Cases: {}. {}",
      label, gyro ? "rate" : "specific force", fmt::join(described, "; "),
      gyro ? "A gyroscope needs rates about its input axis: a rate-table case with the table axis along IRA, both signs."
           : "An accelerometer needs at least two poses with different gravity along IRA (a six-position tumble, a "
             "multipoint rotation-table test) or vibration along IRA."));
}

bool is_rate(ident::Variable v) {
  using ident::Variable;
  return v == Variable::Wi || v == Variable::Wp || v == Variable::Wo || v == Variable::Wx || v == Variable::Wy || v == Variable::Wz;
}
bool is_inertial(ident::Variable v) { return v != ident::Variable::T && v != ident::Variable::Y && v != ident::Variable::E; }

/// What a variable's excitation is called, for the user.
std::string excitation_of(ident::Variable v) {
  using ident::Variable;
  switch (v) {
    case Variable::Ai: case Variable::Ax: return "specific force along i";
    case Variable::Ap: case Variable::Ay: return "specific force along p";
    case Variable::Ao: case Variable::Az: return "specific force along o";
    case Variable::Wi: case Variable::Wx: return "rate about i";
    case Variable::Wp: case Variable::Wy: return "rate about p";
    case Variable::Wo: case Variable::Wz: return "rate about o";
    case Variable::T: return "a temperature change";
    default: return std::string("variation of ") + ident::variable_name(v);
  }
}

/// Why column `j` of a stacked problem is not in the ranking: a zero column needs excitation of
/// its variables; otherwise it is (nearly) a combination of ranked columns, named by their shares.
std::string why_not_determined(const StackedRegression& s, Eigen::Index j, const std::vector<Eigen::Index>& ranking) {
  const Eigen::VectorXd column = s.phi.col(j);
  const double energy = column.squaredNorm();
  const ident::Term term = ident::parse_term(s.labels[static_cast<std::size_t>(j)]);
  if (!(energy > 0.0) || ranking.empty()) {
    std::vector<std::string> needs;
    for (ident::Variable v : {ident::Variable::Ai, ident::Variable::Ap, ident::Variable::Ao, ident::Variable::Wi,
                              ident::Variable::Wp, ident::Variable::Wo, ident::Variable::T}) {
      if (term.uses(v)) needs.push_back(excitation_of(v));
    }
    return fmt::format("not determined by this plan: its input is zero in every case (needs {})",
                       needs.empty() ? std::string("an input") : fmt::format("{}", fmt::join(needs, " and ")));
  }
  Eigen::MatrixXd x(s.phi.rows(), static_cast<Eigen::Index>(ranking.size()));
  for (std::size_t k = 0; k < ranking.size(); ++k) x.col(Eigen::Index(k)) = s.phi.col(ranking[k]);
  const Eigen::VectorXd b = x.colPivHouseholderQr().solve(column);
  std::vector<std::pair<double, std::string>> shares;
  for (std::size_t k = 0; k < ranking.size(); ++k) {
    shares.emplace_back(std::abs(b(Eigen::Index(k))) * x.col(Eigen::Index(k)).norm(), s.labels[static_cast<std::size_t>(ranking[k])]);
  }
  std::sort(shares.rbegin(), shares.rend());
  std::vector<std::string> names;
  for (std::size_t k = 0; k < shares.size() && k < 3 && shares[k].first > 1e-3 * std::sqrt(energy); ++k) names.push_back(shares[k].second);
  return fmt::format("not determined by this plan: its column is a combination of {} here (a plan that moves its "
                     "inputs independently separates them)",
                     fmt::join(names, ", "));
}

}  // namespace

void check_plan(const dataset::Dataset& data, const PipelineOptions& options, std::string_view dataset_label) {
  if (data.cases.empty()) throw InputError("the dataset has no cases");
  check_case_weights(data, options);
  if (data.sensor == dataset::SensorKind::Gyroscope) {
    std::vector<std::string> without;
    for (const dataset::CaseData& c : data.cases)
      if (!c.w_e) without.push_back("'" + c.name + "'");
    if (!without.empty()) {
      throw InputError(fmt::format("gyroscope dataset {}: case(s) {} have no rate columns (w_x, w_y, w_z); a gyroscope's "
                                   "scale factor and misalignment are read from the rates (a rate-table case), and a case "
                                   "without rotation needs its rates as zero columns",
                                   dataset_label, fmt::join(without, ", ")));
    }
  }
  check_scale_excitation(data, dataset_label);
}

// A weight for a case the dataset does not have would be silently ignored: a typo in a case name
// must not pass for a weighted fit.
void check_case_weights(const dataset::Dataset& data, const PipelineOptions& options) {
  std::vector<std::string> names;
  for (const dataset::CaseData& c : data.cases)
    if (std::find(names.begin(), names.end(), c.plan_case()) == names.end()) names.push_back(c.plan_case());
  for (const auto& [key, weight] : options.case_weights) {
    if (std::find(names.begin(), names.end(), key) == names.end())
      throw InputError(fmt::format("--weight {}={}: the dataset has no case '{}' (its cases: {})", key, weight, key,
                                   fmt::join(names, ", ")));
  }
}

std::vector<ident::Term> offered_terms(const ModelChoice& choice, ident::ModelFrame frame, const dataset::Dataset& data,
                                       const PipelineOptions& options, const char* what) {
  if (!choice.select) return parse_fixed(choice.fixed_terms, what);
  return ident::candidate_terms(data.sensor, frame, with_measured_temperature(choice.candidates, data, options));
}

std::optional<std::string> temperature_note(const dataset::Dataset& data, const PipelineOptions& options) {
  if (!options.temperature_when_measured) return std::nullopt;
  const double span = temperature_span(data);
  if (!std::isfinite(span) || span >= kMinTemperatureSpanC) return std::nullopt;
  return fmt::format("temperature terms not determined by this plan: the fixture temperature spans {:.3f} degC (at least "
                     "{:.0f} degC needed; a thermal_step phase gives it)",
                     span, kMinTemperatureSpanC);
}

bool judged_by_excitation(const ident::Term& term) {
  int inertial_degree = 0;
  for (const ident::Factor& f : term.factors()) {
    if (f.variable == ident::Variable::Y || f.variable == ident::Variable::E) return false;
    inertial_degree += is_inertial(f.variable) ? f.power : 0;
  }
  return inertial_degree >= 2;
}

void add_excitation(std::span<const ident::Term> terms, const dataset::CaseData& c, const Eigen::Matrix3d& m_nominal, double t_ref,
                    Eigen::Index first_row, std::span<TermExcitation> tallies, const ident::CaseReading& reading) {
  using ident::Variable;
  // The case's signals once for every term the rule judges and the case can evaluate.
  std::vector<std::size_t> judged;
  ident::VariableSet wanted;
  for (std::size_t i = 0; i < terms.size(); ++i) {
    const ident::Term& term = terms[i];
    const std::vector<Variable> variables = term.variables();
    const std::array<ident::Term, 1> one{term};
    if (!judged_by_excitation(term) || c.size() <= std::max(first_row, ident::first_usable_row(one)) ||
        (term.uses(Variable::T) && !c.temp) || (!c.w_e && std::any_of(variables.begin(), variables.end(), is_rate)))
      continue;
    judged.push_back(i);
    for (Variable v : variables) wanted.set(static_cast<std::size_t>(v));
  }
  if (judged.empty()) return;
  const ident::SignalSet nominal = ident::signals_from_case(c, m_nominal, t_ref, {}, wanted, reading);
  // The same signals with every inertial variable at its input vector's magnitude.
  ident::SignalSet full = nominal;
  const Eigen::VectorXd a_magnitude = c.a_e.rowwise().norm();
  const Eigen::VectorXd w_magnitude = c.w_e ? Eigen::VectorXd(c.w_e->rowwise().norm()) : Eigen::VectorXd();
  for (std::size_t v = 0; v < static_cast<std::size_t>(ident::kVariableCount); ++v) {
    const auto variable = static_cast<Variable>(v);
    if (wanted.test(v) && is_inertial(variable)) full.set(variable, is_rate(variable) ? w_magnitude : a_magnitude);
  }
  Eigen::MatrixXd column;
  for (const std::size_t i : judged) {
    const std::array<ident::Term, 1> one{terms[i]};
    const Eigen::Index first = std::max(first_row, ident::first_usable_row(one));
    column.resize(c.size() - first, 1);
    ident::fill_regressors(one, nominal, first, column);
    tallies[i].nominal += column.squaredNorm();
    ident::fill_regressors(one, full, first, column);
    tallies[i].full += column.squaredNorm();
  }
}

std::string unexcited_reason(const ident::Term& term, const TermExcitation& tally) {
  std::vector<std::string> needs;
  for (ident::Variable v : term.variables()) {
    if (is_inertial(v)) needs.push_back(excitation_of(v));
  }
  return fmt::format("not determined by this plan: the plan's own inputs move it to {:.1e} of the energy its inputs "
                     "allow (at least {:.0e} needed); what moves it beyond that is the sensor's misalignment and the poses' "
                     "scatter, and a fit on it would be extrapolated over the characterized range (needs {} at once)",
                     tally.full > 0.0 ? tally.nominal / tally.full : 0.0, kMinExcitationShare, fmt::join(needs, " and "));
}

std::vector<UndeterminedTerm> remove_unexcited_terms(std::vector<ident::Term>& candidates, std::span<const dataset::CaseData> cases,
                                                     double t_ref) {
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < cases.size(); ++i) inputs.push_back({i, &cases[i], cases[i].m_ec, 1.0, {}});
  return remove_unexcited_terms(candidates, inputs, t_ref);
}

std::vector<UndeterminedTerm> remove_unexcited_terms(std::vector<ident::Term>& candidates, std::span<const StackInput> inputs,
                                                     double t_ref) {
  std::vector<UndeterminedTerm> out;
  std::vector<ident::Term> kept;
  std::vector<TermExcitation> tallies(candidates.size());
  for (const StackInput& in : inputs) add_excitation(candidates, *in.data, in.m_es, t_ref, 0, tallies, in.reading);
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (tallies[i].excited()) {
      kept.push_back(candidates[i]);
    } else {
      out.push_back({candidates[i].to_string(), unexcited_reason(candidates[i], tallies[i])});
    }
  }
  candidates = std::move(kept);
  return out;
}

std::vector<UndeterminedTerm> undetermined_columns(const StackedRegression& s, const std::vector<Eigen::Index>& ranking) {
  std::vector<UndeterminedTerm> out;
  for (Eigen::Index j = 0; j < s.phi.cols(); ++j) {
    if (std::find(ranking.begin(), ranking.end(), j) == ranking.end())
      out.push_back({s.labels[static_cast<std::size_t>(j)], why_not_determined(s, j, ranking)});
  }
  return out;
}

}  // namespace inertia::procedure
