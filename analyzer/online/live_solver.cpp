#include "analyzer/online/live_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/procedure/corner_search.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/turn_search.hpp"
#include "common/frames.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Term;
using ident::Variable;

namespace {

bool contains(const std::vector<Index>& v, Index x) { return std::find(v.begin(), v.end(), x) != v.end(); }

}  // namespace

std::optional<double> StatFit::value(Index term) const {
  for (std::size_t j = 0; j < terms.size(); ++j)
    if (terms[j] == term) return theta(static_cast<Index>(j));
  return std::nullopt;
}

LiveSolver::LiveSolver(const LiveBasis& basis, std::vector<Index> model, std::vector<Index> sensitivities,
                       dataset::SensorKind sensor, CornerGrid grid, bool static_option, SolverOptions options)
    : basis_(basis), model_(std::move(model)), sensitivities_(std::move(sensitivities)), sensor_(sensor),
      grid_(std::move(grid)), static_option_(static_option || grid_.empty()), options_(std::move(options)) {
  bias_ = basis_.find(Term());
  factor_of_.assign(basis_.terms().size(), -1);
  for (std::size_t j = 0; j < basis_.terms().size(); ++j) {
    const Term& t = basis_.terms()[j];
    if (t.is_output_multiplied()) factor_of_[j] = basis_.find(t.denominator_factor());
  }
}

template <class FitAt>
StatFit LiveSolver::best_corner(FitAt&& fit_at) const {
  const procedure::CornerChoice choice =
      procedure::least_residual_corner(grid_.nodes(), static_option_, [&](std::optional<double> corner) {
        const StatFit f = fit_at(corner);
        return f.ok ? f.rss : std::numeric_limits<double>::infinity();
      });
  return fit_at(choice.corner_rad_s);
}

Eigen::MatrixXd LiveSolver::gram(const std::vector<Index>& terms, const std::vector<const Information*>& infos,
                                 const std::vector<Eigen::Matrix3d>& m_cs, std::optional<double> corner, bool differences) const {
  const auto p = static_cast<Index>(terms.size());
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(p + 1, p + 1);
  Eigen::MatrixXd tb, tf;
  const CornerWeights weights = corner ? grid_.at(*corner) : CornerWeights{};
  for (std::size_t i = 0; i < infos.size(); ++i) {
    if (infos[i]->samples() == 0) continue;
    basis_.transform(terms, m_cs[i], weights.filtered(), tb, tf);
    g += differences ? infos[i]->model_difference_gram(tb, tf, weights) : infos[i]->model_gram(tb, tf, weights);
  }
  return g;
}

void LiveSolver::factor_statistics(const std::vector<Index>& terms, const std::vector<const Information*>& infos,
                                   const std::vector<Eigen::Matrix3d>& m_cs, std::vector<Index>& positions,
                                   Eigen::MatrixXd& factor_gram, Eigen::VectorXd& factor_sum) const {
  positions.clear();
  std::vector<Index> factors;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    const Index f = factor_of_[static_cast<std::size_t>(terms[j])];
    if (f < 0) continue;
    positions.push_back(static_cast<Index>(j));
    factors.push_back(f);
  }
  const auto q = static_cast<Index>(factors.size());
  factor_gram = Eigen::MatrixXd::Zero(q, q);
  factor_sum = Eigen::VectorXd::Zero(q);
  if (q == 0) return;
  Eigen::MatrixXd tb, tf;
  for (std::size_t i = 0; i < infos.size(); ++i) {
    if (infos[i]->samples() == 0) continue;
    basis_.transform(factors, m_cs[i], false, tb, tf);
    const Eigen::MatrixXd& g = infos[i]->base_gram();
    const Index b = g.rows() - 1;
    factor_gram.noalias() += tb * g.topLeftCorner(b, b) * tb.transpose();
    factor_sum.noalias() += tb * g.col(0).head(b);   // base column 0 is the constant
  }
}

ident::NormalEquations LiveSolver::equations(const Eigen::MatrixXd& g, double weight, const std::vector<Index>& terms,
                                             const std::vector<const Information*>& infos,
                                             const std::vector<Eigen::Matrix3d>& m_cs) const {
  std::vector<Index> factor_positions;
  Eigen::MatrixXd factor_gram;
  Eigen::VectorXd factor_sum;
  factor_statistics(terms, infos, m_cs, factor_positions, factor_gram, factor_sum);
  std::vector<std::string> labels;
  labels.reserve(terms.size());
  for (const Index t : terms) labels.push_back(basis_.terms()[static_cast<std::size_t>(t)].to_string());
  return {g, static_cast<Index>(std::llround(weight)), std::move(labels), std::move(factor_positions), std::move(factor_gram),
          std::move(factor_sum)};
}

