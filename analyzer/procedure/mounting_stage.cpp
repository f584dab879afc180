#include "analyzer/procedure/mounting_stage.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <utility>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/row_products.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/procedure/corner_search.hpp"
#include "analyzer/procedure/identifiable_fit.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/mounting_regressions.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "analyzer/procedure/mountings.hpp"
#include "analyzer/procedure/placement.hpp"
#include "analyzer/procedure/plan_validation.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/whitened_problem.hpp"
#include "common/parallel.hpp"

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

/// Gram matrix of [IRA XRA YRA 1] over a mounting's rows in its nominal case frame (specific
/// force, or rate for a gyroscope; a case without rates has none): what excitation.hpp judges.
Eigen::Matrix4d input_gram(const MountingCases& m, dataset::SensorKind sensor) {
  Eigen::Matrix4d g = Eigen::Matrix4d::Zero();
  for (const dataset::CaseData* c : m.cases) g += case_input_gram(*c, sensor);
  return g;
}

/// Each case's placement as placement.hpp reads it: its inputs' Gram, its stated sd, and its
/// clusters in the inference (its contiguous phases).
std::vector<CasePlacement> placements_of(const MountingCases& m, dataset::SensorKind sensor) {
  std::vector<CasePlacement> out;
  for (const dataset::CaseData* c : m.cases) out.push_back({case_input_gram(*c, sensor), c->placement_sd_rad});
  return out;
}

