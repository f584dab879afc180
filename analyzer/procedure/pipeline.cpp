#include "analyzer/procedure/pipeline.hpp"

#include <boost/math/distributions/chi_squared.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string_view>

#include "analyzer/noise/allan.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

/// The names of the external-frame sensitivity terms: a_x a_y a_z, or w_x w_y w_z for a gyroscope
/// (eq. 5: its misalignment is read from the rate sensitivities, paper section 2.2).
std::array<const char*, 3> sensitivity_names(dataset::SensorKind sensor) {
  if (sensor == dataset::SensorKind::Gyroscope) return {"w_x", "w_y", "w_z"};
  return {"a_x", "a_y", "a_z"};
}

/// The F_E-and-F_S sensitivities theta_x, theta_y, theta_z of a fit (zero where a term is absent),
/// and their covariance (zero rows and columns for absent terms).
std::optional<Eigen::Vector3d> external_sensitivities(const std::vector<std::string>& labels, const Eigen::VectorXd& theta,
                                                      dataset::SensorKind sensor,
                                                      const Eigen::MatrixXd* covariance = nullptr,
                                                      Eigen::Matrix3d* theta_covariance = nullptr) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  bool any = false;
  const std::array<const char*, 3> names = sensitivity_names(sensor);
  std::array<Eigen::Index, 3> at{-1, -1, -1};
  for (std::size_t j = 0; j < labels.size(); ++j) {
    for (int c = 0; c < 3; ++c) {
      if (labels[j] == names[static_cast<std::size_t>(c)]) {
        s(c) = theta(static_cast<Eigen::Index>(j));
        at[static_cast<std::size_t>(c)] = static_cast<Eigen::Index>(j);
        any = true;
      }
    }
  }
  if (!any || s.norm() == 0.0) return std::nullopt;
  if (covariance != nullptr && theta_covariance != nullptr) {
    theta_covariance->setZero();
    for (std::size_t a = 0; a < 3; ++a)
      for (std::size_t b = 0; b < 3; ++b)
        if (at[a] >= 0 && at[b] >= 0) (*theta_covariance)(Eigen::Index(a), Eigen::Index(b)) = (*covariance)(at[a], at[b]);
  }
  return s;
}

/// Gram matrix of [IRA XRA YRA 1] over a mounting's rows (specific force, or rate for a
/// gyroscope; a case without rates has none): what excitation.hpp judges.
Eigen::Matrix4d input_gram(const std::vector<dataset::CaseData>& cases, dataset::SensorKind sensor) {
  Eigen::Matrix4d g = Eigen::Matrix4d::Zero();
  for (const dataset::CaseData& c : cases) {
    const bool gyro = sensor == dataset::SensorKind::Gyroscope;
    if (gyro && !c.w_e) continue;
    const auto& x = gyro ? *c.w_e : c.a_e;
    Eigen::MatrixXd rows(x.rows(), 4);
    rows.leftCols(3) = x;
    rows.col(3).setOnes();
    g.noalias() += rows.transpose() * rows;
  }
  return g;
}

std::vector<Term> parse_fixed(const std::vector<std::string>& texts, const char* what) {
  if (texts.empty()) throw InputError(std::string("a fixed ") + what + " model needs at least one term");
  return ident::parse_terms(texts);
}

/// One mounting's cases with their references turned into the nominal case frame, so that the
/// shared misalignment is a single M_C^S (with m_ec = I in the copies).
struct MountingCases {
  std::vector<dataset::CaseData> cases;     // copies in the nominal case frame
  std::vector<double> weights;
  MountingKind kind;
};

MountingCases mounting_cases(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                           const PipelineOptions& options, std::optional<double> known_bias) {
  MountingCases m;
  for (std::size_t index : cases) {
    dataset::CaseData c = data.cases.at(index);
    c.a_e = c.a_e * c.m_ec.transpose();   // rows: (M_E^C a_E)^T
    if (c.w_e) *c.w_e = *c.w_e * c.m_ec.transpose();
    c.m_ec = frames::Dcm::Identity();
    if (known_bias) c.y.array() -= *known_bias;
    m.kind.add_case(c.kind);
    m.weights.push_back(case_weight(options, c));
    m.cases.push_back(std::move(c));
  }
  return m;
}

std::vector<StackInput> stack_inputs(const MountingCases& m, const std::vector<std::size_t>& cases,
                                     const frames::Dcm& m_cs) {
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < m.cases.size(); ++i) inputs.push_back({cases[i], &m.cases[i], m_cs, m.weights[i]});
  return inputs;
}

int max_lag_of(const std::vector<Term>& terms) {
  int lag = 0;
  for (const Term& t : terms) lag = std::max(lag, t.max_lag());
  return lag;
}

/// ERR order of the columns of a stacked problem (sensitivities forced first, the bias after
/// them), without the columns the data cannot separate from the ones before them.
std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, const ident::ErrOptions& base,
                                               const std::vector<Eigen::Index>& nuisance = {}) {
  ident::ErrOptions options = base;
  options.forced.clear();
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (ident::is_sensitivity_label(s.labels[j])) options.forced.push_back(static_cast<Eigen::Index>(j));
  }
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (s.labels[j] == "1") options.forced.push_back(static_cast<Eigen::Index>(j));
  }
  options.forced.insert(options.forced.end(), nuisance.begin(), nuisance.end());
  options.reference = ident::ErrReference::AfterForced;
  return ident::err_rank(s.phi, s.y, options).order;
}

/// ULS on `columns`; when the fit names a near-dependence, the named column ranked last (never a
/// sensitivity) leaves `columns`, is recorded in `dropped`, and the fit is repeated.
ident::UlsResult fit_identifiable(const StackedRegression& s, std::vector<Eigen::Index>& columns,
                                  const ident::UlsOptions& uls, std::vector<std::string>& dropped) {
  for (;;) {
    std::vector<Eigen::Index> sorted = columns;
    std::sort(sorted.begin(), sorted.end());
    try {
      return ident::uls_batch(s.phi, s.y, s.labels, s.rational, uls, sorted);
    } catch (const ident::IdentifiabilityError& e) {
      std::vector<std::string> ranked;
      for (const Eigen::Index j : columns) ranked.push_back(s.labels[static_cast<std::size_t>(j)]);
      const std::optional<std::size_t> leaves =
          ident::column_to_leave(e, ranked, [&](std::size_t j) { return ident::is_sensitivity_label(ranked[j]); });
      if (!leaves) throw;
      const auto victim = columns.begin() + static_cast<std::ptrdiff_t>(*leaves);
      dropped.push_back(s.labels[static_cast<std::size_t>(*victim)]);
      columns.erase(victim);
    }
  }
}

/// Columns of `labels` that are plain squares of a sensor-frame acceleration (a_i^2, a_p^2,
/// a_o^2, at any lag): the terms eq. 12 passes through K_jj(s).
std::vector<Eigen::Index> square_columns(const std::vector<std::string>& labels) {
  std::vector<Eigen::Index> out;
  for (std::size_t j = 0; j < labels.size(); ++j) {
    if (labels[j] == "1" || labels[j].find("^2") == std::string::npos) continue;
    if (is_square_term(ident::parse_term(labels[j]))) out.push_back(static_cast<Eigen::Index>(j));
  }
  return out;
}

/// Applies a mounting's square high pass (if any) to a freshly stacked problem.
void apply_square_model(StackedRegression& s, const dataset::Dataset& data, std::optional<double> corner_rad_s) {
  if (!corner_rad_s) return;
  const std::vector<Eigen::Index> squares = square_columns(s.labels);
  if (!squares.empty()) highpass_columns(s.phi, squares, s.cases, data, *corner_rad_s);
}

/// One mounting's regression as algorithm 2 fits it: its cases stacked with M_C^S = m_cs, the
/// squares through the mounting's high pass, AR-whitened.
StackedRegression whitened_regression(std::span<const Term> terms, const MountingCases& m, const std::vector<std::size_t>& cases,
                                      const frames::Dcm& m_cs, const dataset::Dataset& data, std::string_view label,
                                      Eigen::Index first_row, std::optional<double> square_corner,
                                      const ArWhitener& whitener) {
  StackedRegression s = stack_regressions(terms, stack_inputs(m, cases, m_cs), data.t_ref, label, first_row);
  apply_square_model(s, data, square_corner);
  whitener.apply(s);
  return s;
}

/// The squares' corner by the GLS criterion: the search on the rows of `unfiltered` (squares not
/// yet high-passed) after the AR whitening. Why: under 1/f noise the unwhitened residual sum of
/// squares is dominated by the noise's slow wander, and a corner found there scatters many times
/// more than its information says: on sim-paper-daq (20 seeds, truth 500 rad/s) 411-655 rad/s,
/// sd 13 %, moving every term correlated with the squares 2-10 times their sd; found here, mean
/// 499.5 and sd 1.4 % against the 1.3 % its Jacobian column predicts (HonestPrune::searched).
/// The high pass and the whitening are both linear filters run case by case, so they commute but
/// for a case's first few samples.
std::optional<double> whitened_corner(StackedRegression unfiltered, const ArWhitener& whitener, const dataset::Dataset& data,
                                      const PipelineOptions& options) {
  const std::vector<Eigen::Index> squares = square_columns(unfiltered.labels);
  if (squares.empty()) return std::nullopt;
  whitener.apply(unfiltered);
  const SquareCornerSearch search(unfiltered, squares, data);
  return search.best(options.square_highpass_min_rad_s,
                     std::min(options.square_highpass_max_rad_s, max_corner(unfiltered.cases, data)));
}

bool uses_cross_axes(const std::vector<Term>& terms) {
  return std::any_of(terms.begin(), terms.end(),
                     [](const Term& t) { return t.uses(ident::Variable::Ap) || t.uses(ident::Variable::Ao); });
}