StatFit LiveSolver::fit(const Eigen::MatrixXd& g, double weight, const std::vector<Index>& terms,
                        const std::vector<const Information*>& infos, const std::vector<Eigen::Matrix3d>& m_cs) const {
  StatFit out;
  out.weight = weight;
  const ident::NormalEquations equations = this->equations(g, weight, terms, infos, m_cs);
  const std::vector<Index>& factor_positions = equations.output_multiplied();
  const Eigen::MatrixXd& factor_gram = equations.factor_gram();
  const Eigen::VectorXd& factor_sum = equations.factor_sum();
  // The ranking and the dependence rule are the batch's (ident/normal_equations.hpp).
  ident::IdentifiableRanking ranking = ident::rank_identifiable(equations, sensor_);
  std::vector<Index> columns = std::move(ranking.order);   // positions into terms
  for (Index d : ranking.dependent) out.undetermined.push_back(terms[static_cast<std::size_t>(d)]);
  // An output-multiplied column whose factor does not vary on its own is the output times a
  // constant (y*w_i in a dwell): it explains the output by itself, which ULS's correction does
  // not undo (it takes the noise out of the column's energy, not out of its correlation with the
  // output). Not determined until the factor moves (excitation.hpp's share).
  for (std::size_t a = 0; a < factor_positions.size(); ++a) {
    const auto k = static_cast<Index>(a);
    const double energy = factor_gram(k, k);
    const double own = energy - factor_sum(k) * factor_sum(k) / weight;
    if (energy > 0.0 && own >= procedure::kMinExcitationShare * energy) continue;
    const auto it = std::find(columns.begin(), columns.end(), factor_positions[a]);
    if (it == columns.end()) continue;
    out.undetermined.push_back(terms[static_cast<std::size_t>(*it)]);
    columns.erase(it);
  }
  if (columns.empty()) {
    out.why = "no term is determined by the data";
    return out;
  }
  std::vector<Index> left;
  try {
    const auto [ascending, sol] = ident::fit_identifiable(
        columns, equations.labels(), sensor_, left, [&](std::span<const Index> positions) {
          std::vector<std::string> names;
          for (const Index j : positions) names.push_back(equations.labels()[static_cast<std::size_t>(j)]);
          return std::pair(std::vector<Index>(positions.begin(), positions.end()),
                           ident::solve_uls(equations.statistics(positions), names, options_.uls));
        });
    out.ok = true;
    for (const Index j : ascending) out.terms.push_back(terms[static_cast<std::size_t>(j)]);
    out.theta = sol.theta;
    out.rss = sol.zeta_energy;
    const double dof = std::max(weight - static_cast<double>(ascending.size()), 1.0);
    out.s2 = out.rss / dof;
    const bool rational = std::any_of(ascending.begin(), ascending.end(), [&](Index j) {
      return std::find(factor_positions.begin(), factor_positions.end(), j) != factor_positions.end();
    });
    out.covariance = options_.long_run_variance_factor * out.s2 * (rational ? sol.corrected_inverse : sol.gram_inverse);
    out.sd = out.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    out.conditional_sd = out.sd;
    out.gram_inverse = sol.gram_inverse;
  } catch (const std::runtime_error& e) {   // a near-dependence of sensitivities, or no positive-definite correction
    out.why = e.what();
  }
  for (const Index j : left) out.undetermined.push_back(terms[static_cast<std::size_t>(j)]);
  return out;
}

