#include "analyzer/procedure/pipeline.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>

#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

using ident::Term;

double weight_of(const PipelineOptions& options, const std::string& case_name) {
  const auto it = options.case_weights.find(case_name);
  return it == options.case_weights.end() ? 1.0 : it->second;
}

/// The F_E-and-F_S sensitivities theta_x, theta_y, theta_z of a fit (zero where a term is absent).
std::optional<Eigen::Vector3d> external_sensitivities(const std::vector<std::string>& labels,
                                                      const Eigen::VectorXd& theta) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  bool any = false;
  const char* names[3] = {"a_x", "a_y", "a_z"};
  for (std::size_t j = 0; j < labels.size(); ++j) {
    for (int c = 0; c < 3; ++c) {
      if (labels[j] == names[c]) {
        s(c) = theta(static_cast<Eigen::Index>(j));
        any = true;
      }
    }
  }
  if (!any || s.norm() == 0.0) return std::nullopt;
  return s;
}

std::vector<Term> parse_fixed(const std::vector<std::string>& texts, const char* what) {
  if (texts.empty()) throw InputError(std::string("a fixed ") + what + " model needs at least one term");
  return ident::parse_terms(texts);
}

/// One mounting's cases with their references turned into the nominal case frame, so that the
/// shared misalignment is a single M_C^S (with m_ec = I in the copies).
struct MountingData {
  std::vector<dataset::CaseData> cases;     // copies in the nominal case frame
  std::vector<double> weights;
  bool rotation_table = false;
  bool shaker_only = true;
};

MountingData mounting_data(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                           const PipelineOptions& options, std::optional<double> known_bias) {
  MountingData m;
  for (std::size_t index : cases) {
    dataset::CaseData c = data.cases.at(index);
    c.a_e = c.a_e * c.m_ec.transpose();   // rows: (M_E^C a_E)^T
    if (c.w_e) *c.w_e = *c.w_e * c.m_ec.transpose();
    c.m_ec = frames::Dcm::Identity();
    if (known_bias) c.y.array() -= *known_bias;
    m.rotation_table = m.rotation_table || c.kind == dataset::CaseKind::RotationTable;
    m.shaker_only = m.shaker_only && c.kind == dataset::CaseKind::Shaker;
    m.weights.push_back(weight_of(options, c.name));
    m.cases.push_back(std::move(c));
  }
  return m;
}