int max_lag_of(const std::vector<Term>& terms) {
  int lag = 0;
  for (const Term& t : terms) lag = std::max(lag, t.max_lag());
  return lag;
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

/// The sd of the bias of the mounting's selected model (its honest inference), which a mounting
/// taking the bias receives with it (pipeline.cpp).
void record_bias_sd(MountingResult& result, const ident::UlsResult& fit) {
  for (std::size_t j = 0; j < fit.labels.size(); ++j)
    if (fit.labels[j] == "1" && fit.std_dev.size() > static_cast<Eigen::Index>(j)) result.bias_sd = fit.std_dev(static_cast<Eigen::Index>(j));
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
  MisalignmentHook(const MountingRegressions& regressions, const dataset::Dataset& data, double twist,
                   std::array<bool, 2> tilt_axes)
      : regressions_(regressions), data_(data), twist_(twist), tilt_axes_(tilt_axes) {}

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
    std::vector<Term> s_terms = ident::to_sensor_frame(ident::parse_terms(ranked_fit.process_labels()));
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
    stage.phi.resize(0, 0);   // the stage before's rows: freed before this one's are built
    stage.y.resize(0);
    // The stage's normal equations and residuals from the whitened monomials where its terms
    // allow (no copy of its rows), else its rows.
    if (std::optional<RegressionSums> sums = regressions_.sums(s_terms, m_cs)) {
      stage.labels = sums->equations.labels();
      stage.rational = {};
      stage.equations = std::move(sums->equations);
      stage.residuals = std::move(sums->residuals);
      return true;
    }
    stage.equations.reset();
    stage.residuals = nullptr;
    StackedRegression s = regressions_.whitened(s_terms, m_cs);
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
  const MountingRegressions& regressions_;
  const dataset::Dataset& data_;
  double twist_;
  std::array<bool, 2> tilt_axes_;
  std::vector<std::optional<frames::Dcm>> misalignments_;
  std::vector<std::vector<std::string>> tilts_;
};

/// The F_S sensitivities theta_i, theta_p, theta_o of a fit (w_ for a gyroscope; zero where a
/// term is absent), and their covariance when asked.
Eigen::Vector3d sensor_frame_sensitivities(const ident::UlsResult& fit, dataset::SensorKind sensor,
                                           Eigen::Matrix3d* covariance = nullptr) {
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  const std::array<const char*, 3> axes{gyro ? "w_i" : "a_i", gyro ? "w_p" : "a_p", gyro ? "w_o" : "a_o"};
  Eigen::Vector3d theta = Eigen::Vector3d::Zero();
  std::array<Eigen::Index, 3> at{-1, -1, -1};
  for (std::size_t i = 0; i < fit.labels.size(); ++i)
    for (std::size_t a = 0; a < 3; ++a)
      if (fit.labels[i] == axes[a]) at[a] = static_cast<Eigen::Index>(i);
  for (std::size_t a = 0; a < 3; ++a) {
    if (at[a] < 0) continue;
    theta(Eigen::Index(a)) = fit.theta(at[a]);
    if (covariance == nullptr) continue;
    for (std::size_t b = 0; b < 3; ++b)
      if (at[b] >= 0) (*covariance)(Eigen::Index(a), Eigen::Index(b)) = fit.covariance(at[a], at[b]);
  }
  return theta;
}

/// What the bias another mounting handed over (sd `sd`, output unit) adds to the covariance of the
/// sensitivities the angles are read from, of a fit on `terms` at `m_cs`: the output less b + delta
/// moves the coefficients by -delta (X'X)^-1 X'w, w the whitened constant (exact for least
/// squares: the fit is linear in the output). `sensitivities` picks the three from labels and
/// values: (theta_x, theta_y, theta_z) of the F_E fit, or (theta_i, theta_p, theta_o) of the F_S one.
/// Where the mounting reads a tilt from gravity at rest, the bias it was given is part of what it reads.
Eigen::Matrix3d handed_bias_covariance(const MountingRegressions& regressions, std::vector<Term> terms, const frames::Dcm& m_cs,
                                       double sd,
                                       const std::function<Eigen::Vector3d(const std::vector<std::string>&, const Eigen::VectorXd&)>& sensitivities) {
  if (!(sd > 0.0) || terms.empty()) return Eigen::Matrix3d::Zero();
  const auto p = static_cast<Eigen::Index>(terms.size());
  terms.emplace_back();
  const StackedRegression with_one = regressions.whitened(terms, m_cs);
  const Eigen::MatrixXd g = ident::gram(with_one.phi);
  const Eigen::VectorXd d = g.topLeftCorner(p, p).ldlt().solve(g.col(p).head(p));
  const Eigen::Vector3d moved = sensitivities(std::vector<std::string>(with_one.labels.begin(), with_one.labels.begin() + p), d);
  return sd * sd * moved * moved.transpose();
}

/// Algorithm 2's F_E problem at the fixed point of step 1: the nonlinear F_S terms of eq. 2 need
/// M_C^S, which the fit of the full candidate set gives, so the problem is rebuilt with each new
/// M_C^S until it stops moving. With PipelineOptions::estimate_twist, each pass also takes one
/// parabolic step on the twist about n_i.
struct MisalignmentFixedPoint {
  frames::Dcm m_cs = frames::Dcm::Identity();
  StackedRegression es;                     // the F_E problem, whitened
  ArWhitener whitener;
  std::optional<StaticNoiseLaw> noise_law;
  std::optional<double> square_corner;
  double twist = 0.0;
  std::vector<Eigen::Index> usable;         // identifiable columns of es in ERR order
  Eigen::Vector3d sensitivities = Eigen::Vector3d::Zero();   // theta_x..z of the full candidate set
  Eigen::Matrix3d sensitivity_covariance = Eigen::Matrix3d::Zero();
  int refinements = 0;
};

/// The fixed point stops once a pass moves M_C^S by less than this fraction of the angles' sd (the
/// full candidate set's): each pass shrinks the step by orders of magnitude, so the passes after it
/// would move the result far below what the data tell. Never below 1e-10 rad (rounding).
constexpr double kFixedPointShareOfSd = 1e-3;

double fixed_point_tolerance(const MisalignmentFixedPoint& f) {
  const Eigen::Vector3d sd = misalignment_angles(f.sensitivities, f.sensitivity_covariance).sd;
  double smallest = std::numeric_limits<double>::infinity();
  for (int a = 1; a < 3; ++a)
    if (std::isfinite(sd(a)) && sd(a) > 0.0) smallest = std::min(smallest, sd(a));
  return std::isfinite(smallest) ? std::max(1e-10, kFixedPointShareOfSd * smallest) : 1e-10;
}

MisalignmentFixedPoint misalignment_fixed_point(const MountingCases& m, const std::vector<Term>& es_terms, Eigen::Index first_row,
                                                const dataset::Dataset& data, const PipelineOptions& options,
                                                const std::string& mounting, std::string_view dataset_label) {
  MisalignmentFixedPoint f;
  const bool twist_matters = uses_cross_axes(es_terms);
  for (f.refinements = 0; f.refinements < std::max(1, options.max_refinements); ++f.refinements) {
    // The pass before's problem is not needed for this one's: freed before this one is stacked.
    f.es = StackedRegression();
    WhitenedProblem problem =
        whiten_problem(stack_regressions(es_terms, stack_inputs(m, f.m_cs), data.t_ref, dataset_label, first_row), data,
                       whitening_options(options, options.square_highpass && corner_searched_on(f.refinements), f.square_corner));
    f.es = std::move(problem.regression);
    f.whitener = std::move(problem.whitener);
    f.noise_law = std::move(problem.noise_law);
    f.square_corner = problem.square_corner_rad_s;
    // Columns the data cannot separate from the others are left out, named in the result.
    f.usable = std::move(problem.identifiable);
    ident::UlsOptions uls = options.selection.uls;
    uls.noise_lags = 0;
    std::vector<std::string> dropped;
    const ident::UlsResult full = fit_identifiable(f.es, data.sensor, f.usable, uls, dropped);
    const auto theta = external_sensitivities(full.labels, full.theta, data.sensor, &full.covariance, &f.sensitivity_covariance);
    if (!theta) {
      throw std::runtime_error(fmt::format("mounting '{}': the model has no {} sensitivity", mounting,
                                           fmt::join(sensitivity_names(data.sensor), ", ")));
    }
    f.sensitivities = *theta;
    const frames::Dcm aligned = misalignment_from_sensitivities(*theta, frames::Dcm::Identity());
    if (options.estimate_twist && twist_matters) {
      // One parabolic step on the residual sum of squares as a function of the twist.
      const MountingRegressions regressions(m, data, dataset_label, first_row, f.square_corner, f.whitener, es_terms);
      const auto rss_at = [&](double psi) {
        // Whitened: the GLS criterion; unwhitened, the 1/f noise the columns can fit decides.
        const StackedRegression t = regressions.whitened(es_terms, with_twist(aligned, psi));
        return SquareCornerSearch(t, {}, data).rss(std::nullopt);
      };
      constexpr double kProbe = 0.5 * std::numbers::pi / 180.0;
      std::array<double, 3> probe{f.twist, f.twist - kProbe, f.twist + kProbe};   // each its own regression, side by side
      parallel::for_each_index(3, [&](long i) { probe[static_cast<std::size_t>(i)] = rss_at(probe[static_cast<std::size_t>(i)]); });
      const double r0 = probe[0], rm = probe[1], rp = probe[2];
      const double curvature = rp + rm - 2.0 * r0;
      if (curvature > 0.0) {
        f.twist += std::clamp(-kProbe * (rp - rm) / (2.0 * curvature), -4.0 * kProbe, 4.0 * kProbe);
      } else {
        f.twist += rp < rm ? 4.0 * kProbe : (rm < rp ? -4.0 * kProbe : 0.0);
      }
    }
    const frames::Dcm next = with_twist(aligned, f.twist);
    const double change = frames::angle_between(next, f.m_cs);
    f.m_cs = next;
    if (change < fixed_point_tolerance(f)) break;
  }
  return f;
}

}  // namespace