MountingFit LiveSolver::fit_mounting(const MountingStatistics& m, std::optional<double> known_bias, double known_bias_sd) const {
  MountingFit out;
  out.m_cs = m.m_cs;
  if (m.info.samples() == 0) {
    out.note = "no samples";
    return out;
  }
  // The external-frame form (eq. 1): sensitivities split over the case axes, the rest in F_S.
  const bool gyro = sensor_ == dataset::SensorKind::Gyroscope;
  const std::vector<Term> axis_terms = gyro ? std::vector<Term>{plain_term(Variable::Wi), plain_term(Variable::Wp), plain_term(Variable::Wo)}
                                            : std::vector<Term>{plain_term(Variable::Ai), plain_term(Variable::Ap), plain_term(Variable::Ao)};
  // What the mounting's inputs determine, by the batch's rule (excitation.hpp): an angle without
  // its own excitation is held at the nominal frame, within the mounting tolerance (1 sd), which
  // add_misalignment_uncertainty carries into the terms' sd.
  procedure::AxisExcitation excitation = procedure::axis_excitation(m.info.input_gram(), !known_bias.has_value());
  if (!m.hold_unexcited) excitation.determined = {true, true, true};
  const std::vector<std::string> held = procedure::held_angle_notes(excitation, gyro, !known_bias.has_value());
  const double tolerance2 = options_.mounting_tolerance_rad * options_.mounting_tolerance_rad;
  const auto join_held = [&held] {
    std::string text;
    for (const std::string& h : held) text += (text.empty() ? "" : "; ") + h;
    return text;
  };
  if (!excitation.aligns()) {
    out.note = join_held();
    out.angles = rotation_vector(out.m_cs);
    out.angles(0) = kNaN;
    out.angles_covariance = Eigen::Vector3d(0.0, tolerance2, tolerance2).asDiagonal();
    out.angles_sd = Eigen::Vector3d(kNaN, options_.mounting_tolerance_rad, options_.mounting_tolerance_rad);
    out.held = {false, true, true};
    return out;
  }
  // Rotation-vector components (i, p, o) of the angles a tilt axis turns: XRA's about o, YRA's about p.
  constexpr std::array<int, 3> kAngleOfAxis{0, 2, 1};
  std::vector<Index> sensitivities;
  for (std::size_t a = 0; a < 3; ++a)
    if (excitation.determined[a]) sensitivities.push_back(sensitivities_[a]);
  std::vector<Index> es = sensitivities;
  std::vector<std::string> excluded;
  for (Index t : model_) {
    const Term& term = basis_.terms()[static_cast<std::size_t>(t)];
    if (std::find(axis_terms.begin(), axis_terms.end(), term) != axis_terms.end()) continue;
    if (procedure::ieee_1293_excluded(term, m.kind, known_bias.has_value(), options_.ieee_1293)) {
      excluded.push_back(term.to_string());
      continue;
    }
    es.push_back(t);
  }
  // A known bias is subtracted through the constant's column: y - b 1.
  const bool fold_bias = known_bias.has_value() && bias_ >= 0 && !contains(es, bias_);
  std::vector<Index> with_bias = es;
  if (fold_bias) with_bias.push_back(bias_);
  const std::vector<const Information*> infos{&m.info};
  const auto gram_at = [&](const Eigen::Matrix3d& m_cs, std::optional<double> corner) {
    Eigen::MatrixXd g = gram(with_bias, infos, {m_cs}, corner);
    if (!fold_bias) return g;
    const auto p = static_cast<Index>(es.size());
    const Index one = p, y = p + 1;
    const double b = *known_bias;
    Eigen::MatrixXd folded(p + 1, p + 1);
    folded.topLeftCorner(p, p) = g.topLeftCorner(p, p);
    folded.topRightCorner(p, 1) = g.col(y).head(p) - b * g.col(one).head(p);
    folded.bottomLeftCorner(1, p) = folded.topRightCorner(p, 1).transpose();
    folded(p, p) = g(y, y) - 2.0 * b * g(one, y) + b * b * g(one, one);
    return folded;
  };
  const double weight = m.info.weight();
  // The corner: the one with the least residual, on the fixed point's passes that search it
  // (procedure::corner_searched_on, as the batch pipeline's).
  std::optional<double> corner;
  StatFit f;
  for (out.refinements = 0; out.refinements < options_.max_refinements; ++out.refinements) {
    if (procedure::corner_searched_on(out.refinements)) {
      corner = best_corner([&](std::optional<double> b) {
                 StatFit g = fit(gram_at(out.m_cs, b), weight, es, infos, {out.m_cs});
                 g.corner_rad_s = b;
                 return g;
               }).corner_rad_s;
    }
    f = fit(gram_at(out.m_cs, corner), weight, es, infos, {out.m_cs});
    f.corner_rad_s = corner;
    Eigen::Vector3d theta = Eigen::Vector3d::Zero();   // a held axis: 0, its tilt stays nominal
    bool have = f.ok;
    for (std::size_t c = 0; c < 3 && have; ++c) {
      if (!excitation.determined[c]) continue;
      const auto v = f.value(sensitivities_[c]);
      if (!v) have = false;
      else theta(static_cast<Index>(c)) = *v;
    }
    if (!have || !(theta.norm() > 0.0) || !theta.allFinite()) {
      out.fit = f;
      out.determined = false;
      out.m_cs = m.m_cs;
      out.note = f.ok ? "no excitation along the sensitive axis in this mounting" : f.why;
      out.angles_covariance = Eigen::Vector3d(0.0, tolerance2, tolerance2).asDiagonal();
      out.held = {false, true, true};
      return out;
    }
    const frames::Dcm next = procedure::misalignment_from_sensitivities(theta, frames::Dcm::Identity());
    const double change = frames::angle_between(next, out.m_cs);
    out.m_cs = next;
    out.determined = true;
    if (change < options_.refinement_tolerance_rad) break;
  }
  out.fit = f;
  if (!excluded.empty()) {
    std::string list;
    for (const std::string& e : excluded) list += (list.empty() ? "" : ", ") + e;
    out.note = "left out (IEEE 1293 12.3.5.7): " + list;
  }
  if (!held.empty()) out.note += (out.note.empty() ? "" : "; ") + join_held();
  // The bias other mountings take: from the F_S fit of this mounting with its M_C^S (algorithm
  // 2's step 7, as the batch pipeline takes it), the sensitivities merged into the axis term.
  if (bias_ >= 0 && !fold_bias) {
    std::vector<Index> s_terms;
    const Index axis = basis_.find(axis_terms.front());
    if (axis >= 0) s_terms.push_back(axis);
    for (Index t : es)
      if (!contains(sensitivities_, t)) s_terms.push_back(t);
    const StatFit sf = fit(gram(s_terms, infos, {out.m_cs}, corner), weight, s_terms, infos, {out.m_cs});
    out.bias = sf.value(bias_);
    for (std::size_t j = 0; j < sf.terms.size(); ++j)
      if (sf.terms[j] == bias_ && sf.sd.size() > static_cast<Index>(j)) out.bias_sd = sf.sd(static_cast<Index>(j));
  }
  // Angles and their sd by the delta method through algorithm 1, with the cases' placements.
  Eigen::Vector3d theta = Eigen::Vector3d::Zero();
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  std::array<Index, 3> pos{-1, -1, -1};
  for (std::size_t a = 0; a < 3; ++a)
    for (std::size_t j = 0; j < f.terms.size(); ++j)
      if (excitation.determined[a] && f.terms[j] == sensitivities_[a]) pos[a] = static_cast<Index>(j);
  for (std::size_t a = 0; a < 3; ++a) {
    if (pos[a] < 0) continue;
    theta(static_cast<Index>(a)) = f.theta(pos[a]);
    for (std::size_t b = 0; b < 3; ++b)
      if (pos[b] >= 0) c(static_cast<Index>(a), static_cast<Index>(b)) = f.covariance(pos[a], pos[b]);
  }
  if (fold_bias && known_bias_sd > 0.0) {
    // The bias handed over moves the fit as the output less b + delta does: every coefficient by
    // -delta (X'X)^-1 X'w, w the whitened constant (procedure::estimate_mounting's rule).
    std::vector<Index> with_one = f.terms;
    with_one.push_back(bias_);
    const Eigen::MatrixXd g = gram(with_one, infos, {out.m_cs}, corner);
    const auto p = static_cast<Index>(f.terms.size());
    const Eigen::VectorXd d = g.topLeftCorner(p, p).ldlt().solve(g.col(p).head(p));
    Eigen::Vector3d d_sensitivities = Eigen::Vector3d::Zero();
    for (std::size_t a = 0; a < 3; ++a)
      if (pos[a] >= 0) d_sensitivities(static_cast<Index>(a)) = d(pos[a]);
    c += known_bias_sd * known_bias_sd * d_sensitivities * d_sensitivities.transpose();
  }
  const Eigen::Matrix3d placed = procedure::placement_covariance(theta, m.placements, !known_bias.has_value());
  const procedure::MisalignmentAngles angles = procedure::misalignment_angles(theta, c + placed);
  out.angles = rotation_vector(out.m_cs);
  out.angles(0) = kNaN;
  out.angles_covariance = angles.covariance;
  out.angles_sd = angles.sd;
  // The delta method is linear in the sensitivities' covariance: the placements' share apart, of
  // the tilts (about i algorithm 1 reads nothing).
  out.placement_angles_covariance = angles.jacobian * placed * angles.jacobian.transpose();
  out.placement_angles_covariance.row(0).setZero();
  out.placement_angles_covariance.col(0).setZero();
  for (std::size_t a = 1; a < 3; ++a) {
    if (excitation.determined[a]) continue;
    const auto k = kAngleOfAxis[a];
    for (Eigen::Matrix3d* cov : {&out.angles_covariance, &out.placement_angles_covariance}) {
      cov->row(k).setZero();
      cov->col(k).setZero();
    }
    out.angles_covariance(k, k) = tolerance2;
    out.angles_sd(k) = options_.mounting_tolerance_rad;
    out.held[static_cast<std::size_t>(k)] = true;
  }
  return out;
}