std::vector<StackInput> stack_inputs(const MountingData& m, const std::vector<std::size_t>& cases,
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

bool is_sensitivity_label(const std::string& label) {
  return label == "a_x" || label == "a_y" || label == "a_z" || label == "a_i" || label == "w_x" || label == "w_y" ||
         label == "w_z" || label == "w_i";
}

/// ERR order of the columns of a stacked problem (sensitivities forced first, the bias after
/// them), without the columns the data cannot separate from the ones before them.
std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, const ident::ErrOptions& base) {
  ident::ErrOptions options = base;
  options.forced.clear();
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (is_sensitivity_label(s.labels[j])) options.forced.push_back(static_cast<Eigen::Index>(j));
  }
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (s.labels[j] == "1") options.forced.push_back(static_cast<Eigen::Index>(j));
  }
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
      return ident::uls_batch(s.phi, s.y, s.labels, {}, uls, sorted);
    } catch (const ident::IdentifiabilityError& e) {
      auto victim = columns.end();
      for (auto it = columns.begin(); it != columns.end(); ++it) {
        const std::string& label = s.labels[static_cast<std::size_t>(*it)];
        if (!is_sensitivity_label(label) && std::find(e.labels().begin(), e.labels().end(), label) != e.labels().end()) {
          victim = it;   // keep the last one in ranked order
        }
      }
      if (victim == columns.end()) throw;
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
StackedRegression whitened_regression(std::span<const Term> terms, const MountingData& m, const std::vector<std::size_t>& cases,
                                      const frames::Dcm& m_cs, const dataset::Dataset& data, std::string_view label,
                                      Eigen::Index first_row, std::optional<double> square_corner,
                                      const ArWhitener& whitener) {
  StackedRegression s = stack_regressions(terms, stack_inputs(m, cases, m_cs), data.t_ref, label, first_row);
  apply_square_model(s, data, square_corner);
  whitener.apply(s);
  return s;
}

/// `m` turned about its first row (n_i) by `psi`: n_p, n_o rotated in their plane.
frames::Dcm with_twist(const frames::Dcm& m, double psi) {
  if (psi == 0.0) return m;
  frames::Dcm r = m;
  const double c = std::cos(psi), s = std::sin(psi);
  r.row(1) = c * m.row(1) + s * m.row(2);
  r.row(2) = -s * m.row(1) + c * m.row(2);
  return r;
}

bool uses_cross_axes(const std::vector<Term>& terms) {
  return std::any_of(terms.begin(), terms.end(),
                     [](const Term& t) { return t.uses(ident::Variable::Ap) || t.uses(ident::Variable::Ao); });
}

/// The F_S terms a tilt of the input axis adds to the sensitivity term when `s_terms` has it
/// (a_i; w_i for gyroscopes) and lacks them: to first order in the tilt (d_p, d_o),
/// theta_i (n_i + d_p n_p + d_o n_o) . a = theta_i a_i + theta_i d_p a_p + theta_i d_o a_o.
std::vector<Term> tilt_terms(const std::vector<Term>& s_terms, dataset::SensorKind sensor) {
  using ident::Variable;
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  const auto plain = [](Variable v) { return Term::from_factors({ident::Factor{v, 0, ident::FactorFunction::Plain, 1}}); };
  if (std::find(s_terms.begin(), s_terms.end(), plain(gyro ? Variable::Wi : Variable::Ai)) == s_terms.end()) return {};
  std::vector<Term> out;
  for (Variable v : gyro ? std::array{Variable::Wp, Variable::Wo} : std::array{Variable::Ap, Variable::Ao}) {
    if (std::find(s_terms.begin(), s_terms.end(), plain(v)) == s_terms.end()) out.push_back(plain(v));
  }
  return out;
}

/// Algorithm 2 steps 6-8 as a selection hook: the misalignment from the step-5 fit, then the F_S
/// problem of the ranked terms built with it.
class MisalignmentHook final : public ident::FitHook {
 public:
  MisalignmentHook(const MountingData& m, const std::vector<std::size_t>& cases, const std::vector<Term>& es_terms,
                   const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                   const ArWhitener& whitener, std::optional<double> square_corner, double twist)
      : m_(m), cases_(cases), es_terms_(es_terms), data_(data), label_(label), first_row_(first_row),
        whitener_(whitener), square_corner_(square_corner), twist_(twist) {}

  /// The tilt terms kept in the stage of j ranked terms (empty: none).
  [[nodiscard]] std::vector<std::string> tilts(std::size_t j) const {
    return j >= 1 && j <= tilts_.size() ? tilts_[j - 1] : std::vector<std::string>{};
  }

  bool transform(std::size_t j, const ident::UlsResult& ranked_fit, ident::StageProblem& stage) override {
    const auto theta = external_sensitivities(ranked_fit.labels, ranked_fit.theta);
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
    std::vector<Term> tilts = tilt_terms(s_terms, data_.sensor);
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
    stage.rational = {};
    return true;
  }

  [[nodiscard]] std::optional<frames::Dcm> misalignment(std::size_t j) const {
    return j >= 1 && j <= misalignments_.size() ? misalignments_[j - 1] : std::nullopt;
  }

 private:
  const MountingData& m_;
  const std::vector<std::size_t>& cases_;
  const std::vector<Term>& es_terms_;
  const dataset::Dataset& data_;
  std::string_view label_;
  Eigen::Index first_row_;
  const ArWhitener& whitener_;
  std::optional<double> square_corner_;
  double twist_;
  std::vector<std::optional<frames::Dcm>> misalignments_;
  std::vector<std::vector<std::string>> tilts_;
};

}  // namespace

std::vector<std::pair<std::string, std::vector<std::size_t>>> mountings_of(const dataset::Dataset& data) {
  std::vector<std::pair<std::string, std::vector<std::size_t>>> groups;
  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    const std::string& label = data.cases[i].mounting;
    auto it = label.empty() ? groups.end()
                            : std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == label; });
    if (it == groups.end()) {
      groups.emplace_back(label.empty() ? data.cases[i].name : label, std::vector<std::size_t>{i});
    } else {
      it->second.push_back(i);
    }
  }
  return groups;
}