/// The F_S terms a tilt of the input axis adds to the sensitivity term when `s_terms` has it
/// (a_i; w_i for gyroscopes) and lacks them: to first order in the tilt (d_p, d_o),
/// theta_i (n_i + d_p n_p + d_o n_o) . a = theta_i a_i + theta_i d_p a_p + theta_i d_o a_o.
/// Only axes the mounting's excitation determines get one (`axes`: XRA, YRA).
std::vector<Term> tilt_terms(const std::vector<Term>& s_terms, dataset::SensorKind sensor, std::array<bool, 2> axes) {
  using ident::Variable;
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  const auto plain = [](Variable v) { return Term::from_factors({ident::Factor{v, 0, ident::FactorFunction::Plain, 1}}); };
  if (std::find(s_terms.begin(), s_terms.end(), plain(gyro ? Variable::Wi : Variable::Ai)) == s_terms.end()) return {};
  std::vector<Term> out;
  const auto variables = gyro ? std::array{Variable::Wp, Variable::Wo} : std::array{Variable::Ap, Variable::Ao};
  for (std::size_t a = 0; a < 2; ++a) {
    if (axes[a] && std::find(s_terms.begin(), s_terms.end(), plain(variables[a])) == s_terms.end()) out.push_back(plain(variables[a]));
  }
  return out;
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

/// The mounting's angles from its M_C^S, with `sd` (about i, p, o); an angle held at the nominal
/// frame has sd 0 (XRA without excitation holds the angle about o, YRA the one about p).
void set_angles(MountingResult& result, const Eigen::Vector3d& sd) {
  result.angles = rotation_vector(result.m_cs);
  result.angles_sd = sd;
  if (!result.excitation.determined[1]) result.angles_sd(2) = 0.0;
  if (!result.excitation.determined[2]) result.angles_sd(1) = 0.0;
  result.angles(0) = std::nan("");
  result.angles_sd(0) = std::nan("");
}

/// Algorithm 2 steps 6-8 as a selection hook: the misalignment from the step-5 fit, then the F_S
/// problem of the ranked terms built with it.
class MisalignmentHook final : public ident::FitHook {
 public:
  MisalignmentHook(const MountingCases& m, const std::vector<std::size_t>& cases, const std::vector<Term>& es_terms,
                   const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                   const ArWhitener& whitener, std::optional<double> square_corner, double twist,
                   std::array<bool, 2> tilt_axes)
      : m_(m), cases_(cases), es_terms_(es_terms), data_(data), label_(label), first_row_(first_row),
        whitener_(whitener), square_corner_(square_corner), twist_(twist), tilt_axes_(tilt_axes) {}

  /// The tilt terms kept in the stage of j ranked terms (empty: none).
  [[nodiscard]] std::vector<std::string> tilts(std::size_t j) const {
    return j >= 1 && j <= tilts_.size() ? tilts_[j - 1] : std::vector<std::string>{};
  }

  bool transform(std::size_t j, const ident::UlsResult& ranked_fit, ident::StageProblem& stage) override {
    const auto theta = external_sensitivities(ranked_fit.labels, ranked_fit.theta, data_.sensor);
    if (misalignments_.size() < j) misalignments_.resize(j);
    if (!theta) return false;   // no a_x, a_y, a_z yet: nothing to align; score the F_E problem
    const frames::Dcm m_cs = with_twist(misalignment_from_sensitivities(*theta, frames::Dcm::Identity()), twist_);
    misalignments_[j - 1] = m_cs;
    std::vector<Term> ranked;
    for (const std::string& label : ranked_fit.labels) ranked.push_back(ident::parse_term(label));
    std::vector<Term> s_terms = ident::to_sensor_frame(ranked);
    // M_E^S came from this data: its tilt stays free in the F_S fit (kept, never pruned), or the
    // t-tests would credit its error to terms that share its directions (under gravity a tilt
    // error is a per-orientation offset, which 1, abs(a_i), sign(a_i) and the squares can fit).
    const std::size_t model_terms = s_terms.size();
    std::vector<Term> tilts = tilt_terms(s_terms, data_.sensor, tilt_axes_);
    s_terms.insert(s_terms.end(), tilts.begin(), tilts.end());
    stage.kept.clear();
    for (std::size_t c = model_terms; c < s_terms.size(); ++c) stage.kept.push_back(static_cast<Eigen::Index>(c));
    if (tilts_.size() < j) tilts_.resize(j);
    tilts_[j - 1] = ident::to_strings(tilts);
    StackedRegression s =
        whitened_regression(s_terms, m_, cases_, m_cs, data_, label_, first_row_, square_corner_, whitener_);
    stage.phi = std::move(s.phi);
    stage.y = std::move(s.y);
    stage.labels = std::move(s.labels);
    stage.rational = std::move(s.rational);
    return true;
  }

  [[nodiscard]] std::optional<frames::Dcm> misalignment(std::size_t j) const {
    return j >= 1 && j <= misalignments_.size() ? misalignments_[j - 1] : std::nullopt;
  }

 private:
  const MountingCases& m_;
  const std::vector<std::size_t>& cases_;
  const std::vector<Term>& es_terms_;
  const dataset::Dataset& data_;
  std::string_view label_;
  Eigen::Index first_row_;
  const ArWhitener& whitener_;
  std::optional<double> square_corner_;
  double twist_;
  std::array<bool, 2> tilt_axes_;
  std::vector<std::optional<frames::Dcm>> misalignments_;
  std::vector<std::vector<std::string>> tilts_;
};

/// One angle a mounting's excitation does not determine (excitation.hpp), held at the nominal
/// frame in blocks 5-6 and estimated in the batch with the tolerance as prior.
struct HeldColumn {
  std::size_t mounting = 0;                 // into the result's mountings
  int axis = 1;                             // 1: tilt of n_i toward p (turn about o), 2: toward o (about p),
                                            // 3: twist about n_i (PipelineOptions::batch_relative_twist)
};

std::vector<HeldColumn> held_columns(const std::vector<MountingResult>& mountings) {
  std::vector<HeldColumn> held;
  for (std::size_t m = 0; m < mountings.size(); ++m) {
    for (int axis = 1; axis < 3; ++axis) {
      if (!mountings[m].excitation.determined[static_cast<std::size_t>(axis)]) held.push_back({m, axis});
    }
  }
  return held;
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

/// True when `c` is a piece of the plan case whose rows the stack holds just before it
/// (CaseData::piece_of): a few lost samples cut neither its noise process nor its phases.
bool continues_plan_case(const dataset::CaseData& c, const std::string* previous_plan_case) {
  return previous_plan_case != nullptr && !c.piece_of.empty() && *previous_plan_case == c.plan_case();
}

/// One id per batch row: the contiguous runs of one phase label within a case of the plan (the
/// whole case when it has no phase column). A phase cut by lost samples into two pieces of its
/// case (CaseData::piece_of) is one run. The clusters of the jackknife inference.
std::vector<int> phase_clusters(const StackedRegression& batch, const dataset::Dataset& data) {
  std::vector<int> ids(static_cast<std::size_t>(batch.phi.rows()), -1);
  int next = 0;
  const std::string* previous_case = nullptr;
  std::string previous_phase;
  for (const CaseRows& rows : batch.cases) {
    const dataset::CaseData& c = data.cases[rows.case_index];
    const bool continues = continues_plan_case(c, previous_case);
    for (Eigen::Index r = 0; r < rows.rows; ++r) {
      const auto sample = static_cast<std::size_t>(rows.first_sample + r);
      const std::string& phase = c.phase.empty() ? c.plan_case() : c.phase_names[c.phase[sample]];
      if ((r == 0 && !continues) || phase != previous_phase) ++next;
      previous_phase = phase;
      ids[static_cast<std::size_t>(rows.begin + r)] = next;
    }
    if (rows.rows > 0) previous_case = &c.plan_case();
  }
  return ids;
}

/// The stacked rows of each case of the plan: its pieces (CaseData::piece_of) are consecutive in
/// the stack, and one noise process runs through them (a few lost samples do not restart it).
std::vector<CaseRows> plan_case_rows(const StackedRegression& batch, const dataset::Dataset& data) {
  std::vector<CaseRows> out;
  const std::string* previous_case = nullptr;
  for (const CaseRows& rows : batch.cases) {
    const dataset::CaseData& c = data.cases[rows.case_index];
    if (rows.rows == 0) continue;
    if (continues_plan_case(c, previous_case) && out.back().begin + out.back().rows == rows.begin) {
      out.back().rows += rows.rows;
    } else {
      out.push_back(rows);
    }
    previous_case = &c.plan_case();
  }
  return out;
}

/// The derivative of a fit's prediction with respect to a parameter its regression was built
/// with (HonestPrune::searched), by a central difference: `stack_at(terms, offset)` rebuilds the
/// whitened regression of the fit's terms with the parameter moved by `offset`.
Eigen::VectorXd prediction_derivative(const ident::UlsResult& fit, double step,
                                      const std::function<StackedRegression(std::span<const Term>, double)>& stack_at) {
  const Eigen::Index p = fit.process_terms;
  std::vector<Term> terms;
  for (Eigen::Index j = 0; j < p; ++j) terms.push_back(ident::parse_term(fit.labels[std::size_t(j)]));
  const StackedRegression up = stack_at(terms, step), down = stack_at(terms, -step);
  return (up.phi - down.phi) * fit.theta.head(p) / (2.0 * step);
}

bool has_square(const ident::UlsResult& fit) {
  return !square_columns(std::vector<std::string>(fit.labels.begin(), fit.labels.begin() + fit.process_terms)).empty();
}

/// The plan's own noise where it holds still: the Allan variance of the unwhitened residual over
/// the static stretches (noise::static_stretches: dwells, static cases), pooled, and its terms.
/// A case's whitened residual cannot say what its noise does below one cycle per case, and a case's
/// mean (the bias, a pose's static terms) is read there. The static stretches of all cases together
/// can: on sim-rotation-table acc1 they give B 8.7e-5 mA to +-3 %, where each case's whitened
/// residual left B and K undetermined.
struct StaticNoiseLaw {
  noise::NoiseFit fit;
  double tau0_s = 0.0;
  Eigen::Index plan_rows = 0;   // the rows of every case: one cycle per plan is the lowest frequency it spans

  /// The whitened residual's two-sided density per sample at f cycles per sample, below one cycle
  /// per case (noise::fitted_spectrum's below_record): the law's white part and its determined
  /// flicker and random walk through the whitener's gain at DC, A(1)^2, held at its level at one
  /// cycle per plan below that.
  [[nodiscard]] std::function<double(double)> below_record(const ArWhitener& whitener) const {
    const double gain = 1.0 - whitener.coefficients().sum();
    noise::NoiseFit held = fit;
    for (const noise::NoiseTerm t : {noise::NoiseTerm::B, noise::NoiseTerm::K, noise::NoiseTerm::R}) {
      noise::NoiseCoefficient& c = held.terms[static_cast<std::size_t>(t)];
      if (!c.determined || t == noise::NoiseTerm::R) c.value = 0.0;
    }
    const double lowest = 1.0 / static_cast<double>(std::max<Eigen::Index>(plan_rows, 1));
    const double rate = 1.0 / tau0_s;
    return [held, gain, lowest, rate, tau0 = tau0_s](double f) {
      return gain * gain * 0.5 * noise::model_psd(held, std::max(f, lowest) * rate, tau0) * rate;
    };
  }
};

/// The law of `residuals` (unwhitened, rows of `layout`) over the static stretches of `data`; none
/// when the plan has none of 64 samples or more, or too few octaves for the fit.
std::optional<StaticNoiseLaw> static_noise_law(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout,
                                               const dataset::Dataset& data) {
  StaticNoiseLaw out;
  std::vector<std::vector<noise::AllanPoint>> stretches;
  for (const CaseRows& rows : layout) out.plan_rows += rows.rows;
  for (const noise::Stretch& stretch : noise::static_stretches(data)) {
    const double period = data.cases[stretch.case_index].sample_period_s;
    if (out.tau0_s == 0.0) out.tau0_s = period;
    if (std::abs(period - out.tau0_s) > 1e-9 * out.tau0_s) continue;
    for (const CaseRows& rows : layout) {
      if (rows.case_index != stretch.case_index) continue;
      const Eigen::Index from = std::max(stretch.begin, rows.first_sample), to = std::min(stretch.end, rows.first_sample + rows.rows);
      if (to - from < 64) continue;
      noise::AllanAccumulator allan(out.tau0_s);
      allan.push(residuals.segment(rows.begin + from - rows.first_sample, to - from));
      stretches.push_back(allan.points());
    }
  }
  if (stretches.empty()) return std::nullopt;
  noise::NoiseFitOptions options;
  options.terms[static_cast<std::size_t>(noise::NoiseTerm::R)] = false;   // a drift, not a stationary noise
  try {
    out.fit = noise::fit_noise(noise::pool(stretches), options);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
  // A law that does not hold on its own stretches is not carried below them. The gyro bench's
  // Gauss-Markov rate noise (correlation 0.1 s) in dwells of about a second reads as flicker and
  // random walk (chi-square 42.7 on 6 dof), and that random walk, held at one cycle per plan,
  // made w_i's sd 14 times the spread.
  if (out.fit.dof > 0 && boost::math::cdf(boost::math::complement(boost::math::chi_squared(out.fit.dof), out.fit.chi_square)) < 1e-3)
    return std::nullopt;
  return out;
}

/// Honest inference after a selection (whose t-tests take every sample as independent), on a
/// fitted model of a stacked problem. The cases' contiguous phases are clusters; offsets between
/// them that the noise model does not explain (a pose's placement, drift, 1/f noise below the AR
/// model's reach, a model error that repeats per phase) are a variance component
/// (statistics.hpp, cluster_offsets), and every coefficient's covariance includes what they do to
/// it. A term that varies within the phases is determined there and tested on the samples' dof; a
/// term constant within each phase (a square in static poses, the bias) is determined only by
/// the phases' means and is tested on the between-phase dof, less the parameters found by a
/// search on the same data (`searched`: mounting angles, the squares' corner). When the model has as many
/// phase-level parameters as phases the offsets cannot be told from it: the weakest removable
/// phase-level term leaves first. Then, one at a time, the term whose test falls below
/// `threshold` leaves and the model is refitted. `extra` may add to the covariance (held angles).
struct HonestPrune {
  const StackedRegression* s = nullptr;
  const std::vector<int>* clusters = nullptr;
  const std::vector<CaseRows>* noise_runs = nullptr;   // one noise process each (plan_case_rows)
  const Eigen::VectorXd* loading = nullptr;    // per row: a_p^2 + a_o^2 (the placement tilt's reach)
  double threshold = 0.01;
  bool may_remove = true;
  std::function<bool(const std::string&)> protect;
  std::function<void(const ident::UlsResult&, Eigen::MatrixXd&)> extra;
  // Parameters the fit's columns depend on that were estimated by a search on the same data (the
  // squares' corner, the mountings' angles): the derivative of the fitted prediction with respect
  // to each, one whitened column per parameter (rows of s). They join the covariance as columns
  // of the Jacobian, so what their own uncertainty moves is in the coefficients' sd (sim-paper-daq:
  // the corner's column predicts its sd at 1.3 %; over 20 seeds it spread 1.4 %).
  std::function<Eigen::MatrixXd(const ident::UlsResult&)> searched;
  // The whitened residual's density below one cycle per case (StaticNoiseLaw::below_record); empty:
  // its white part alone.
  std::function<double(double)> below_record;
};

struct HonestResult {
  ident::ClusterOffsets offsets;
  Eigen::VectorXd dof;
  Eigen::MatrixXd searched_covariance;   // the searched parameters' block of the joint covariance
};

/// Offset variances, or weights, that differ between clusters by less than this factor leave
/// least squares as it is.
constexpr double kDistinct = 10.0;

/// The random-effects estimate (ident::random_effects_fit) under the offsets `offsets` found, with
/// the noise model of the plan's cases (noise_times(M) = R M).
std::optional<ident::RandomEffectsFit> random_effects(const Eigen::MatrixXd& x, Eigen::Index estimated, const Eigen::VectorXd& y,
                                                      const std::vector<int>& clusters, const Eigen::VectorXd* loading,
                                                      const ident::ClusterOffsets& offsets, const ident::ColouredNoise& coloured,
                                                      const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& noise_times) {
  const auto g_count = static_cast<Eigen::Index>(coloured.cluster_ids.size());
  if (g_count < 2) return std::nullopt;
  Eigen::VectorXd loading_sum = Eigen::VectorXd::Zero(g_count), rows = Eigen::VectorXd::Zero(g_count);
  for (std::size_t k = 0; k < clusters.size(); ++k) {
    const auto g = std::lower_bound(coloured.cluster_ids.begin(), coloured.cluster_ids.end(), clusters[k]) - coloured.cluster_ids.begin();
    if (loading != nullptr && loading->size() != 0) loading_sum(g) += (*loading)(static_cast<Eigen::Index>(k));
    rows(g) += 1.0;
  }
  Eigen::VectorXd tau2(g_count), noise_sums(g_count);
  for (Eigen::Index g = 0; g < g_count; ++g) {
    tau2(g) = offsets.tau2_common + offsets.tau2_per_loading * loading_sum(g) / rows(g);
    noise_sums(g) = coloured.sums_covariance(g, g);
    if (!(noise_sums(g) > 0.0)) return std::nullopt;
  }
  // An offset alike in every phase leaves the combination of the phases' means as least squares
  // has it, and the weights then only trade those means against what varies within the phases,
  // which in static phases is the whitening's transients and the reference's noise: on sim-tumble
  // seed 31, under a common offset, the weighed fit's covariance came out indefinite.
  if (!(tau2.maxCoeff() > kDistinct * tau2.minCoeff())) return std::nullopt;
  std::optional<ident::RandomEffectsFit> out;
  try {
    out = ident::random_effects_fit(x, estimated, y, clusters, tau2, noise_sums, noise_times);
  } catch (const std::invalid_argument&) {
    return std::nullopt;   // the weighed columns are dependent: least squares with the sandwich stands
  }
  // Weights alike: the offsets are small against the noise in every phase, and least squares is
  // as good.
  if (!(out->weights.maxCoeff() > kDistinct * out->weights.minCoeff())) return std::nullopt;
  if (!out->covariance.allFinite() || (out->covariance.diagonal().array() < 0.0).any()) return std::nullopt;
  return out;
}

HonestResult honest_prune(const HonestPrune& h, std::vector<Eigen::Index>& columns, ident::UlsResult& fit,
                          const ident::UlsOptions& uls, std::vector<UndeterminedTerm>* removed, std::string_view what) {
  const StackedRegression& s = *h.s;
  std::vector<std::string> dropped;
  // The whitened residual's own noise model per case of the plan (its low-frequency colour:
  // coloured_noise.hpp), fitted once on the selected model's residual: a term that leaves takes its
  // column of the meat X'RX with it, and the residual it leaves behind differs by a term that
  // tested as nothing.
  std::vector<noise::SegmentSpectrum> spectra;
  ident::ColouredNoise coloured;
  for (;;) {
    HonestResult out;
    const Eigen::Index p = fit.process_terms;
    out.dof = Eigen::VectorXd::Constant(p, static_cast<double>(fit.residuals.size() - p - 1));
    if (s.phi.rows() != fit.residuals.size() || p == 0) return out;
    Eigen::MatrixXd searched = h.searched ? h.searched(fit) : Eigen::MatrixXd();
    if (searched.cols() == 0) searched.resize(s.phi.rows(), 0);
    if (searched.rows() != s.phi.rows()) throw std::logic_error("honest_prune: searched columns of another stack");
    Eigen::MatrixXd x(s.phi.rows(), p + searched.cols());
    std::vector<Eigen::Index> output_multiplied;
    for (Eigen::Index j = 0; j < p; ++j) {
      const auto column = static_cast<Eigen::Index>(std::find(s.labels.begin(), s.labels.end(), fit.labels[std::size_t(j)]) -
                                                    s.labels.begin());
      if (std::find(s.rational.columns.begin(), s.rational.columns.end(), column) != s.rational.columns.end()) output_multiplied.push_back(j);
      x.col(j) = s.phi.col(column);
    }
    x.leftCols(p) *= ident::linear_form_signs(p, output_multiplied).asDiagonal();   // the linear form
    x.rightCols(searched.cols()) = searched;
    if (spectra.empty()) {
      std::map<int, Eigen::Index> order;   // cluster id -> column of Z (ascending ids)
      for (const int id : *h.clusters) order.emplace(id, 0);
      for (auto& [id, column] : order) {
        column = static_cast<Eigen::Index>(coloured.cluster_ids.size());
        coloured.cluster_ids.push_back(id);
      }
      const auto g_count = static_cast<Eigen::Index>(order.size());
      coloured.sums_covariance = Eigen::MatrixXd::Zero(g_count, g_count);
      for (const CaseRows& rows : *h.noise_runs) {
        spectra.push_back(noise::fitted_spectrum(fit.residuals.segment(rows.begin, rows.rows), h.below_record));
        // The covariance of the sums of this case's phases (each phase a run of rows within it).
        std::vector<Eigen::Index> columns;
        for (Eigen::Index k = rows.begin; k < rows.begin + rows.rows; ++k) {
          const Eigen::Index g = order.at((*h.clusters)[static_cast<std::size_t>(k)]);
          if (std::find(columns.begin(), columns.end(), g) == columns.end()) columns.push_back(g);
        }
        Eigen::MatrixXd z = Eigen::MatrixXd::Zero(rows.rows, static_cast<Eigen::Index>(columns.size()));
        for (Eigen::Index k = 0; k < rows.rows; ++k) {
          const Eigen::Index g = order.at((*h.clusters)[static_cast<std::size_t>(rows.begin + k)]);
          z(k, std::find(columns.begin(), columns.end(), g) - columns.begin()) = 1.0;
        }
        const Eigen::MatrixXd zrz = z.transpose() * noise::covariance_times(spectra.back(), z);
        for (std::size_t a = 0; a < columns.size(); ++a)
          for (std::size_t b = 0; b < columns.size(); ++b) coloured.sums_covariance(columns[a], columns[b]) = zrz(Eigen::Index(a), Eigen::Index(b));
      }
    }
    // R m for columns m over the stack's rows: each case of the plan under its own spectrum.
    const auto noise_times = [&](const Eigen::MatrixXd& m) {
      Eigen::MatrixXd out = Eigen::MatrixXd::Zero(m.rows(), m.cols());
      for (std::size_t r = 0; r < spectra.size(); ++r) {
        const CaseRows& run = (*h.noise_runs)[r];
        out.middleRows(run.begin, run.rows) = noise::covariance_times(spectra[r], m.middleRows(run.begin, run.rows));
      }
      return out;
    };
    const Eigen::MatrixXd rx = noise_times(x);
    coloured.meat = x.transpose() * rx;
    coloured.cross = Eigen::MatrixXd::Zero(x.cols(), static_cast<Eigen::Index>(coloured.cluster_ids.size()));
    for (Eigen::Index k = 0; k < x.rows(); ++k) {
      const int id = (*h.clusters)[static_cast<std::size_t>(k)];
      const auto g = std::lower_bound(coloured.cluster_ids.begin(), coloured.cluster_ids.end(), id) - coloured.cluster_ids.begin();
      coloured.cross.col(g) += rx.row(k).transpose();
    }
    coloured.meat = (0.5 * (coloured.meat + coloured.meat.transpose())).eval();
    // Nothing is estimated elsewhere from the phases' means: what was (angles, corner) is in x.
    out.offsets = ident::cluster_offsets(x, fit.residuals, fit.residual_variance, *h.clusters, 0,
                                         h.loading != nullptr ? *h.loading : Eigen::VectorXd(), &coloured);
    const Eigen::MatrixXd x_process = x.leftCols(p);
    // Which terms live between the phases: little of their column varies within one.
    std::vector<bool> phase_level(static_cast<std::size_t>(p), false);
    {
      std::map<int, std::pair<Eigen::VectorXd, double>> sums;
      for (Eigen::Index k = 0; k < x.rows(); ++k) {
        auto [it, fresh] = sums.try_emplace((*h.clusters)[static_cast<std::size_t>(k)]);
        if (fresh) it->second = {Eigen::VectorXd::Zero(p), 0.0};
        it->second.first += x_process.row(k).transpose();
        it->second.second += 1.0;
      }
      Eigen::VectorXd between = Eigen::VectorXd::Zero(p);
      for (const auto& [id, sum] : sums) between += sum.first.cwiseAbs2() / sum.second;
      const Eigen::VectorXd total = x_process.colwise().squaredNorm().transpose();
      for (Eigen::Index j = 0; j < p; ++j) phase_level[std::size_t(j)] = ident::cluster_level(total(j), between(j));
    }
    // When the phases' means are all the model's columns say (every term constant within each
    // phase: static poses) and their offsets differ, each mean is weighed by what its offset
    // leaves of it (random effects). Where a column varies within the phases the weights would
    // also trade the means against that variation, which leans on the within-phase noise model:
    // on sim-paper-daq the weighed estimates spread up to 1.30 times their sd over 60 seeds, where
    // least squares' spread 1.21 times theirs (plan-check), so there least squares with the
    // sandwich above stays. So it does for ULS's output-multiplied columns and noise terms, which
    // carry their own noise model.
    std::optional<ident::RandomEffectsFit> weighed;
    const bool means_only = std::all_of(phase_level.begin(), phase_level.end(), [](bool b) { return b; });
    if (means_only && out.offsets.tau2 > 0.0 && output_multiplied.empty() && fit.theta.size() == p)
      weighed = random_effects(x, p, s.y, *h.clusters, h.loading, out.offsets, coloured, noise_times);
    if (weighed) {
      out.offsets.within = weighed->within;
      out.offsets.covariance = weighed->covariance;
      out.offsets.weights = weighed->weights;
    }
    // The searched parameters' rows and columns have done their work (the terms' block of the
    // joint covariance includes them); what is reported is the terms'.
    out.searched_covariance = out.offsets.covariance.bottomRightCorner(searched.cols(), searched.cols());
    out.offsets.classical =
        fit.residual_variance * (x_process.transpose() * x_process).ldlt().solve(Eigen::MatrixXd::Identity(p, p));
    for (Eigen::MatrixXd* m : {&out.offsets.within, &out.offsets.covariance}) *m = m->topLeftCorner(p, p).eval();
    // The fit's covariance (ULS's, with its bias correction) takes the residual as white and the
    // searched parameters as known: what the residual's colour, the offsets between phases and
    // the searched parameters add to that is added to it.
    // The weighed estimate's covariance is its own sandwich, whole.
    Eigen::MatrixXd covariance = weighed ? out.offsets.covariance
                                         : Eigen::MatrixXd(fit.covariance.topLeftCorner(p, p) + out.offsets.covariance -
                                                           out.offsets.classical);
    // A term constant within each phase is determined by the phases' means alone, and is tested on
    // their dof whatever the offsets' estimate: on few dof that estimate often comes out near 0
    // (sim-tumble seed 119: 6 poses, 1 dof, and a_o^2 named from the placement scatter at t -22.8
    // on the samples' 17774 dof; the mounting's angles then 250 of their sd from the truth).
    // Weighed by clearly distinct offsets, the phases' means carry the offsets' share of a term's
    // variance by its weights, and only that share is known on their dof (Welch-Satterthwaite):
    // a tumble's bias and scale factor, from the two poses a placement tilt hardly moves, on the
    // noise's; the angles, from the four it moves, on the poses'. The offsets' estimate here is
    // clear of 0 (the weights differ: kDistinct), which is when the rule above would hide them.
    for (Eigen::Index j = 0; j < p; ++j) {
      const bool offsets_dominate = out.offsets.tau2 > 0.0 && out.offsets.covariance(j, j) > 2.0 * out.offsets.within(j, j);
      const bool between_only = phase_level[std::size_t(j)] && out.offsets.clusters >= 2 && out.offsets.between_dof >= 1;
      if (!(offsets_dominate || between_only)) continue;
      const double samples_dof = out.dof(j), between_dof = std::max(1, out.offsets.between_dof);
      out.dof(j) = between_dof;
      if (weighed) {
        const double v = out.offsets.covariance(j, j), w = out.offsets.within(j, j), o = std::max(0.0, v - w);
        out.dof(j) = std::clamp(v * v / (o * o / between_dof + w * w / samples_dof), between_dof, samples_dof);
      }
    }
    if (h.extra) h.extra(fit, covariance);   // the least-squares fit's response to a held turn stands for the weighed one's
    if (weighed) {
      fit.theta.head(p) = weighed->theta;
      fit.residuals = s.y - x.leftCols(p) * weighed->theta;
      fit.residual_variance = fit.residuals.squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, fit.residuals.size() - p));
    }
    fit.covariance.topLeftCorner(p, p) = covariance;
    // A variance that rounding left at or below zero belongs to a column the joint design (with the
    // searched parameters' columns) cannot tell from the others: not determined, t 0, never a t of
    // infinity (sim-tumble seed 31: sign(a_i) and a_i*abs(a_i) beside a_i).
    fit.std_dev = fit.covariance.diagonal().unaryExpr([](double v) {
      return v > 0.0 && std::isfinite(v) ? std::sqrt(v) : std::numeric_limits<double>::infinity();
    });
    const bool saturated = out.offsets.clusters >= 2 && out.offsets.between_dof <= 0;
    Eigen::Index worst = -1;
    double worst_p = -1.0, worst_t = 0.0;
    for (Eigen::Index j = 0; j < p; ++j) {
      const std::string& label = fit.labels[std::size_t(j)];
      if (h.protect && h.protect(label)) continue;
      const double t = fit.theta(j) / fit.std_dev(j);
      double pv = 0.0;
      if (saturated) {
        if (!phase_level[std::size_t(j)]) continue;
        pv = 1.0 / (1.0 + std::abs(t));   // the weakest phase-level term by its classical t
      } else {
        pv = ident::student_t_two_sided_p(t, out.dof(j));
        if (!(pv > h.threshold)) continue;
      }
      if (pv > worst_p) {
        worst = j;
        worst_p = pv;
        worst_t = t;
      }
    }
    if (worst < 0 || !h.may_remove) return out;
    const std::string label = fit.labels[std::size_t(worst)];
    if (removed != nullptr) {
      removed->push_back(
          {label, saturated ? fmt::format("left out of the {} after selection: it had as many parameters at the level of the "
                                          "{} phases' means as there are phases, so the offsets between them (placement, "
                                          "drift) could not be told from it; this was its weakest (t {:.1f})",
                                          what, out.offsets.clusters, worst_t)
                            : fmt::format("left out of the {} after selection: t {:.1f} on {:.0f} dof, with the offsets "
                                          "between its {} phases{}, is below the selection's level",
                                          what, worst_t, out.dof(worst), out.offsets.clusters,
                                          h.extra ? " and the held angles" : "")});
    }
    const auto at = std::find(s.labels.begin(), s.labels.end(), label);
    std::erase(columns, static_cast<Eigen::Index>(at - s.labels.begin()));
    fit = fit_identifiable(s, columns, uls, dropped);
  }
}

/// Per row of a whitened stacked problem: a_p^2 + a_o^2 (gyros w_p^2 + w_o^2) unfiltered, the
/// reach of a small tilt of the input axis (the loading of placement offsets, cluster_offsets).
Eigen::VectorXd cross_axis_loading(const StackedRegression& whitened, std::span<const Term> candidates, const dataset::Dataset& data,
                                   const std::vector<CaseOutcome>& cases, const ArWhitener& whitener, std::string_view label) {
  const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;
  const std::vector<Term> cross = ident::parse_terms(gyro ? std::vector<std::string>{"w_p", "w_o"} : std::vector<std::string>{"a_p", "a_o"});
  std::vector<StackInput> inputs;
  for (const CaseRows& rows : whitened.cases) inputs.push_back({rows.case_index, &data.cases[rows.case_index], cases[rows.case_index].m_es, 1.0});
  const StackedRegression raw = stack_regressions(cross, inputs, data.t_ref, label, ident::first_usable_row(candidates));
  Eigen::VectorXd out(whitened.phi.rows());
  for (std::size_t c = 0; c < whitened.cases.size(); ++c) {
    const CaseRows& w = whitened.cases[c];
    const CaseRows& r = raw.cases[c];
    const Eigen::Index skip = r.rows - w.rows;   // the whitener's first rows
    if (skip < 0 || r.case_index != w.case_index) throw std::logic_error("cross_axis_loading: layouts differ");
    out.segment(w.begin, w.rows) = raw.phi.middleRows(r.begin + skip, w.rows).rowwise().squaredNorm();
  }
  (void)whitener;
  return out;
}

/// One Gauss-Newton step for parameters the columns of the fitted, whitened stack `s` are built
/// with (variable projection: the terms re-fitted at every value). `derivatives`: the fitted
/// prediction's derivative per parameter (prediction_derivative). With J~ the derivatives with
/// the fit's columns projected out, the step is (J~'J~)^-1 J~'r; `information` gets J~'J~ /
/// sigma^2, the parameters' information with the terms free.
Eigen::VectorXd gauss_newton_step(const StackedRegression& s, const ident::UlsResult& fit, const Eigen::MatrixXd& derivatives,
                                  Eigen::MatrixXd& information) {
  Eigen::MatrixXd x(s.phi.rows(), fit.process_terms);
  for (Eigen::Index j = 0; j < x.cols(); ++j) {
    const auto at = std::find(s.labels.begin(), s.labels.end(), fit.labels[std::size_t(j)]);
    x.col(j) = s.phi.col(at - s.labels.begin());
  }
  const Eigen::LDLT<Eigen::MatrixXd> gram(x.transpose() * x);
  const Eigen::MatrixXd projected = derivatives - x * gram.solve(x.transpose() * derivatives);
  const Eigen::MatrixXd jj = projected.transpose() * projected;
  information = jj / fit.residual_variance;
  return jj.ldlt().solve(projected.transpose() * fit.residuals);
}

/// The batch's stacked inputs with every mounting's M_C^S (held angles applied).
std::vector<StackInput> batch_inputs(const dataset::Dataset& data, const PipelineOptions& options,
                                     const std::vector<MountingResult>& mountings, const std::vector<Eigen::Vector3d>& tilts,
                                     std::vector<CaseOutcome>& cases) {
  for (std::size_t m = 0; m < mountings.size(); ++m) {
    for (std::size_t index : mountings[m].cases) {
      cases[index].case_index = index;
      cases[index].m_es = turned(mountings[m].m_cs, tilts[m]) * data.cases[index].m_ec;   // M_E^S = M_C^S M_E^C
    }
  }
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    inputs.push_back({i, &data.cases[i], cases[i].m_es, case_weight(options, data.cases[i])});
  }
  return inputs;
}