StatFit LiveSolver::fit_batch_at(const std::vector<const Information*>& infos, const std::vector<Eigen::Matrix3d>& m_cs,
                                 std::optional<double> corner) const {
  double weight = 0.0;
  for (const Information* i : infos) weight += i->weight();
  StatFit f = fit(gram(model_, infos, m_cs, corner), weight, model_, infos, m_cs);
  f.corner_rad_s = corner;
  return f;
}

namespace {

/// The batch turned on the live statistics: each step the batch's Gauss-Newton step
/// (relative_twists.cpp), from the Gram of the fitted columns, the prediction's derivatives and
/// the output (LiveSolver::turn_derivative_gram) instead of from the rows.
class StatisticsTurns final : public procedure::TurnedBatch {
 public:
  StatisticsTurns(const LiveSolver& solver, const std::vector<const Information*>& infos, std::vector<Eigen::Matrix3d>& m_cs,
                  std::optional<double> corner, double long_run_variance_factor, double tolerance_rad,
                  const CaseClusters* cases, std::vector<RelativeTurn>& out)
      : solver_(solver), infos_(infos), m_cs_(m_cs), start_m_cs_(m_cs), corner_(corner),
        long_run_variance_factor_(long_run_variance_factor), tolerance_rad_(tolerance_rad), cases_(cases), out_(out) {}

  std::optional<procedure::TurnStep> step(std::span<const procedure::TurnParameter> parameters) override {
    const StatFit at = solver_.fit_batch_at(infos_, m_cs_, corner_);
    if (!at.ok || !(at.s2 > 0.0)) return std::nullopt;
    const Eigen::MatrixXd g = solver_.turn_derivative_gram(at, parameters, infos_, m_cs_, procedure::kTurnDerivativeStepRad);
    const auto p = static_cast<Index>(at.terms.size()), q = static_cast<Index>(parameters.size());
    const Eigen::VectorXd coefficients = solver_.signed_theta(at);
    // With J the derivatives and the fitted columns X projected out (the terms re-fitted at every
    // turn), the step is (J~'J~)^-1 J~'r and J~'J~ / sigma^2 the turns' information; r = y - X theta.
    const Eigen::MatrixXd xx = g.topLeftCorner(p, p), xd = g.block(0, p, p, q), dd = g.block(p, p, q, q);
    const Eigen::VectorXd xr = g.block(0, p + q, p, 1) - xx * coefficients;
    const Eigen::VectorXd dr = g.block(p, p + q, q, 1) - xd.transpose() * coefficients;
    const Eigen::LDLT<Eigen::MatrixXd> gram(xx);
    const Eigen::MatrixXd jj = dd - xd.transpose() * gram.solve(xd);
    const Eigen::VectorXd jr = dr - xd.transpose() * gram.solve(xr);
    if (!jj.allFinite() || !jr.allFinite()) return std::nullopt;
    procedure::TurnStep out;
    out.information = jj / (long_run_variance_factor_ * at.s2);
    out.delta = jj.ldlt().solve(jr);
    if (cases_ != nullptr) {
      const std::optional<Eigen::MatrixXd> c = solver_.turn_covariance(at, parameters, *cases_, m_cs_, procedure::kTurnDerivativeStepRad);
      if (c && c->allFinite()) out.information = c->ldlt().solve(Eigen::MatrixXd::Identity(q, q));
    }
    return out;
  }

  void turn(std::span<const procedure::TurnParameter> parameters, const Eigen::VectorXd& delta,
            const Eigen::MatrixXd& covariance) override {
    m_cs_ = moved(parameters, delta);
    const Eigen::Matrix3d to_angles = procedure::turn_angles();
    for (std::size_t i = 0; i < parameters.size(); ++i) {
      const std::size_t k = parameters[i].mounting;
      if (parameters[i].axis != 2) continue;
      // The turn's covariance over turned()'s axes: a tilt the mounting's excitation does not
      // determine was not searched, and stays held within the tolerance.
      Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
      std::array<bool, 3> held{};
      for (int axis = 0; axis < 2; ++axis) {
        held[static_cast<std::size_t>(procedure::angle_of_turn(axis))] = true;
        c(axis, axis) = tolerance_rad_ * tolerance_rad_;
      }
      for (std::size_t a = 0; a < parameters.size(); ++a) {
        if (parameters[a].mounting != k) continue;
        held[static_cast<std::size_t>(procedure::angle_of_turn(parameters[a].axis))] = false;
        for (std::size_t b = 0; b < parameters.size(); ++b)
          if (parameters[b].mounting == k)
            c(parameters[a].axis, parameters[b].axis) = covariance(static_cast<Index>(a), static_cast<Index>(b));
      }
      out_[k].estimated = true;
      out_[k].covariance = to_angles * c * to_angles.transpose();
      out_[k].held_angles = held;
      out_[k].twist_rad += delta(static_cast<Index>(i));
      out_[k].twist_sd_rad = std::sqrt(std::max(0.0, covariance(static_cast<Index>(i), static_cast<Index>(i))));
    }
  }

  void restore(std::span<const std::size_t> mountings) override {
    for (const std::size_t k : mountings) {
      m_cs_[k] = start_m_cs_[k];
      out_[k] = RelativeTurn{};
    }
  }

  void hold(std::span<const procedure::TurnParameter> parameters, std::size_t twist, const Eigen::MatrixXd&,
            const procedure::TwistHeld& why) override {
    RelativeTurn& r = out_[parameters[twist].mounting];
    r.twist_sd_rad = why.sd_rad;
    r.why = why;
    r.held = true;
    r.covariance(0, 0) = tolerance_rad_ * tolerance_rad_;
  }