MountingResult estimate_mounting(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                                 const std::string& mounting, const PipelineOptions& options,
                                 std::string_view dataset_label, std::optional<double> known_bias) {
  MountingResult result;
  result.mounting = mounting;
  result.cases = cases;
  const MountingData m = mounting_data(data, cases, options, known_bias);
  result.known_bias = known_bias;

  // The F_E-and-F_S candidates (eq. 2), or the fixed model.
  std::vector<Term> es_terms = options.misalignment.select
                                   ? ident::candidate_terms(data.sensor, ident::ModelFrame::ExternalAndSensor,
                                                            options.misalignment.candidates)
                                   : parse_fixed(options.misalignment.fixed_terms, "misalignment");
  if (m.rotation_table && options.ieee_rotation_table_exclusions) {
    const auto ieee_excluded = [](const Term& t) {
      const auto& f = t.factors();
      return f.size() == 1 && f[0].power == 2 && f[0].function == ident::FactorFunction::Plain &&
             (f[0].variable == ident::Variable::Ap || f[0].variable == ident::Variable::Ao);
    };
    for (const Term& t : es_terms) {
      if (ieee_excluded(t)) result.excluded.push_back(t.to_string());
    }
    std::erase_if(es_terms, ieee_excluded);
  }
  if (m.shaker_only && options.ieee_shaker_exclusions) {
    // On a slip table gravity is constant in every orientation: per orientation each column is a
    // combination of 1, v and v^2 (v the vibration), and the bias is what gets confounded.
    for (const Term& t : es_terms) {
      if (t.is_bias()) result.excluded.push_back(t.to_string());
    }
    std::erase_if(es_terms, [](const Term& t) { return t.is_bias(); });
  }
  const Eigen::Index first_row = max_lag_of(es_terms);

  // Step 1 with a fixed point: the nonlinear F_S terms of eq. 2 need M_C^S, which the fit gives.
  frames::Dcm m_cs = frames::Dcm::Identity();
  StackedRegression es;
  ArWhitener whitener;
  std::optional<double> square_corner;
  double twist = 0.0;
  const bool twist_matters = uses_cross_axes(es_terms);
  std::vector<Eigen::Index> usable;
  for (result.refinements = 0; result.refinements < std::max(1, options.max_refinements); ++result.refinements) {
    es = stack_regressions(es_terms, stack_inputs(m, cases, m_cs), data.t_ref, dataset_label, first_row);
    if (options.square_highpass) {
      const std::vector<Eigen::Index> squares = square_columns(es.labels);
      if (!squares.empty() && result.refinements < 2) {   // the corner hardly moves with M_C^S after that
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
    whitener.apply(es);
    const ident::UlsResult full = fit_identifiable(es, usable, uls, dropped);
    const auto theta = external_sensitivities(full.labels, full.theta);
    if (!theta) throw std::runtime_error("mounting '" + mounting + "': the model has no a_x, a_y, a_z sensitivity");
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
    return result;
  }

  // Steps 2-15 on the converged F_E problem.
  MisalignmentHook hook(m, cases, es_terms, data, dataset_label, first_row, whitener, square_corner, twist);
  ident::SelectionProblem problem{es.phi, es.y, es.labels, {}, {}};
  ident::SelectionOptions selection = options.selection;
  selection.uls.noise_lags = 0;
  problem.ranking = usable;   // identifiable columns in ERR order, sensitivities first
  const ident::SelectionResult selected = ident::select_model(problem, selection, &hook);
  const ident::CandidateModel& best = selected.best_model();
  result.candidates_tried = selected.candidates.size();
  result.fitness = best.fitness;
  const auto best_misalignment = hook.misalignment(best.ranked_terms);
  if (!best.transformed || !best_misalignment) {
    throw std::runtime_error("mounting '" + mounting + "': the selected model has no a_x, a_y, a_z sensitivity");
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
  if (!tilts.empty()) {
    const bool gyro = data.sensor == dataset::SensorKind::Gyroscope;
    const std::string axes[3] = {gyro ? "w_i" : "a_i", tilts.front(), tilts.back()};
    Eigen::Vector3d theta = Eigen::Vector3d::Zero();   // theta_i, theta_p, theta_o
    std::vector<Term> s_terms;
    for (std::size_t i = 0; i < best.fit.labels.size(); ++i) {
      const std::string& label = best.fit.labels[i];
      for (int a = 0; a < 3; ++a) {
        if (label == axes[a]) theta(a) = best.fit.theta(static_cast<Eigen::Index>(i));
      }
      if (std::find(tilts.begin(), tilts.end(), label) == tilts.end()) s_terms.push_back(ident::parse_term(label));
    }
    if (tilts.size() == 2 && theta(0) != 0.0) {
      result.m_cs = with_twist(misalignment_from_sensitivities(result.m_cs.transpose() * theta, frames::Dcm::Identity()), twist);
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

PipelineResult run_pipeline(const dataset::Dataset& data, const PipelineOptions& options,
                            std::string_view dataset_label) {
  if (data.cases.empty()) throw InputError("the dataset has no cases");
  PipelineResult result;
  result.cases.resize(data.cases.size());

  // Blocks 5-6. Mountings that can estimate the bias go first, so shaker-only mountings can use it.
  auto groups = mountings_of(data);
  const auto shaker_only = [&](const std::vector<std::size_t>& cases) {
    return std::all_of(cases.begin(), cases.end(),
                       [&](std::size_t i) { return data.cases[i].kind == dataset::CaseKind::Shaker; });
  };
  std::stable_partition(groups.begin(), groups.end(), [&](const auto& g) { return !shaker_only(g.second); });
  std::optional<double> bias;
  for (const auto& [mounting, cases] : groups) {
    const bool use_bias = shaker_only(cases) && options.ieee_shaker_exclusions && options.shaker_bias_from_other_mountings;
    MountingResult m = estimate_mounting(data, cases, mounting, options, dataset_label, use_bias ? bias : std::nullopt);
    if (!bias) {
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

  // Blocks 7-9.
  std::vector<Term> candidates;
  if (options.batch.select) {
    candidates = ident::candidate_terms(data.sensor, ident::ModelFrame::Sensor, options.batch.candidates);
  } else {
    candidates = parse_fixed(options.batch.fixed_terms, "batch");
  }
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    inputs.push_back({i, &data.cases[i], result.cases[i].m_es, weight_of(options, data.cases[i].name)});
  }
  StackedRegression batch = stack_regressions(candidates, inputs, data.t_ref, dataset_label);
  if (options.square_highpass && options.batch_square_highpass) {
    // The squares' high pass (eq. 12), its corner estimated on the whole batch as in blocks 5-6.
    const std::vector<Eigen::Index> squares = square_columns(batch.labels);
    if (!squares.empty()) {
      const SquareCornerSearch search(batch, squares, data);
      result.square_corner_rad_s = search.best(options.square_highpass_min_rad_s,
                                               std::min(options.square_highpass_max_rad_s, max_corner(batch.cases, data)));
      apply_square_model(batch, data, result.square_corner_rad_s);
    }
  }
  {
    // The noise model from the residuals of the full candidate set (dependent columns left out).
    std::vector<Eigen::Index> usable = identifiable_ranking(batch, options.selection.err);
    ident::UlsOptions uls = options.selection.uls;
    uls.noise_lags = 0;
    std::vector<std::string> dropped;
    const ident::UlsResult ols = fit_identifiable(batch, usable, uls, dropped);
    const ArWhitener whitener = ArWhitener::fit(ols.residuals, batch.cases, options.whitening_max_order);
    whitener.apply(batch);
    result.whitening = whitener.coefficients();
  }
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
  if (options.batch.select) {
    ident::SelectionOptions selection = options.selection;
    selection.uls.noise_lags = 0;   // structure first; the noise model joins the final fit
    ident::SelectionProblem problem{batch.phi, batch.y, batch.labels, {}, identifiable_ranking(batch, selection.err)};
    const ident::SelectionResult selected = ident::select_model(problem, selection, nullptr);
    columns = selected.best_model().columns;
  } else {
    columns = identifiable_ranking(batch, options.selection.err);
  }
  std::vector<std::string> dropped;
  result.fit = fit_identifiable(batch, columns, uls, dropped);
  for (const std::string& label : result.fit.labels) {
    if (result.terms.size() < static_cast<std::size_t>(result.fit.process_terms)) result.terms.push_back(ident::parse_term(label));
  }
  const Eigen::Index n = result.fit.residuals.size();
  result.t_test = ident::parameter_t_test(result.fit.process_theta(), result.fit.std_dev.head(result.fit.process_terms), n);
  result.residual_mean = ident::residual_mean_test(result.fit.residuals);
  result.aic = ident::aic(result.fit.residuals, result.fit.theta.size());
  return result;
}

}  // namespace inertia::procedure