MountingResult estimate_mounting(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                                 const std::string& mounting, const PipelineOptions& options,
                                 std::string_view dataset_label, std::optional<double> known_bias, double known_bias_sd) {
  MountingResult result;
  result.mounting = mounting;
  result.cases = cases;
  const MountingCases m = mounting_cases(data, cases, options, known_bias);
  result.known_bias = known_bias;
  if (known_bias) result.known_bias_sd = known_bias_sd;
  const bool handed = known_bias && known_bias_sd > 0.0;
  const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;

  // What this mounting's inputs can determine; an axis without its own excitation keeps the
  // nominal case frame (excitation.hpp).
  result.excitation = axis_excitation(input_gram(m, data.sensor), !known_bias.has_value());
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
  std::vector<Term> es_terms = offered_terms(options.misalignment, ident::ModelFrame::ExternalAndSensor, data, options, "misalignment");
  {
    std::vector<Term> kept;
    for (Term& t : es_terms) {
      if (ieee_1293_excluded(t, m.kind, known_bias.has_value(), options.ieee_1293)) {
        result.excluded.push_back(t.to_string());
      } else {
        kept.push_back(std::move(t));
      }
    }
    es_terms = std::move(kept);
  }
  if (options.misalignment.select) {
    for (const UndeterminedTerm& u : remove_unexcited_terms(es_terms, stack_inputs(m, frames::Dcm::Identity()), data.t_ref))
      result.excluded.push_back(u.term);
  }
  {
    const std::array<const char*, 3> names = sensitivity_names(data.sensor);
    for (int axis = 1; axis < 3; ++axis) {
      if (!result.excitation.determined[static_cast<std::size_t>(axis)])
        std::erase(es_terms, ident::parse_term(names[static_cast<std::size_t>(axis)]));
    }
  }
  const std::array<bool, 2> tilt_axes{result.excitation.determined[1], result.excitation.determined[2]};
  const Eigen::Index first_row = max_lag_of(es_terms);

  // Step 1 with a fixed point.
  MisalignmentFixedPoint f = misalignment_fixed_point(m, es_terms, first_row, data, options, mounting, dataset_label);
  result.refinements = f.refinements;
  const frames::Dcm m_cs = f.m_cs;
  const StackedRegression& es = f.es;
  const ArWhitener& whitener = f.whitener;
  const std::optional<double> square_corner = f.square_corner;
  const double twist = f.twist;
  const std::vector<Eigen::Index>& usable = f.usable;
  result.whitening_order = whitener.order();
  result.square_corner_rad_s = square_corner;
  result.twist_rad = twist;
  for (Eigen::Index j = 0; j < es.phi.cols(); ++j) {
    if (std::find(usable.begin(), usable.end(), j) == usable.end()) result.excluded.push_back(es.labels[static_cast<std::size_t>(j)]);
  }
  // Every F_S regression from here on: the candidates' terms in F_S, with any M_C^S.
  const MountingRegressions regressions(m, data, dataset_label, first_row, square_corner, whitener, ident::to_sensor_frame(es_terms));

  if (!options.misalignment.select) {
    // A fixed model: its misalignment is the fixed point above; its F_S fit for the record.
    result.m_cs = m_cs;
    result.es_terms = ident::to_strings(es_terms);
    const std::vector<Term> s_terms = ident::to_sensor_frame(es_terms);
    StackedRegression s = regressions.whitened(s_terms, m_cs);
    std::vector<Eigen::Index> columns = identifiable_ranking(s, data.sensor, options.selection.err);
    result.s_fit = fit_identifiable(s, data.sensor, columns, options.selection.uls, result.excluded);
    result.s_terms = s.labels;
    result.candidates_tried = 1;
    const Eigen::Matrix3d placed = placement_covariance(f.sensitivities, placements_of(m, data.sensor), !known_bias.has_value());
    const Eigen::Matrix3d bias_part =
        handed_bias_covariance(regressions, es_terms, m_cs, handed ? known_bias_sd : 0.0, [&](const std::vector<std::string>& labels, const Eigen::VectorXd& d) {
          return external_sensitivities(labels, d, data.sensor).value_or(Eigen::Vector3d::Zero());
        });
    set_angles(result, misalignment_angles(f.sensitivities, f.sensitivity_covariance + placed + bias_part).sd);
    record_bias_sd(result, result.s_fit);
    return result;
  }

  // Steps 2-15 on the converged F_E problem.
  MisalignmentHook hook(regressions, data, twist, tilt_axes);
  ident::SelectionProblem problem{es.phi, es.y, es.labels, es.rational, {}};
  ident::SelectionOptions selection = options.selection;
  selection.uls.noise_lags = 0;
  problem.ranking = usable;   // identifiable columns in ERR order, sensitivities first
  problem.stretch_starts = stretch_starts(es.cases);
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
  // The F_E problem has done its work (the selection): every fit below is an F_S regression from
  // `regressions`, and the rows are freed before the inference's buffers are taken.
  f.es = StackedRegression();
  // The kept tilt corrects M_E^S (algorithm 1 on the model's sensitivities theta_i n_i + theta_p
  // n_p + theta_o n_o), and the selected terms are fitted without it on the F_S regression built
  // with the corrected M_E^S.
  const std::vector<std::string> tilts = hook.tilts(best.ranked_terms);
  result.s_fit = best.fit;
  {
    // Honest inference on the selected model (as the batch stage's): offsets between the
    // mounting's phases (a pose's placement) are not information about its terms.
    const std::vector<Term> selected_terms = ident::parse_terms(best.fit.process_labels());
    const StackedRegression stage = regressions.whitened(selected_terms, *best_misalignment);
    std::vector<CaseOutcome> outcomes(data.cases.size());
    for (std::size_t index : cases) outcomes[index].m_es = *best_misalignment * data.cases[index].m_ec;
    const PhaseLayout layout = phase_layout(stage, selected_terms, data, outcomes, dataset_label);
    InferenceProblem honest;
    honest.s = &stage;
    honest.layout = &layout;
    honest.threshold = ident::family_threshold(options.selection.alpha, selected.ranking.size());
    honest.sensor = data.sensor;
    honest.protect = [&](const std::string& label) { return std::find(tilts.begin(), tilts.end(), label) != tilts.end(); };
    if (f.noise_law) honest.below_record = f.noise_law->below_record(whitener);
    if (square_corner) {
      honest.searched = [&](const ident::UlsResult& fit) {
        if (!has_square_term(fit)) return SearchedColumns{};
        // The columns are smooth in the corner: 1 % keeps the difference far above rounding.
        return SearchedColumns{Eigen::MatrixXd(prediction_derivative(fit, 1e-2 * *square_corner, whitener, stage.cases, [&](std::span<const Term> terms, double moved) {
                                 return mounting_regression(terms, m, *best_misalignment, data, dataset_label, first_row,
                                                            *square_corner + moved);
                               })),
                               {0}};
      };
    }
    // The cases' stated placements, part of the residual's covariance: the tilts' sd, and so the
    // angles', then carry them.
    const std::vector<StatedPlacement> placements = stated_placements(data);
    if (!placements.empty()) {
      const Eigen::Index stage_first_row = std::max(ident::first_usable_row(selected_terms), first_row);   // as stage's
      honest.placements = [&, stage_first_row](const ident::UlsResult& fit) {
        std::vector<Term> terms;
        for (Eigen::Index j = 0; j < fit.process_terms; ++j) terms.push_back(ident::parse_term(fit.labels[std::size_t(j)]));
        return placement_columns(terms, fit.theta.head(fit.process_terms), stack_inputs(m, *best_misalignment), placements, data,
                                 dataset_label, stage_first_row, square_corner, whitener);
      };
    }
    std::vector<Eigen::Index> columns(selected_terms.size());
    for (std::size_t i = 0; i < columns.size(); ++i) columns[i] = static_cast<Eigen::Index>(i);
    ident::UlsResult fit = fit_identifiable(stage, data.sensor, columns, options.selection.uls, result.excluded);
    InferenceOutcome inference = infer_after_selection(honest, std::move(columns), std::move(fit), options.selection.uls);
    result.s_fit = std::move(inference.fit);
    for (const PrunedTerm& pruned : inference.pruned) result.pruned.push_back({pruned.term, pruned_reason(pruned, "mounting's model")});
    // The angles' test dof: the tilts' (between the mounting's phases when their offsets dominate).
    for (Eigen::Index j = 0; j < inference.dof.size(); ++j) {
      const std::string& label = result.s_fit.labels[static_cast<std::size_t>(j)];
      if (std::find(tilts.begin(), tilts.end(), label) != tilts.end()) result.angles_dof = std::min(result.angles_dof, inference.dof(j));
    }
  }
  const ident::UlsResult selected_fit = result.s_fit;
  record_bias_sd(result, selected_fit);
  {
    // The angles' sd: the kept tilts' in the selected model (the tilt of n_i toward p and o, over
    // theta_i), whose covariance holds the cases' placements and a bias handed over, by the delta
    // method through algorithm 1.
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    const Eigen::Vector3d theta = sensor_frame_sensitivities(selected_fit, data.sensor, &covariance);
    if (handed)
      covariance += handed_bias_covariance(regressions, ident::parse_terms(selected_fit.process_labels()), *best_misalignment, known_bias_sd,
                                           [&](const std::vector<std::string>& labels, const Eigen::VectorXd& d) {
                                             ident::UlsResult moved;
                                             moved.labels = labels;
                                             moved.theta = d;
                                             return sensor_frame_sensitivities(moved, data.sensor);
                                           });
    if (theta(0) != 0.0) set_angles(result, misalignment_angles(theta, covariance).sd);
  }
  if (!tilts.empty()) {
    const Eigen::Vector3d theta = sensor_frame_sensitivities(selected_fit, data.sensor);   // theta_i, theta_p, theta_o
    std::vector<Term> s_terms;
    for (const std::string& label : selected_fit.labels) {
      if (std::find(tilts.begin(), tilts.end(), label) == tilts.end()) s_terms.push_back(ident::parse_term(label));
    }
    if (theta(0) != 0.0) {
      result.m_cs = with_twist(misalignment_from_sensitivities(result.m_cs.transpose() * theta, frames::Dcm::Identity()), twist);
      set_angles(result, result.angles_sd);
    }
    StackedRegression s = regressions.whitened(s_terms, result.m_cs);
    std::vector<Eigen::Index> columns(s_terms.size());
    for (std::size_t i = 0; i < columns.size(); ++i) columns[i] = static_cast<Eigen::Index>(i);
    result.s_fit = fit_identifiable(s, data.sensor, columns, options.selection.uls, result.excluded);
  }
  result.s_terms = result.s_fit.labels;
  return result;
}

}  // namespace inertia::procedure