 private:
  /// The mountings' M_C^S with the parameters turned by `x`.
  std::vector<Eigen::Matrix3d> moved(std::span<const procedure::TurnParameter> parameters, const Eigen::VectorXd& x) const {
    const std::vector<Eigen::Vector3d> turns = procedure::turns_of(parameters, x, m_cs_.size());
    std::vector<Eigen::Matrix3d> turned_m_cs = m_cs_;
    for (const procedure::TurnParameter& twist : parameters)
      if (twist.axis == 2) turned_m_cs[twist.mounting] = procedure::turned(m_cs_[twist.mounting], turns[twist.mounting]);
    return turned_m_cs;
  }

  const LiveSolver& solver_;
  const std::vector<const Information*>& infos_;
  std::vector<Eigen::Matrix3d>& m_cs_;
  const std::vector<Eigen::Matrix3d> start_m_cs_;   // the frames the search started from
  std::optional<double> corner_;
  double long_run_variance_factor_;
  double tolerance_rad_;
  const CaseClusters* cases_;
  std::vector<RelativeTurn>& out_;
};

}  // namespace

void LiveSolver::turn_derivative_transforms(const StatFit& at, std::span<const procedure::TurnParameter> parameters, std::size_t m,
                                            const Eigen::Matrix3d& m_cs, const CornerWeights& weights, double step,
                                            Eigen::MatrixXd& with_b, Eigen::MatrixXd& with_f) const {
  const auto p = static_cast<Index>(at.terms.size()), q = static_cast<Index>(parameters.size());
  const Eigen::VectorXd coefficients = signed_theta(at);
  Eigen::MatrixXd tb, tf, up_b, up_f, down_b, down_f;
  basis_.transform(at.terms, m_cs, weights.filtered(), tb, tf);
  with_b = Eigen::MatrixXd::Zero(p + q, tb.cols());
  with_f = Eigen::MatrixXd::Zero(p + q, tf.cols());
  with_b.topRows(p) = tb;
  with_f.topRows(p) = tf;
  for (Index i = 0; i < q; ++i) {
    const procedure::TurnParameter& parameter = parameters[static_cast<std::size_t>(i)];
    if (parameter.mounting != m) continue;
    Eigen::Vector3d turn = Eigen::Vector3d::Zero();
    turn(parameter.axis) = step;
    basis_.transform(at.terms, procedure::turned(m_cs, turn), weights.filtered(), up_b, up_f);
    basis_.transform(at.terms, procedure::turned(m_cs, -turn), weights.filtered(), down_b, down_f);
    with_b.row(p + i) = coefficients.transpose() * (up_b - down_b) / (2.0 * step);
    if (tf.cols() > 0) with_f.row(p + i) = coefficients.transpose() * (up_f - down_f) / (2.0 * step);
  }
}

Eigen::MatrixXd LiveSolver::turn_derivative_gram(const StatFit& at, std::span<const procedure::TurnParameter> parameters,
                                                  const std::vector<const Information*>& infos,
                                                  const std::vector<Eigen::Matrix3d>& m_cs, double step) const {
  const auto p = static_cast<Index>(at.terms.size()), q = static_cast<Index>(parameters.size());
  const CornerWeights weights = at.corner_rad_s ? grid_.at(*at.corner_rad_s) : CornerWeights{};
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(p + q + 1, p + q + 1);
  Eigen::MatrixXd with_b, with_f;
  for (std::size_t m = 0; m < infos.size(); ++m) {
    if (infos[m]->samples() == 0) continue;
    turn_derivative_transforms(at, parameters, m, m_cs[m], weights, step, with_b, with_f);
    g += infos[m]->model_gram(with_b, with_f, weights);
  }
  return g;
}

std::vector<RelativeTurn> LiveSolver::relative_turns(const std::vector<const Information*>& infos,
                                                     std::vector<Eigen::Matrix3d>& m_cs, std::size_t reference,
                                                     const std::vector<bool>& aligned,
                                                     const std::vector<std::array<bool, 2>>& tilts_determined,
                                                     std::optional<double> corner, const CaseClusters* cases) const {
  std::vector<RelativeTurn> out(m_cs.size());
  const bool cross = std::any_of(model_.begin(), model_.end(), [&](Index t) {
    const Term& term = basis_.terms()[static_cast<std::size_t>(t)];
    return term.uses(Variable::Ap) || term.uses(Variable::Ao);
  });
  if (!options_.relative_twist || sensor_ != dataset::SensorKind::Accelerometer || !cross) return out;
  std::vector<std::size_t> turning;
  for (std::size_t k = 0; k < m_cs.size(); ++k)
    if (k != reference && aligned[k] && infos[k]->samples() > 0) turning.push_back(k);
  StatisticsTurns statistics(*this, infos, m_cs, corner, options_.long_run_variance_factor, options_.mounting_tolerance_rad, cases, out);
  procedure::search_turns(statistics, std::move(turning), tilts_determined, options_.mounting_tolerance_rad);
  return out;
}