/// The batch's whitened regression of the terms with each mounting turned (turned()) and the
/// squares through a corner (run_pipeline's batch_at).
using BatchAt = std::function<StackedRegression(std::span<const Term>, const std::vector<Eigen::Vector3d>&, std::optional<double>)>;

/// The relative twists of PipelineOptions::batch_relative_twist.
struct RelativeTwists {
  std::vector<std::size_t> estimated;   // mountings whose twist (and tilts) the batch refined
  std::vector<std::size_t> held;        // mountings whose twist the plan does not determine
};

/// PipelineOptions::batch_relative_twist: each further aligned mounting's turn against the
/// reference mounting (the first aligned), its twist about n_i with the tilts its excitation
/// determines, by Gauss-Newton steps on the whitened batch of every identifiable candidate. The
/// tilts join because a held twist leaks into them (the stage's model error: 0.003 deg on the
/// noise-free paper shaker). A twist whose sd, with the tilts free, exceeds the mounting
/// tolerance is held at the nominal frame; the rest turn their mounting's M_C^S, and `batch` is
/// rebuilt with them.
RelativeTwists relative_twists(StackedRegression& batch, const BatchAt& batch_at, const std::vector<Term>& candidates,
                               const dataset::Dataset& data, const PipelineOptions& options, PipelineResult& result) {
  RelativeTwists out;
  if (!options.batch_relative_twist || data.sensor != dataset::SensorKind::Accelerometer || !uses_cross_axes(candidates))
    return out;
  const auto reference =
      std::find_if(result.mountings.begin(), result.mountings.end(), [](const MountingResult& m) { return m.aligned; });
  if (reference == result.mountings.end()) return out;
  std::vector<std::size_t> turning;
  for (std::size_t k = 0; k < result.mountings.size(); ++k)
    if (result.mountings[k].aligned && &result.mountings[k] != &*reference) turning.push_back(k);
  const std::vector<Eigen::Vector3d> nominal(result.mountings.size(), Eigen::Vector3d::Zero());
  ident::UlsOptions uls = options.selection.uls;
  uls.noise_lags = 0;
  for (int iteration = 0; iteration < kTurnMaxSteps && !turning.empty(); ++iteration) {
    struct Parameter {
      std::size_t mounting;
      int axis;   // of turned(): 0, 1 tilts, 2 twist
    };
    std::vector<Parameter> parameters;
    for (std::size_t k : turning) {
      for (int axis = 0; axis < 2; ++axis)
        if (result.mountings[k].excitation.determined[static_cast<std::size_t>(axis) + 1]) parameters.push_back({k, axis});
      parameters.push_back({k, 2});
    }
    std::vector<Eigen::Index> usable = identifiable_ranking(batch, options.selection.err);
    std::vector<std::string> dropped;
    const ident::UlsResult fit = fit_identifiable(batch, usable, uls, dropped);
    Eigen::MatrixXd derivatives(batch.phi.rows(), static_cast<Eigen::Index>(parameters.size()));
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      derivatives.col(static_cast<Eigen::Index>(i)) = prediction_derivative(fit, 1e-4, [&](std::span<const Term> terms, double moved) {
        std::vector<Eigen::Vector3d> turns = nominal;
        turns[parameters[i].mounting](parameters[i].axis) = moved;
        return batch_at(terms, turns, result.square_corner_rad_s);
      });
    }
    Eigen::MatrixXd information;
    const Eigen::VectorXd delta = gauss_newton_step(batch, fit, derivatives, information);
    const Eigen::VectorXd sd = information.ldlt()
                                   .solve(Eigen::MatrixXd::Identity(information.rows(), information.cols()))
                                   .diagonal()
                                   .cwiseMax(0.0)
                                   .cwiseSqrt();
    if (iteration == 0) {
      std::vector<std::size_t> determined;
      for (std::size_t i = 0; i < parameters.size(); ++i) {
        if (parameters[i].axis != 2) continue;
        const double twist_sd = sd(static_cast<Eigen::Index>(i));
        MountingResult& m = result.mountings[parameters[i].mounting];
        if (std::isfinite(twist_sd) && twist_sd > 0.0 && twist_sd <= options.mounting_tolerance_rad) {
          determined.push_back(parameters[i].mounting);
        } else {
          out.held.push_back(parameters[i].mounting);
          m.twist_reference = reference->mounting;
          m.angles(0) = 0.0;
          m.angles_sd(0) = 0.0;   // held
          // A held twist leaks into the tilts the stage estimated with it: by how much, for a twist
          // of the tolerance, is the regression of the tilts on the twist in the information (the
          // other parameters free). It widens the angles' sd as the batch's refit widens the terms'.
          const auto j = static_cast<Eigen::Index>(i);
          std::vector<Eigen::Index> others;
          for (Eigen::Index r = 0; r < information.rows(); ++r)
            if (r != j) others.push_back(r);
          const Eigen::MatrixXd i_oo = information(others, others);
          const Eigen::VectorXd shift = -i_oo.ldlt().solve(information(others, j)) * options.mounting_tolerance_rad;
          for (std::size_t r = 0; r < others.size(); ++r) {
            const Parameter& tilt = parameters[static_cast<std::size_t>(others[r])];
            if (tilt.mounting != parameters[i].mounting || !std::isfinite(shift(static_cast<Eigen::Index>(r)))) continue;
            const int angle = angle_of_turn(tilt.axis);
            m.angles_sd(angle) = std::hypot(m.angles_sd(angle), shift(static_cast<Eigen::Index>(r)));
            m.angles_held_sd(angle) = std::abs(shift(static_cast<Eigen::Index>(r)));
          }
          result.notes.push_back(fmt::format(
              "the twist about n_i of mounting '{}' against '{}' is not determined by this plan (sd {:.2g} deg with its "
              "tilts free, more than the {:.2f} deg mounting tolerance): held at the nominal frame, and what the tolerance "
              "moves is in the sd; more cross-axis excitation (a_p, a_o) in both mountings determines it",
              m.mounting, reference->mounting, rad_to_deg(twist_sd), rad_to_deg(options.mounting_tolerance_rad)));
        }
      }
      if (determined.size() < turning.size()) {
        turning = determined;
        continue;   // the step again, without the held twists
      }
    }
    std::vector<Eigen::Vector3d> turns = nominal;
    for (std::size_t i = 0; i < parameters.size(); ++i) turns[parameters[i].mounting](parameters[i].axis) = delta(static_cast<Eigen::Index>(i));
    for (std::size_t k : turning) {
      MountingResult& m = result.mountings[k];
      m.m_cs = turned(m.m_cs, turns[k]);
      m.twist_rad += turns[k](2);
      m.twist_reference = reference->mounting;
      m.angles(0) = (std::isnan(m.angles(0)) ? 0.0 : m.angles(0)) + turns[k](2);
    }
    batch = batch_at(candidates, nominal, result.square_corner_rad_s);
    if ((delta.array().abs() <= kTurnConvergence * sd.array()).all()) break;
  }
  out.estimated = turning;
  for (std::size_t k : out.estimated) {
    // The tilts as algorithm 1 reads them: of n_i alone (the twist is angles(0)).
    MountingResult& m = result.mountings[k];
    const Eigen::Vector3d tilts = rotation_vector(misalignment_from_sensitivities(m.m_cs.row(0).transpose(), frames::Dcm::Identity()));
    m.angles(1) = tilts(1);
    m.angles(2) = tilts(2);
  }
  batch_inputs(data, options, result.mountings, nominal, result.cases);   // the cases' M_E^S with the turns
  return out;
}

}  // namespace