void LiveSolver::add_misalignment_uncertainty(StatFit& batch, const std::vector<const Information*>& infos,
                                              const std::vector<Eigen::Matrix3d>& m_cs,
                                              const std::vector<Eigen::Matrix3d>& angle_covariances,
                                              const std::vector<std::array<bool, 3>>& held) const {
  if (!batch.ok) return;
  const auto p = static_cast<Index>(batch.terms.size());
  Eigen::MatrixXd added = Eigen::MatrixXd::Zero(p, p);
  const auto response = [&](const std::vector<Eigen::Matrix3d>& moved) -> std::optional<Eigen::VectorXd> {
    const StatFit f = fit_batch_at(infos, moved, batch.corner_rad_s);
    if (!f.ok || f.terms != batch.terms) return std::nullopt;
    return f.theta;
  };
  for (std::size_t m = 0; m < m_cs.size(); ++m) {
    if (infos[m]->samples() == 0 || !angle_covariances[m].allFinite()) continue;
    Eigen::Matrix3d estimated = angle_covariances[m];
    for (int k = 0; k < 3; ++k) {
      if (!held[m][static_cast<std::size_t>(k)]) continue;
      estimated.row(k).setZero();
      estimated.col(k).setZero();
      const std::optional<Eigen::VectorXd> d = procedure::held_angle_response(
          batch.theta, k, options_.mounting_tolerance_rad, [&](const Eigen::Vector3d& turn) {
            std::vector<Eigen::Matrix3d> moved = m_cs;
            moved[m] = procedure::turned(m_cs[m], turn);
            return response(moved);
          });
      if (d) added.noalias() += *d * d->transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(estimated);
    for (int k = 0; k < 3; ++k) {
      const double lambda = eig.eigenvalues()(k);
      if (!(lambda > 0.0)) continue;
      const Eigen::Vector3d step = std::sqrt(lambda) * eig.eigenvectors().col(k);
      // The step turns M_C^S in its own frame (about o, -about p, about i: procedure::turned), so a
      // turn about i is about n_i itself. Added to M_C^S's rotation vector in case axes instead, a
      // twist's large variance (a degree) leaked into the tilts and inflated the sd of every term.
      const Eigen::Vector3d turn = procedure::turn_angles() * step;
      std::vector<Eigen::Matrix3d> plus = m_cs, minus = m_cs;
      plus[m] = procedure::turned(m_cs[m], turn);
      minus[m] = procedure::turned(m_cs[m], -turn);
      const std::optional<Eigen::VectorXd> a = response(plus), b = response(minus);
      if (!a || !b) continue;
      const Eigen::VectorXd d = 0.5 * (*a - *b);
      added.noalias() += d * d.transpose();
    }
  }
  batch.covariance += added;
  batch.sd = batch.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

Eigen::VectorXd LiveSolver::prediction_signs(const std::vector<Index>& terms) const {
  std::vector<Index> output_multiplied;
  for (std::size_t j = 0; j < terms.size(); ++j)
    if (basis_.terms()[static_cast<std::size_t>(terms[j])].is_output_multiplied()) output_multiplied.push_back(static_cast<Index>(j));
  return ident::linear_form_signs(static_cast<Index>(terms.size()), output_multiplied);
}

namespace {

/// The batch's ident::ColouredNoise on the clusters' sums: X = Z M' + W, M the clusters' column
/// means, W what varies within them. The noise's colour lies below the frequencies W holds, so W
/// meets it as white (sigma2) and is orthogonal to the clusters' indicators:
///   X'RZ = M C,  X'RX = M C M' + sigma2 W'W,  W'W = X'X - S N^-1 S',  M = S N^-1,
/// C = Z'RZ block diagonal over the cases (`run_noise`, per case its runs', per unit variance of
/// the noise: C = sigma2 times the block). White noise (C = sigma2 N) gives back sigma2 X'X and
/// sigma2 S. None when a case has no blocks.
std::optional<ident::ColouredNoise> coloured_noise(const ident::ClusterSums& sums,
                                                   const std::vector<std::pair<std::size_t, std::size_t>>& origin,
                                                   const std::vector<Eigen::MatrixXd>& run_noise, const Eigen::MatrixXd& xtx,
                                                   double sigma2) {
  const auto g_count = static_cast<Index>(origin.size());
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(g_count, g_count);
  for (Index a = 0; a < g_count; ++a) {
    const auto [case_a, run_a] = origin[static_cast<std::size_t>(a)];
    if (case_a >= run_noise.size()) return std::nullopt;
    const Eigen::MatrixXd& block = run_noise[case_a];
    if (block.rows() <= static_cast<Index>(run_a)) return std::nullopt;
    for (Index b = 0; b < g_count; ++b) {
      const auto [case_b, run_b] = origin[static_cast<std::size_t>(b)];
      if (case_b == case_a) c(a, b) = sigma2 * block(static_cast<Index>(run_a), static_cast<Index>(run_b));
    }
  }
  const Eigen::MatrixXd means = sums.columns * sums.rows.cwiseInverse().asDiagonal();   // M (p x G)
  ident::ColouredNoise out;
  out.cluster_ids = sums.ids;
  out.sums_covariance = c;
  out.cross = means * c;
  out.meat = means * c * means.transpose() + sigma2 * (xtx - means * sums.columns.transpose());
  out.meat = 0.5 * (out.meat + out.meat.transpose()).eval();
  return out;
}

}  // namespace

LiveSolver::RunSums LiveSolver::run_sums(const std::vector<const Information*>& cases, const std::vector<Eigen::Matrix3d>& m_cs,
                                         double noise_gain, const Eigen::VectorXd& sign, const Eigen::VectorXd& theta,
                                         const CornerWeights& weights, const CaseTransform& transform) const {
  const auto p = sign.size();
  std::vector<Eigen::VectorXd> column_sums;
  std::vector<double> output_sums, residual_sums, rows, loading;
  RunSums out;
  out.gram = Eigen::MatrixXd::Zero(p + 1, p + 1);
  Eigen::MatrixXd tb, tf;
  for (std::size_t c = 0; c < cases.size(); ++c) {
    if (cases[c]->samples() == 0) continue;
    transform(c, tb, tf);
    out.gram += cases[c]->model_gram(tb, tf, weights);
    out.weight += cases[c]->weight();
    const Eigen::Vector3d input_axis = m_cs[c].row(0).transpose();
    for (std::size_t r = 0; r < cases[c]->runs(); ++r) {
      const double n = static_cast<double>(cases[c]->run_samples(r));
      if (n < 1.0) continue;
      // The run's sums of the whitened columns and output (the constant is A(1) on every row).
      Eigen::VectorXd v = cases[c]->run_constant_products(r, tb, tf, weights) / noise_gain;
      v.head(p).array() *= sign.array();
      column_sums.push_back(v.head(p));
      output_sums.push_back(v(p));
      residual_sums.push_back(v(p) - theta.dot(v.head(p)));
      rows.push_back(n);
      out.origin.emplace_back(c, r);
      // The input across the sensitive axis, squared, on the run's mean: |u|^2 - (n_i . u)^2.
      const Eigen::Matrix4d& u = cases[c]->run_input_gram(r);
      loading.push_back(u(3, 3) > 0.0 ? (u.topLeftCorner<3, 3>().trace() - input_axis.dot(u.topLeftCorner<3, 3>() * input_axis)) / u(3, 3)
                                      : 0.0);
    }
  }
  const auto g_count = static_cast<Index>(rows.size());
  out.sums.columns.resize(p, g_count);
  out.sums.residuals.resize(g_count);
  out.sums.rows.resize(g_count);
  out.sums.loading.resize(g_count);
  out.output_sums.resize(g_count);
  for (Index g = 0; g < g_count; ++g) {
    out.sums.ids.push_back(static_cast<int>(g));
    out.sums.columns.col(g) = column_sums[static_cast<std::size_t>(g)];
    out.sums.residuals(g) = residual_sums[static_cast<std::size_t>(g)];
    out.sums.rows(g) = rows[static_cast<std::size_t>(g)];
    out.sums.loading(g) = loading[static_cast<std::size_t>(g)];
    out.output_sums(g) = output_sums[static_cast<std::size_t>(g)];
  }
  Eigen::VectorXd signs = Eigen::VectorXd::Ones(p + 1);
  signs.head(p) = sign;
  out.gram = signs.asDiagonal() * out.gram * signs.asDiagonal();
  return out;
}

std::optional<Eigen::MatrixXd> LiveSolver::turn_covariance(const StatFit& at, std::span<const procedure::TurnParameter> parameters,
                                                           const CaseClusters& cases, const std::vector<Eigen::Matrix3d>& m_cs,
                                                           double step) const {
  if (!(cases.noise_gain > 0.0)) return std::nullopt;
  const auto p = static_cast<Index>(at.terms.size()), q = static_cast<Index>(parameters.size());
  const CornerWeights weights = at.corner_rad_s ? grid_.at(*at.corner_rad_s) : CornerWeights{};
  // The derivatives are the mountings': each mounting's transforms once, read by each of its cases.
  std::vector<Eigen::MatrixXd> with_b(m_cs.size()), with_f(m_cs.size());
  std::vector<bool> made(m_cs.size(), false);
  std::vector<Eigen::Matrix3d> case_m_cs;
  for (const std::size_t m : cases.mountings) case_m_cs.push_back(m_cs[m]);
  // The derivatives join the columns with coefficient 0: their sign is the prediction's.
  Eigen::VectorXd sign = Eigen::VectorXd::Ones(p + q), theta = Eigen::VectorXd::Zero(p + q);
  sign.head(p) = prediction_signs(at.terms);
  theta.head(p) = at.theta;
  const RunSums sums = run_sums(cases.infos, case_m_cs, cases.noise_gain, sign, theta, weights,
                                [&](std::size_t c, Eigen::MatrixXd& tb, Eigen::MatrixXd& tf) {
                                  const std::size_t m = cases.mountings[c];
                                  if (!made[m]) turn_derivative_transforms(at, parameters, m, m_cs[m], weights, step, with_b[m], with_f[m]);
                                  made[m] = true;
                                  tb = with_b[m];
                                  tf = with_f[m];
                                });
  if (sums.sums.rows.size() < 2) return std::nullopt;
  const double sigma2 = options_.long_run_variance_factor * at.s2;
  const std::optional<ident::ColouredNoise> coloured =
      cases.run_noise.empty() ? std::nullopt : coloured_noise(sums.sums, sums.origin, cases.run_noise, sums.gram.topLeftCorner(p + q, p + q), sigma2);
  const ident::ClusterOffsets offsets =
      ident::cluster_offsets(sums.sums, ident::GramFactor::from_gram(sums.gram.topLeftCorner(p + q, p + q), sums.weight), sigma2,
                             cases.angles_from_means, coloured ? &*coloured : nullptr);
  return Eigen::MatrixXd(offsets.covariance.bottomRightCorner(q, q));
}

CaseScatter LiveSolver::add_case_scatter(StatFit& batch, const std::vector<const Information*>& cases,
                                         const std::vector<Eigen::Matrix3d>& m_cs, double noise_gain,
                                         int angles_from_means, const std::vector<Eigen::MatrixXd>* run_noise) const {
  CaseScatter out;
  if (!batch.ok || !(noise_gain > 0.0)) return out;
  const auto p = static_cast<Index>(batch.terms.size());
  const CornerWeights weights = batch.corner_rad_s ? grid_.at(*batch.corner_rad_s) : CornerWeights{};
  // The columns in the linear form of the fit, as batch.theta and batch.covariance take them.
  const Eigen::VectorXd sign = prediction_signs(batch.terms);
  const RunSums run = run_sums(cases, m_cs, noise_gain, sign, batch.theta, weights,
                               [&](std::size_t c, Eigen::MatrixXd& tb, Eigen::MatrixXd& tf) {
                                 basis_.transform(batch.terms, m_cs[c], weights.filtered(), tb, tf);
                               });
  const ident::ClusterSums& sums = run.sums;
  const Eigen::MatrixXd& gram = run.gram;
  const double weight = run.weight;
  const auto g_count = sums.rows.size();
  out.clusters = static_cast<int>(g_count);
  const std::vector<bool> phase_level = ident::phase_level_columns(sums, gram.diagonal().head(p));
  for (Index j = 0; j < p; ++j)
    if (phase_level[static_cast<std::size_t>(j)]) out.phase_level.push_back(batch.terms[static_cast<std::size_t>(j)]);
  if (g_count < 2) return out;
  const double sigma2 = options_.long_run_variance_factor * batch.s2;
  const std::optional<ident::ColouredNoise> coloured =
      run_noise != nullptr ? coloured_noise(sums, run.origin, *run_noise, gram.topLeftCorner(p, p), sigma2) : std::nullopt;
  const ident::ClusterOffsets offsets = ident::cluster_offsets(sums, ident::GramFactor::from_gram(gram.topLeftCorner(p, p), weight),
                                                               sigma2, angles_from_means, coloured ? &*coloured : nullptr);
  out.offsets = offsets;
  out.dof = offsets.between_dof;
  out.tau2 = offsets.tau2 / (noise_gain * noise_gain);
  const bool offsets_found = out.dof >= 1 && offsets.tau2 > 0.0;
  // When every column is constant within the clusters (static poses) and no column is the output's,
  // the clusters' means are weighed by what their offsets leave of them, as the batch weighs them
  // (ident::weighed_by_offsets); otherwise least squares with the offsets' sandwich.
  const bool means_only =
      (sign.array() > 0.0).all() && std::all_of(phase_level.begin(), phase_level.end(), [](bool b) { return b; });
  std::optional<ident::RandomEffectsFit> weighed;
  if (offsets_found && means_only) {
    const Eigen::VectorXd& y_sums = run.output_sums;
    const Eigen::VectorXd noise_sums = coloured ? Eigen::VectorXd(coloured->sums_covariance.diagonal()) : Eigen::VectorXd(sigma2 * sums.rows);
    weighed = ident::weighed_by_offsets(offsets, sums.loading, noise_sums, [&](const Eigen::VectorXd& tau2) {
      return ident::random_effects_fit(gram, sums, y_sums, p, tau2, sigma2, coloured ? &coloured->sums_covariance : nullptr);
    });
  }
  // What the offsets (or the weighing) and the noise's colour make of the fit's own covariance,
  // as the batch does; the fit's own is ULS's corrected one where a column is the output's.
  if (weighed) {
    batch.theta = weighed->theta;
    batch.covariance += weighed->covariance - offsets.classical;
    out.weighed = true;
    out.offsets.within = weighed->within.topLeftCorner(p, p);
    out.offsets.covariance = weighed->covariance.topLeftCorner(p, p);
    out.offsets.weights = weighed->weights;
  } else {
    batch.covariance += offsets.covariance - offsets.classical;
  }
  batch.sd = batch.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  return out;
}

StatFit LiveSolver::fit_batch(const std::vector<const Information*>& infos, const std::vector<Eigen::Matrix3d>& m_cs) const {
  double weight = 0.0;
  for (const Information* i : infos) weight += i->weight();
  if (weight <= 0.0) {
    StatFit none;
    none.why = "no samples";
    return none;
  }
  return best_corner([&](std::optional<double> b) {
    StatFit f = fit(gram(model_, infos, m_cs, b), weight, model_, infos, m_cs);
    f.corner_rad_s = b;
    return f;
  });
}

std::vector<Index> LiveSolver::select(const StatFit& batch, const std::vector<const Information*>& infos,
                                      const std::vector<Eigen::Matrix3d>& m_cs) const {
  if (!batch.ok) return batch.terms;
  ident::NormalEquations equations =
      this->equations(gram(batch.terms, infos, m_cs, batch.corner_rad_s), batch.weight, batch.terms, infos, m_cs);
  double difference_weight = 0.0;
  for (const Information* info : infos) difference_weight += info->difference_weight();
  equations.set_successive_differences(gram(batch.terms, infos, m_cs, batch.corner_rad_s, true),
                                       static_cast<Index>(std::llround(difference_weight)));
  ident::IdentifiableRanking ranking = ident::rank_identifiable(equations, sensor_);
  std::vector<Index> kept;
  for (const Index j : ident::sensitivities_then_bias(equations.labels(), sensor_))
    if (std::find(ranking.order.begin(), ranking.order.end(), j) != ranking.order.end()) kept.push_back(j);
  ident::SelectionOptions options;
  options.alpha = options_.structure_alpha;
  options.uls = options_.uls;
  const ident::SelectionResult selected = ident::select_model(equations, std::move(ranking.order), kept, options);
  std::vector<Index> out;
  for (const Index c : selected.best_model().columns) out.push_back(batch.terms[static_cast<std::size_t>(c)]);
  return out;
}

std::vector<CandidateStat> LiveSolver::structure(const std::vector<Index>& candidates, const StatFit& batch,
                                                 const std::vector<const Information*>& infos,
                                                 const std::vector<Eigen::Matrix3d>& m_cs) const {
  std::vector<CandidateStat> out;
  if (!batch.ok || candidates.empty()) return out;
  std::vector<Index> terms = batch.terms;
  terms.insert(terms.end(), candidates.begin(), candidates.end());
  const Eigen::MatrixXd g = gram(terms, infos, m_cs, batch.corner_rad_s);
  const auto p = static_cast<Index>(batch.terms.size());
  const Index y = g.rows() - 1;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(g.topLeftCorner(p, p));
  const Eigen::VectorXd bm = g.col(y).head(p);
  // The output's energy about its mean (the bias alone), the reference of the ERR.
  double reference = g(y, y);
  if (const auto b = std::find(terms.begin(), terms.end(), bias_); bias_ >= 0 && b != terms.end()) {
    const auto j = static_cast<Index>(b - terms.begin());
    if (g(j, j) > 0.0) reference -= g(j, y) * g(j, y) / g(j, j);
  }
  const double dof = batch.weight - static_cast<double>(p) - 1.0;
  const double alpha = ident::family_threshold(options_.structure_alpha, candidates.size());
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const Index j = p + static_cast<Index>(c);
    CandidateStat s;
    s.term = candidates[c];
    const Eigen::VectorXd gmc = g.col(j).head(p);
    const Eigen::VectorXd v = ldlt.solve(gmc);
    const double d = g(j, j) - gmc.dot(v);
    if (!(d > 1e-10 * g(j, j)) || dof <= 0.0) {
      s.t = kNaN;   // in the span of the model's columns, or no excitation: nothing to tell
      s.value = kNaN;
      s.sd = kNaN;
      out.push_back(s);
      continue;
    }
    const double r = g(j, y) - v.dot(bm);
    s.value = r / d;
    const double gain = r * r / d;
    s.err = reference > 0.0 ? gain / reference : 0.0;
    const double s2 = std::max(batch.rss - gain, 0.0) / dof;
    s.sd = std::sqrt(options_.long_run_variance_factor * s2 / d);
    s.t = s.sd > 0.0 ? s.value / s.sd : kNaN;
    s.p_value = std::isfinite(s.t) ? ident::student_t_two_sided_p(s.t, dof) : 1.0;
    s.significant = s.p_value < alpha;
    out.push_back(s);
  }
  return out;
}

}  // namespace inertia::online