MountingGroups group_mountings(const std::vector<MountingKey>& cases, dataset::SensorKind sensor,
                               std::vector<std::string>* notes) {
  const auto note = [&](std::string text) {
    if (notes != nullptr) notes->push_back(std::move(text));
  };
  MountingGroups groups;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string& label = cases[i].label.empty() ? cases[i].name : cases[i].label;
    auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == label; });
    if (it == groups.end()) {
      groups.emplace_back(label, std::vector<std::size_t>{i});
    } else {
      it->second.push_back(i);
    }
  }
  if (sensor == dataset::SensorKind::Gyroscope) {
    if (groups.size() > 1) {
      note("gyroscope: one M_C^S for every case, from the rate sensitivities of all cases together (paper section 2.2: "
           "M_E^C of each case must be known accurately); mounting labels are not used");
    }
    std::vector<std::size_t> all(cases.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
    return {{"all cases", all}};
  }
  const bool labelled = std::any_of(cases.begin(), cases.end(), [](const MountingKey& c) { return !c.label.empty(); });
  std::vector<std::size_t> poses;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    if (cases[i].kind == CaseKind::Static || cases[i].kind == CaseKind::Thermal) poses.push_back(i);
  }
  if (!labelled && poses.size() >= 2) {
    std::erase_if(groups, [&](const auto& g) { return std::find(poses.begin(), poses.end(), g.second.front()) != poses.end(); });
    groups.insert(groups.begin(), {"poses", poses});
    std::vector<std::string> names;
    for (std::size_t i : poses) names.push_back(cases[i].name);
    note(fmt::format("inferred: the {} static poses ({}) share one mounting 'poses' (the sensor stays in its fixture, "
                     "which is turned between them); give each case a `mounting` label in dataset.toml to say otherwise",
                     poses.size(), fmt::join(names, ", ")));
  }
  return groups;
}

MountingGroups mountings_of(const dataset::Dataset& data, std::vector<std::string>* notes) {
  std::vector<MountingKey> keys;
  for (const dataset::CaseData& c : data.cases) keys.push_back({c.plan_case(), c.mounting, c.kind});
  return group_mountings(keys, data.sensor, notes);
}

MountingResult estimate_mounting(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                                 const std::string& mounting, const PipelineOptions& options,
                                 std::string_view dataset_label, std::optional<double> known_bias) {
  MountingResult result;
  result.mounting = mounting;
  result.cases = cases;
  const MountingCases m = mounting_cases(data, cases, options, known_bias);
  result.known_bias = known_bias;
  const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;

  // What this mounting's inputs can determine; an axis without its own excitation keeps the
  // nominal case frame (excitation.hpp).
  result.excitation = axis_excitation(input_gram(m.cases, data.sensor), !known_bias.has_value());
  result.held = held_angle_notes(result.excitation, gyro, !known_bias.has_value());
  if (!result.excitation.aligns()) {
    // Nothing to align: both angles are held (algorithm 2 would only fit the scale factor).
    result.aligned = false;
    result.angles(0) = std::nan("");
    result.angles_sd(0) = std::nan("");
    result.excitation.determined[1] = result.excitation.determined[2] = false;
    return result;
  }

  // The F_E-and-F_S candidates (eq. 2), or the fixed model.
  std::vector<Term> es_terms = options.misalignment.select
                                   ? ident::candidate_terms(data.sensor, ident::ModelFrame::ExternalAndSensor,
                                                            with_measured_temperature(options.misalignment.candidates, data, options))
                                   : parse_fixed(options.misalignment.fixed_terms, "misalignment");
  for (const Term& t : es_terms) {
    if (ieee_1293_excluded(t, m.kind, known_bias.has_value(), options.ieee_1293)) result.excluded.push_back(t.to_string());
  }
  std::erase_if(es_terms, [&](const Term& t) { return ieee_1293_excluded(t, m.kind, known_bias.has_value(), options.ieee_1293); });
  {
    const std::array<const char*, 3> names = sensitivity_names(data.sensor);
    for (int axis = 1; axis < 3; ++axis) {
      if (!result.excitation.determined[static_cast<std::size_t>(axis)])
        std::erase(es_terms, ident::parse_term(names[static_cast<std::size_t>(axis)]));
    }
  }
  const std::array<bool, 2> tilt_axes{result.excitation.determined[1], result.excitation.determined[2]};
  const Eigen::Index first_row = max_lag_of(es_terms);

  // Step 1 with a fixed point: the nonlinear F_S terms of eq. 2 need M_C^S, which the fit gives.
  frames::Dcm m_cs = frames::Dcm::Identity();
  StackedRegression es;
  ArWhitener whitener;
  std::optional<StaticNoiseLaw> stage_law;
  std::optional<double> square_corner;
  double twist = 0.0;
  const bool twist_matters = uses_cross_axes(es_terms);
  std::vector<Eigen::Index> usable;
  Eigen::Vector3d full_sensitivities = Eigen::Vector3d::Zero();
  Eigen::Matrix3d full_sensitivity_covariance = Eigen::Matrix3d::Zero();
  for (result.refinements = 0; result.refinements < std::max(1, options.max_refinements); ++result.refinements) {
    es = stack_regressions(es_terms, stack_inputs(m, cases, m_cs), data.t_ref, dataset_label, first_row);
    std::optional<StackedRegression> unfiltered;   // for the corner's search after the whitening (batch's note)
    if (options.square_highpass) {
      const std::vector<Eigen::Index> squares = square_columns(es.labels);
      if (!squares.empty() && result.refinements < 2) {   // the corner hardly moves with M_C^S after that
        unfiltered = es;
        const SquareCornerSearch search(es, squares, data);
        square_corner = search.best(options.square_highpass_min_rad_s,
                                    std::min(options.square_highpass_max_rad_s, max_corner(es.cases, data)));
      }
      apply_square_model(es, data, square_corner);
    }
    // Columns the data cannot separate from the others are left out, named in the result.
    usable = identifiable_ranking(es, options.selection.err);
    ident::UlsOptions uls = options.selection.uls;
    uls.noise_lags = 0;
    std::vector<std::string> dropped;
    const ident::UlsResult ols = fit_identifiable(es, usable, uls, dropped);
    whitener = ArWhitener::fit(ols.residuals, es.cases, options.whitening_max_order);
    stage_law = static_noise_law(ols.residuals, es.cases, data);
    if (unfiltered) {
      square_corner = whitened_corner(*unfiltered, whitener, data, options);
      es = std::move(*unfiltered);
      apply_square_model(es, data, square_corner);
    }
    whitener.apply(es);
    const ident::UlsResult full = fit_identifiable(es, usable, uls, dropped);
    const auto theta = external_sensitivities(full.labels, full.theta, data.sensor, &full.covariance, &full_sensitivity_covariance);
    if (!theta) {
      throw std::runtime_error(fmt::format("mounting '{}': the model has no {} sensitivity", mounting,
                                           fmt::join(sensitivity_names(data.sensor), ", ")));
    }
    full_sensitivities = *theta;
    const frames::Dcm aligned = misalignment_from_sensitivities(*theta, frames::Dcm::Identity());
    if (options.estimate_twist && twist_matters) {
      // One parabolic step on the residual sum of squares as a function of the twist.
      const auto rss_at = [&](double psi) {
        // Whitened: the GLS criterion; unwhitened, the 1/f noise the columns can fit decides.
        const StackedRegression t = whitened_regression(es_terms, m, cases, with_twist(aligned, psi), data, dataset_label,
                                                        first_row, square_corner, whitener);
        return SquareCornerSearch(t, {}, data).rss(std::nullopt);
      };
      constexpr double kProbe = 0.5 * std::numbers::pi / 180.0;
      const double r0 = rss_at(twist), rm = rss_at(twist - kProbe), rp = rss_at(twist + kProbe);
      const double curvature = rp + rm - 2.0 * r0;
      if (curvature > 0.0) {
        twist += std::clamp(-kProbe * (rp - rm) / (2.0 * curvature), -4.0 * kProbe, 4.0 * kProbe);
      } else {
        twist += rp < rm ? 4.0 * kProbe : (rm < rp ? -4.0 * kProbe : 0.0);
      }
    }
    const frames::Dcm next = with_twist(aligned, twist);
    const double change = frames::angle_between(next, m_cs);
    m_cs = next;
    if (change < 1e-10) break;
  }
  result.whitening_order = whitener.order();
  result.square_corner_rad_s = square_corner;
  result.twist_rad = twist;
  for (Eigen::Index j = 0; j < es.phi.cols(); ++j) {
    if (std::find(usable.begin(), usable.end(), j) == usable.end()) result.excluded.push_back(es.labels[static_cast<std::size_t>(j)]);
  }

  if (!options.misalignment.select) {
    // A fixed model: its misalignment is the fixed point above; its F_S fit for the record.
    result.m_cs = m_cs;
    result.es_terms = ident::to_strings(es_terms);
    const std::vector<Term> s_terms = ident::to_sensor_frame(es_terms);
    StackedRegression s =
        whitened_regression(s_terms, m, cases, m_cs, data, dataset_label, first_row, square_corner, whitener);
    std::vector<Eigen::Index> columns = identifiable_ranking(s, options.selection.err);
    result.s_fit = fit_identifiable(s, columns, options.selection.uls, result.excluded);
    result.s_terms = s.labels;
    result.candidates_tried = 1;
    set_angles(result, misalignment_angles(full_sensitivities, full_sensitivity_covariance).sd);
    return result;
  }

  // Steps 2-15 on the converged F_E problem.
  MisalignmentHook hook(m, cases, es_terms, data, dataset_label, first_row, whitener, square_corner, twist, tilt_axes);
  ident::SelectionProblem problem{es.phi, es.y, es.labels, es.rational, {}};
  ident::SelectionOptions selection = options.selection;
  selection.uls.noise_lags = 0;
  problem.ranking = usable;   // identifiable columns in ERR order, sensitivities first
  const ident::SelectionResult selected = ident::select_model(problem, selection, &hook);
  const ident::CandidateModel& best = selected.best_model();
  result.candidates_tried = selected.candidates.size();
  result.fitness = best.fitness;
  const auto best_misalignment = hook.misalignment(best.ranked_terms);
  if (!best.transformed || !best_misalignment) {
    throw std::runtime_error(fmt::format("mounting '{}': the selected model has no {} sensitivity", mounting,
                                         fmt::join(sensitivity_names(data.sensor), ", ")));
  }
  result.m_cs = *best_misalignment;
  for (std::size_t i = 0; i < best.ranked_terms; ++i) {
    result.es_terms.push_back(es.labels[static_cast<std::size_t>(selected.ranking[i])]);
  }
  // The kept tilt corrects M_E^S (algorithm 1 on the model's sensitivities theta_i n_i + theta_p
  // n_p + theta_o n_o), and the selected terms are fitted without it on the F_S regression built
  // with the corrected M_E^S.
  const std::vector<std::string> tilts = hook.tilts(best.ranked_terms);
  result.s_fit = best.fit;
  {
    // Honest inference on the selected model (as the batch's, run_pipeline): offsets between the
    // mounting's phases (a pose's placement) are not information about its terms.
    std::vector<Term> selected_terms;
    for (const std::string& label : best.fit.labels) selected_terms.push_back(ident::parse_term(label));
    const StackedRegression stage = whitened_regression(selected_terms, m, cases, *best_misalignment, data, dataset_label,
                                                        first_row, square_corner, whitener);
    std::vector<CaseOutcome> outcomes(data.cases.size());
    for (std::size_t index : cases) outcomes[index].m_es = *best_misalignment * data.cases[index].m_ec;
    const std::vector<int> clusters = phase_clusters(stage, data);
    const Eigen::VectorXd loading = cross_axis_loading(stage, selected_terms, data, outcomes, whitener, dataset_label);
    HonestPrune honest;
    honest.s = &stage;
    honest.clusters = &clusters;
    const std::vector<CaseRows> noise_runs = plan_case_rows(stage, data);
    honest.noise_runs = &noise_runs;
    honest.loading = &loading;
    honest.threshold = options.selection.alpha / static_cast<double>(std::max<std::size_t>(1, selected.ranking.size()));
    honest.protect = [&](const std::string& label) {
      return ident::is_sensitivity_label(label) || label == "1" || std::find(tilts.begin(), tilts.end(), label) != tilts.end();
    };
    if (stage_law) honest.below_record = stage_law->below_record(whitener);
    if (square_corner) {
      honest.searched = [&](const ident::UlsResult& fit) {
        if (!has_square(fit)) return Eigen::MatrixXd();
        // The columns are smooth in the corner: 1 % keeps the difference far above rounding.
        return Eigen::MatrixXd(prediction_derivative(fit, 1e-2 * *square_corner, [&](std::span<const Term> terms, double moved) {
          return whitened_regression(terms, m, cases, *best_misalignment, data, dataset_label, first_row, *square_corner + moved,
                                     whitener);
        }));
      };
    }
    std::vector<Eigen::Index> columns(selected_terms.size());
    for (std::size_t i = 0; i < columns.size(); ++i) columns[i] = static_cast<Eigen::Index>(i);
    result.s_fit = fit_identifiable(stage, columns, options.selection.uls, result.excluded);
    const HonestResult inference = honest_prune(honest, columns, result.s_fit, options.selection.uls, &result.pruned, "mounting's model");
    // The angles' test dof: the tilts' (between the mounting's phases when their offsets dominate).
    for (Eigen::Index j = 0; j < inference.dof.size(); ++j) {
      const std::string& label = result.s_fit.labels[static_cast<std::size_t>(j)];
      if (std::find(tilts.begin(), tilts.end(), label) != tilts.end()) result.angles_dof = std::min(result.angles_dof, inference.dof(j));
    }
  }
  const ident::UlsResult selected_fit = result.s_fit;
  {
    // The angles' sd: the kept tilts' in the selected model (the tilt of n_i toward p and o, over
    // theta_i), by the delta method through algorithm 1.
    const std::string axes[3] = {gyro ? "w_i" : "a_i", gyro ? "w_p" : "a_p", gyro ? "w_o" : "a_o"};
    Eigen::Vector3d theta = Eigen::Vector3d::Zero();
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    std::array<Eigen::Index, 3> at{-1, -1, -1};
    for (std::size_t i = 0; i < selected_fit.labels.size(); ++i)
      for (std::size_t a = 0; a < 3; ++a)
        if (selected_fit.labels[i] == axes[a]) at[a] = static_cast<Eigen::Index>(i);
    for (std::size_t a = 0; a < 3; ++a) {
      if (at[a] < 0) continue;
      theta(Eigen::Index(a)) = selected_fit.theta(at[a]);
      for (std::size_t b = 0; b < 3; ++b)
        if (at[b] >= 0) covariance(Eigen::Index(a), Eigen::Index(b)) = selected_fit.covariance(at[a], at[b]);
    }
    if (theta(0) != 0.0) set_angles(result, misalignment_angles(theta, covariance).sd);
  }
  if (!tilts.empty()) {
    const std::string axes[3] = {gyro ? "w_i" : "a_i", gyro ? "w_p" : "a_p", gyro ? "w_o" : "a_o"};
    Eigen::Vector3d theta = Eigen::Vector3d::Zero();   // theta_i, theta_p, theta_o
    std::vector<Term> s_terms;
    for (std::size_t i = 0; i < selected_fit.labels.size(); ++i) {
      const std::string& label = selected_fit.labels[i];
      for (int a = 0; a < 3; ++a) {
        if (label == axes[a]) theta(a) = selected_fit.theta(static_cast<Eigen::Index>(i));
      }
      if (std::find(tilts.begin(), tilts.end(), label) == tilts.end()) s_terms.push_back(ident::parse_term(label));
    }
    if (theta(0) != 0.0) {
      result.m_cs = with_twist(misalignment_from_sensitivities(result.m_cs.transpose() * theta, frames::Dcm::Identity()), twist);
      set_angles(result, result.angles_sd);
    }
    StackedRegression s =
        whitened_regression(s_terms, m, cases, result.m_cs, data, dataset_label, first_row, square_corner, whitener);
    std::vector<Eigen::Index> columns(s_terms.size());
    for (std::size_t i = 0; i < columns.size(); ++i) columns[i] = static_cast<Eigen::Index>(i);
    result.s_fit = fit_identifiable(s, columns, options.selection.uls, result.excluded);
  }
  result.s_terms = result.s_fit.labels;
  return result;
}

double case_weight(const PipelineOptions& options, const dataset::CaseData& c) {
  for (const auto& [key, weight] : options.case_weights)
    if (key == c.plan_case()) return weight;
  return 1.0;
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

PipelineResult run_pipeline(const dataset::Dataset& data, const PipelineOptions& options,
                            std::string_view dataset_label) {
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
  PipelineResult result;
  result.cases.resize(data.cases.size());

  // Blocks 5-6, in the order and with the bias the mounting rules give (mounting_rules.hpp).
  const MountingGroups groups = mountings_of(data, &result.notes);
  std::vector<MountingKind> kinds(groups.size());
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (std::size_t index : groups[g].second) kinds[g].add_case(data.cases[index].kind);
  std::optional<double> bias;
  for (const std::size_t g : mounting_order(kinds)) {
    const auto& [mounting, cases] = groups[g];
    MountingResult m = estimate_mounting(data, cases, mounting, options, dataset_label,
                                         takes_bias(kinds[g], options.ieee_1293) ? bias : std::nullopt);
    if (!bias && hands_on_bias(kinds[g])) {
      for (std::size_t j = 0; j < m.s_fit.labels.size(); ++j) {
        if (m.s_fit.labels[j] == "1") bias = m.s_fit.theta(static_cast<Eigen::Index>(j));
      }
    }
    for (std::size_t index : cases) {
      result.cases[index].case_index = index;
      result.cases[index].m_es = m.m_cs * data.cases[index].m_ec;   // M_E^S = M_C^S M_E^C
    }
    result.mountings.push_back(std::move(m));
  }
  result.m_cs = result.mountings.front().m_cs;
  for (const MountingResult& m : result.mountings) {
    if (m.aligned) {
      result.m_cs = m.m_cs;   // the model file's M_C^S: the first mounting the data aligned
      break;
    }
  }

  // Blocks 7-9.
  if (options.temperature_when_measured) {
    const double span = temperature_span(data);
    if (std::isfinite(span) && span < kMinTemperatureSpanC) {
      result.notes.push_back(fmt::format("temperature terms not determined by this plan: the fixture temperature spans "
                                         "{:.3f} degC (at least {:.0f} degC needed; a thermal_step phase gives it)",
                                         span, kMinTemperatureSpanC));
    }
  }
  std::vector<Term> candidates;
  if (options.batch.select) {
    candidates = ident::candidate_terms(data.sensor, ident::ModelFrame::Sensor,
                                        with_measured_temperature(options.batch.candidates, data, options));
  } else {
    candidates = parse_fixed(options.batch.fixed_terms, "batch");
  }
  // Held angles (excitation.hpp) stay at the nominal frame; after the selection their tolerance
  // is propagated into the coefficients' covariance (below).
  const std::vector<HeldColumn> held = held_columns(result.mountings);
  const std::vector<Eigen::Vector3d> nominal(result.mountings.size(), Eigen::Vector3d::Zero());
  StackedRegression batch = stack_regressions(candidates, batch_inputs(data, options, result.mountings, nominal, result.cases),
                                              data.t_ref, dataset_label);
  std::optional<StackedRegression> unfiltered;   // for the corner's search after the whitening
  if (options.square_highpass && options.batch_square_highpass) {
    // The squares' high pass (eq. 12), its corner estimated on the whole batch as in blocks 5-6:
    // first on the unwhitened rows (the whitening's residual needs a corner), then whitened.
    const std::vector<Eigen::Index> squares = square_columns(batch.labels);
    if (!squares.empty()) {
      unfiltered = batch;
      const SquareCornerSearch search(batch, squares, data);
      result.square_corner_rad_s = search.best(options.square_highpass_min_rad_s,
                                               std::min(options.square_highpass_max_rad_s, max_corner(batch.cases, data)));
      apply_square_model(batch, data, result.square_corner_rad_s);
    }
  }
  ArWhitener whitener;
  std::optional<StaticNoiseLaw> batch_law;
  {
    // The noise model from the residuals of the full candidate set (dependent columns left out).
    std::vector<Eigen::Index> usable = identifiable_ranking(batch, options.selection.err);
    ident::UlsOptions uls = options.selection.uls;
    uls.noise_lags = 0;
    std::vector<std::string> dropped;
    const ident::UlsResult ols = fit_identifiable(batch, usable, uls, dropped);
    whitener = ArWhitener::fit(ols.residuals, batch.cases, options.whitening_max_order);
    batch_law = static_noise_law(ols.residuals, batch.cases, data);
    if (unfiltered) {
      result.square_corner_rad_s = whitened_corner(*unfiltered, whitener, data, options);
      batch = std::move(*unfiltered);
      apply_square_model(batch, data, result.square_corner_rad_s);
    }
    whitener.apply(batch);
    result.whitening = whitener.coefficients();
  }
  // The batch's whitened regression of `terms` with each mounting turned by `tilts` and the squares
  // through `corner`: what the searched parameters' derivatives and the held angles' refits rebuild.
  const auto batch_at = [&](std::span<const Term> terms, const std::vector<Eigen::Vector3d>& tilts,
                            std::optional<double> corner) {
    std::vector<CaseOutcome> cases = result.cases;
    StackedRegression st = stack_regressions(terms, batch_inputs(data, options, result.mountings, tilts, cases), data.t_ref,
                                             dataset_label, ident::first_usable_row(candidates));
    apply_square_model(st, data, corner);
    whitener.apply(st);
    return st;
  };
  const RelativeTwists twists = relative_twists(batch, batch_at, candidates, data, options, result);
  for (const CaseRows& rows : batch.cases) {
    CaseOutcome& c = result.cases[rows.case_index];
    c.first_row = rows.first_sample;
    c.begin = rows.begin;
    c.rows = rows.rows;
  }

  // Block 10 or 11.
  ident::UlsOptions uls = options.selection.uls;
  uls.noise_lags = options.batch.noise_lags;
  std::vector<Eigen::Index> columns;
  const std::vector<Eigen::Index> ranking = identifiable_ranking(batch, options.selection.err);
  for (Eigen::Index j = 0; j < batch.phi.cols(); ++j) {
    if (std::find(ranking.begin(), ranking.end(), j) == ranking.end()) {
      result.undetermined.push_back({batch.labels[static_cast<std::size_t>(j)], why_not_determined(batch, j, ranking)});
    }
  }
  if (options.batch.select) {
    ident::SelectionOptions selection = options.selection;
    selection.uls.noise_lags = 0;   // structure first; the noise model joins the final fit
    ident::SelectionProblem problem{batch.phi, batch.y, batch.labels, batch.rational, ranking};
    // Every inertial sensor has a bias and a scale factor: the t-test of step 9 weighs the other
    // terms against them, never them against a candidate. Pruning the weaker of a near-collinear
    // pair first, it took the bias out of sim-gyro-thermal's model (seed 116: t 0.9 beside a_p's
    // 1.3, with the bias's 2e-6 rad/s in the p axis' mean specific force) and named a_p at t 7.8.
    const char own = data.sensor == dataset::SensorKind::Gyroscope ? 'w' : 'a';   // a gyro's a_i is a g-sensitivity
    for (const Eigen::Index j : ranking) {
      const std::string& label = batch.labels[static_cast<std::size_t>(j)];
      if (label == "1" || (ident::is_sensitivity_label(label) && label.front() == own)) problem.kept.push_back(j);
    }
    const ident::SelectionResult selected = ident::select_model(problem, selection, nullptr);
    columns = selected.best_model().columns;
  } else {
    columns = ranking;
  }
  std::vector<std::string> dropped;
  result.fit = fit_identifiable(batch, columns, uls, dropped);
  // Honest inference on the selected model (the selection's t-tests take every sample as
  // independent): (1) the cluster jackknife covariance over the cases' contiguous phases, where
  // it is larger (coloured residual within a phase, offsets between phases and cases, a model
  // error that repeats per phase, a term only a few phases carry), with Student's t on G - 1 dof; (2) each held angle turned by the
  // mounting tolerance moves the coefficients by d (the exact refit, nonlinear terms included),
  // and the covariance gains d d'. A term whose t then falls below the selection's level is not
  // determined by this plan: it leaves and the rest is refitted.
  const std::vector<int> clusters = phase_clusters(batch, data);
  const Eigen::VectorXd loading = cross_axis_loading(batch, candidates, data, result.cases, whitener, dataset_label);
  HonestPrune honest;
  honest.s = &batch;
  honest.clusters = &clusters;
  const std::vector<CaseRows> noise_runs = plan_case_rows(batch, data);
  honest.noise_runs = &noise_runs;
  honest.loading = &loading;
  honest.threshold = options.selection.alpha / static_cast<double>(std::max<std::size_t>(1, ranking.size()));
  honest.may_remove = options.batch.select;
  honest.protect = [](const std::string& label) { return ident::is_sensitivity_label(label) || label == "1"; };
  if (batch_law) honest.below_record = batch_law->below_record(whitener);
  // The searches whose results the batch's columns are built with: the squares' corner and each
  // mounting's determined angles (blocks 5-6, on the same samples). They join the Jacobian, so the
  // between-phase dof no longer count the angles separately.
  struct Searched {
    std::size_t mounting = 0;
    int axis = 0;   // 0: the squares' corner; 1, 2, 3: the mounting's turn (turned(): tilts, twist)
  };
  std::vector<Searched> searches;
  if (result.square_corner_rad_s) searches.push_back({0, 0});
  for (std::size_t k = 0; k < result.mountings.size(); ++k)
    for (int axis = 1; axis < 3; ++axis)
      if (result.mountings[k].excitation.determined[static_cast<std::size_t>(axis)]) searches.push_back({k, axis});
  for (std::size_t k : twists.estimated) searches.push_back({k, 3});
  std::vector<std::size_t> searched_columns;   // of the last call: the searches its columns are
  honest.searched = [&](const ident::UlsResult& fit) {
    Eigen::MatrixXd columns(batch.phi.rows(), 0);
    searched_columns.clear();
    for (std::size_t i = 0; i < searches.size(); ++i) {
      const Searched& search = searches[i];
      if (search.axis == 0 && !has_square(fit)) continue;
      const auto stack_at = [&](std::span<const Term> terms, double moved) {
        std::vector<Eigen::Vector3d> tilts = nominal;
        if (search.axis > 0) tilts[search.mounting](search.axis - 1) = moved;
        return batch_at(terms, tilts, search.axis == 0 ? *result.square_corner_rad_s + moved : result.square_corner_rad_s);
      };
      // Steps: 1 % of the corner; 1e-4 rad of a turn (the columns are smooth in both).
      const double step = search.axis == 0 ? 1e-2 * *result.square_corner_rad_s : 1e-4;
      columns.conservativeResize(Eigen::NoChange, columns.cols() + 1);
      columns.col(columns.cols() - 1) = prediction_derivative(fit, step, stack_at);
      searched_columns.push_back(i);
    }
    return columns;
  };
  // Held angles and held twists: each turned by the tolerance moves the coefficients by d.
  std::vector<HeldColumn> held_turns = held;
  for (std::size_t k : twists.held) held_turns.push_back({k, 3});
  Eigen::MatrixXd held_part;   // of the last call: what the held turns added
  if (!held_turns.empty() && options.mounting_tolerance_rad > 0.0) {
    honest.extra = [&](const ident::UlsResult& fit, Eigen::MatrixXd& covariance) {
      held_part = Eigen::MatrixXd::Zero(covariance.rows(), covariance.cols());
      const Eigen::Index p = fit.process_terms;
      std::vector<Term> terms;
      for (Eigen::Index j = 0; j < p; ++j) terms.push_back(ident::parse_term(fit.labels[std::size_t(j)]));
      for (const HeldColumn& h : held_turns) {
        std::vector<Eigen::Vector3d> tilts = nominal;
        tilts[h.mounting](h.axis - 1) = options.mounting_tolerance_rad;
        const StackedRegression s = batch_at(terms, tilts, result.square_corner_rad_s);
        std::vector<Eigen::Index> all(terms.size());
        for (std::size_t j = 0; j < all.size(); ++j) all[j] = static_cast<Eigen::Index>(j);
        const ident::UlsResult moved = ident::uls_batch(s.phi, s.y, s.labels, s.rational, uls, all);
        const Eigen::VectorXd d = moved.theta.head(p) - fit.theta.head(p);
        held_part += d * d.transpose();
      }
      covariance += held_part;
    };
  }
  HonestResult inference = honest_prune(honest, columns, result.fit, uls, &result.undetermined, "batch model");
  if (!held.empty() && options.batch.select) {
    // Held angles leave the model in a frame that is not the sensor's. A turn within the tolerance
    // is allowed for above; a misfit the model cannot absorb shows as an innovation that still
    // follows the sensitive input. Then the frame-dependent terms (everything but the bias, the
    // scale factor and temperature terms) are not determined by this plan: they leave.
    const auto input_column = std::find_if(batch.labels.begin(), batch.labels.end(),
                                           [](const std::string& l) { return l == "a_i" || l == "w_i"; });
    const bool none_aligned =
        std::none_of(result.mountings.begin(), result.mountings.end(), [](const MountingResult& m) { return m.aligned; });
    if (input_column != batch.labels.end() && batch.phi.rows() == result.fit.residuals.size()) {
      const ident::CorrelationCheck check = ident::residual_input_correlation(
          result.fit.residuals, batch.phi.col(input_column - batch.labels.begin()), 20);
      if (!check.pass || none_aligned) {
        // Linear in the sensitive input (times temperature, output or lags) holds in any frame near
        // the sensor's; squares, |a_i|, sign and the cross-axis inputs do not.
        std::vector<Eigen::Index> kept;
        for (Eigen::Index c : columns) {
          const std::string& label = batch.labels[static_cast<std::size_t>(c)];
          if (frame_free(ident::parse_term(label))) {
            kept.push_back(c);
          } else {
            result.undetermined.push_back(
                {label, none_aligned
                            ? std::string("not determined by this plan: no mounting is aligned, so the sensor frame's p and o "
                                          "axes are not known in any case and a term that depends on them has no frame; an "
                                          "aligned mounting (a table or tumble case, or one mounting label shared by the "
                                          "shaker orientations) determines them")
                            : fmt::format("not determined by this plan: the held mounting angles leave a misfit the model "
                                          "cannot absorb (the innovation still follows the sensitive input: {} of {} lags "
                                          "outside the 95 % band), so the terms that depend on the sensor frame's p and o "
                                          "axes are not known; an aligned mounting determines them",
                                          check.outside, check.lags.size())});
          }
        }
        if (kept.size() < columns.size()) {
          columns = kept;
          result.fit = fit_identifiable(batch, columns, uls, dropped);
          honest.may_remove = false;
          inference = honest_prune(honest, columns, result.fit, uls, nullptr, "batch model");
        }
      }
    }
  }
  result.inference = inference.offsets;
  result.test_dof = inference.dof;
  result.held_sd = held_part.rows() == result.fit.process_terms ? Eigen::VectorXd(held_part.diagonal().cwiseMax(0.0).cwiseSqrt())
                                                                  : Eigen::VectorXd::Zero(result.fit.process_terms);
  // The angles the batch refined (relative_twists) get their sd from its joint covariance.
  for (std::size_t c = 0; c < searched_columns.size() && static_cast<Eigen::Index>(c) < inference.searched_covariance.rows(); ++c) {
    const Searched& search = searches[searched_columns[c]];
    if (search.axis == 0 || std::find(twists.estimated.begin(), twists.estimated.end(), search.mounting) == twists.estimated.end())
      continue;
    const auto i = static_cast<Eigen::Index>(c);
    result.mountings[search.mounting].angles_sd(angle_of_turn(search.axis - 1)) =
        std::sqrt(std::max(0.0, inference.searched_covariance(i, i)));
  }
  for (std::size_t k : twists.estimated) {
    const MountingResult& m = result.mountings[k];
    result.notes.push_back(fmt::format("mounting '{}' is turned {:+.4f} +- {:.4f} deg about n_i against '{}' (found in the batch, "
                                       "with its tilts: one set of cross-axis terms holds in both; the sensor's p and o axes "
                                       "are those of '{}''s nominal frame, as algorithm 1 takes them)",
                                       m.mounting, rad_to_deg(m.angles(0)), rad_to_deg(m.angles_sd(0)), m.twist_reference,
                                       m.twist_reference));
  }
  if (!held_turns.empty() && options.mounting_tolerance_rad > 0.0) {
    result.notes.push_back(fmt::format("{} mounting angle(s) held at the nominal case frame; each is assumed within "
                                       "+-{:.2f} deg (--mounting-tolerance-deg), and what that moves is in the sd",
                                       held_turns.size(), rad_to_deg(options.mounting_tolerance_rad)));
  }
  for (const std::string& label : result.fit.labels) {
    if (result.terms.size() < static_cast<std::size_t>(result.fit.process_terms)) result.terms.push_back(ident::parse_term(label));
  }
  result.t_test = ident::parameter_t_test(result.fit.process_theta(), result.fit.std_dev.head(result.fit.process_terms),
                                          result.fit.residuals.size());
  for (Eigen::Index j = 0; j < result.t_test.p_value.size() && j < result.test_dof.size(); ++j) {
    result.t_test.p_value(j) = ident::student_t_two_sided_p(result.t_test.t(j), result.test_dof(j));
  }
  result.residual_mean = ident::residual_mean_test(result.fit.residuals);
  result.aic = ident::aic(result.fit.residuals, result.fit.theta.size());
  return result;
}

}  // namespace inertia::procedure
