#include "analyzer/online/online_estimator.hpp"

#include <algorithm>
#include <cmath>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;
using ident::Term;
using ident::Variable;

Term plain(Variable v, int power = 1) {
  return Term::from_factors({ident::Factor{v, 0, ident::FactorFunction::Plain, power}});
}
Term product(Variable a, Variable b) {
  return Term::from_factors({ident::Factor{a}, ident::Factor{b}});
}

Index position(const std::vector<Term>& terms, const Term& t) {
  const auto it = std::find(terms.begin(), terms.end(), t);
  return it == terms.end() ? -1 : static_cast<Index>(it - terms.begin());
}

// Rows [from, from + count) of a case, as a case of their own (a_e, w_e, temp, y; the rest copied).
void append_rows(const dataset::CaseData& src, Index from, Index count, dataset::CaseData& dst) {
  const Index old = dst.y.size();
  dst.y.conservativeResize(old + count);
  dst.y.segment(old, count) = src.y.segment(from, count);
  dst.a_e.conservativeResize(old + count, Eigen::NoChange);
  dst.a_e.middleRows(old, count) = src.a_e.middleRows(from, count);
  if (src.w_e) {
    if (!dst.w_e) dst.w_e = dataset::Matrix3Columns(old, 3);
    dst.w_e->conservativeResize(old + count, Eigen::NoChange);
    dst.w_e->middleRows(old, count) = src.w_e->middleRows(from, count);
  } else {
    dst.w_e.reset();
  }
  if (src.temp) {
    if (!dst.temp) dst.temp = Eigen::VectorXd(old);
    dst.temp->conservativeResize(old + count);
    dst.temp->segment(old, count) = src.temp->segment(from, count);
  } else {
    dst.temp.reset();
  }
  dst.t.conservativeResize(old + count);
  dst.t.segment(old, count) = src.t.size() == src.y.size() ? Eigen::VectorXd(src.t.segment(from, count))
                                                          : Eigen::VectorXd::Zero(count);
}

}  // namespace

std::vector<Term> OnlineEstimator::default_terms(dataset::SensorKind sensor) {
  if (sensor == dataset::SensorKind::Gyroscope) {
    // Bias, scale factor and the g-sensitivity of eq. 5 (static part).
    return {Term(), plain(Variable::Wi), plain(Variable::Ai), plain(Variable::Ap), plain(Variable::Ao)};
  }
  // The paper's complete static model (eq. 4, r = 0, table 3's case 3).
  return {Term(),
          plain(Variable::Ai),
          plain(Variable::Ai, 2),
          plain(Variable::Ap, 2),
          plain(Variable::Ao, 2),
          product(Variable::Ai, Variable::Ap),
          product(Variable::Ai, Variable::Ao),
          product(Variable::Ap, Variable::Ao)};
}

OnlineEstimator::OnlineEstimator(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model,
                                 double t_ref, const OnlineOptions& options)
    : sensor_(sensor), t_ref_(t_ref), options_(options), m_cs_(frames::Dcm::Identity()),
      uls_() {
  if (model) {
    if (model->sensor != sensor) {
      throw InputError("online: the model is for a " + std::string(dataset::to_string(model->sensor)) +
                       ", the bench's sensor is a " + dataset::to_string(sensor));
    }
    m_cs_ = model->m_cs;
    square_highpass_rad_s_ = model->square_highpass_rad_s;
    for (const model::ModelTerm& t : model->terms) terms_.push_back(t.term);
  } else {
    terms_ = default_terms(sensor);
  }
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  const Variable axis = gyro ? Variable::Wi : Variable::Ai;
  scale_term_ = position(terms_, plain(axis));
  if (scale_term_ < 0) {
    throw InputError(std::string("online: the model has no scale-factor term '") + ident::variable_name(axis) +
                     "', so no misalignment can be referred to it");
  }
  const Variable across_p = gyro ? Variable::Wp : Variable::Ap, across_o = gyro ? Variable::Wo : Variable::Ao;
  for (Variable v : {across_p, across_o}) {
    if (position(terms_, plain(v)) < 0) terms_.push_back(plain(v));
  }
  cross_p_ = position(terms_, plain(across_p));
  cross_o_ = position(terms_, plain(across_o));
  for (std::size_t j = 0; j < terms_.size(); ++j) {
    if (terms_[j].is_noise_term()) {
      throw InputError("online: term '" + terms_[j].to_string() +
                       "' is a noise lag; the live estimator does not carry residual history across gaps");
    }
    if (terms_[j].is_output_multiplied()) output_multiplied_.push_back(static_cast<Index>(j));
    max_lag_ = std::max<Index>(max_lag_, terms_[j].max_lag());
  }
  factors_.resize(static_cast<Index>(output_multiplied_.size()));
}

void OnlineEstimator::push(const dataset::CaseData& chunk, bool continues_previous) {
  const Index n = chunk.y.size();
  if (n == 0) return;
  if (chunk.a_e.rows() != n) throw InputError("online: chunk of case '" + chunk.name + "' has a_e and y of different lengths");

  // The samples the regressors see: the kept history (lagged terms), then the chunk.
  dataset::CaseData work;
  work.name = chunk.name;
  work.kind = chunk.kind;
  work.m_ec = chunk.m_ec;
  work.sample_period_s = chunk.sample_period_s;
  work.a_e.resize(0, 3);
  const bool continued = continues_previous && has_history_;
  if (continued) append_rows(history_, 0, history_.y.size(), work);
  const Index kept = work.y.size();
  append_rows(chunk, 0, n, work);

  // Keep the newest max_lag_ samples for the next chunk (a static model keeps none).
  history_ = dataset::CaseData{};
  history_.a_e.resize(0, 3);
  const Index tail = std::min<Index>(max_lag_, work.y.size());
  append_rows(work, work.y.size() - tail, tail, history_);
  has_history_ = true;
  if (!continued) highpass_state_.resize(0);

  const Index first_row = continued ? kept : std::min<Index>(max_lag_, work.y.size());
  if (work.y.size() <= first_row) return;
  const Eigen::Matrix3d m_es = m_cs_ * chunk.m_ec;
  const ident::SignalSet signals = ident::signals_from_case(work, m_es, t_ref_, "live stream");
  ident::check_signals(terms_, signals);
  const Index rows = work.y.size() - first_row;
  Eigen::MatrixXd phi(rows, static_cast<Index>(terms_.size()));
  ident::fill_regressors(terms_, signals, first_row, phi);

  if (square_highpass_rad_s_) {
    // One filter memory per square column, continued across chunks of one case.
    if (highpass_state_.size() == 0) highpass_state_ = Eigen::VectorXd::Constant(3 * static_cast<Index>(terms_.size()), NAN);
    for (std::size_t j = 0; j < terms_.size(); ++j) {
      if (!procedure::is_square_term(terms_[j])) continue;
      const Index s = 3 * static_cast<Index>(j);
      procedure::HighpassState state;
      if (!std::isnan(highpass_state_(s))) state = {highpass_state_(s), highpass_state_(s + 1), true};
      procedure::highpass_in_place(phi.col(static_cast<Index>(j)), *square_highpass_rad_s_, chunk.sample_period_s, state);
      highpass_state_(s) = state.previous_input;
      highpass_state_(s + 1) = state.output;
    }
  }

  Eigen::MatrixXd factor_values;
  if (!output_multiplied_.empty()) {
    std::vector<Term> factor_terms;
    for (Index j : output_multiplied_) factor_terms.push_back(terms_[static_cast<std::size_t>(j)].denominator_factor());
    factor_values.resize(rows, static_cast<Index>(factor_terms.size()));
    ident::fill_regressors(factor_terms, signals, first_row, factor_values);
  }
  if (!uls_) {
    // RMS of each column over these first rows; a column still zero (a dwell: a_p = 0) gets 1.
    Eigen::VectorXd scale = (phi.colwise().squaredNorm() / static_cast<double>(rows)).cwiseSqrt().transpose();
    for (Index j = 0; j < scale.size(); ++j) {
      if (!(scale(j) > 0.0) || !std::isfinite(scale(j))) scale(j) = 1.0;
    }
    uls_.emplace(static_cast<Index>(terms_.size()), output_multiplied_, options_.uls, scale);
  }
  const Eigen::VectorXd& y = signals.get(Variable::Y);
  for (Index r = 0; r < rows; ++r) {
    if (!output_multiplied_.empty()) factors_ = factor_values.row(r).transpose();
    uls_->update(phi.row(r).transpose(), y(first_row + r), factors_);
  }
}

OnlineSnapshot OnlineEstimator::snapshot() {
  OnlineSnapshot s;
  for (const Term& t : terms_) s.terms.push_back(t.to_string());
  s.samples_used = uls_ ? uls_->samples() : 0;
  if (s.samples_used == 0) {
    s.values = Eigen::VectorXd::Zero(static_cast<Index>(terms_.size()));
    s.std_devs = Eigen::VectorXd::Constant(static_cast<Index>(terms_.size()), INFINITY);
    return s;
  }
  const ident::RecursiveEstimate e = uls_->estimate();
  const Index p = static_cast<Index>(terms_.size());
  s.values = e.theta.head(p);
  s.std_devs = e.std_dev.head(p);
  s.residual_variance = e.residual_variance;
  // Small-angle rotation of the sensitive axis from M_C^S: the output picks up K (theta_o a_p -
  // theta_p a_o) when the axis tilts by theta_o towards p and theta_p away from o.
  const double k = s.values(scale_term_);
  s.misalignment_rad = Eigen::Vector3d(0.0, -s.values(cross_o_) / k, s.values(cross_p_) / k);

  // Judged on the newest data only: a snapshot without new samples keeps the previous verdict
  // (time passing proves nothing), one with new samples compares with the estimate before them.
  if (s.samples_used != previous_samples_) {
    const bool enough = s.samples_used >= static_cast<std::int64_t>(options_.min_samples_per_term) * p;
    bool settled = previous_values_.has_value();
    if (settled) {
      for (Index j = 0; j < p; ++j) {
        const double moved = std::abs(s.values(j) - (*previous_values_)(j));
        if (!(moved <= options_.converged_sigmas * s.std_devs(j))) settled = false;
      }
    }
    converged_ = enough && settled;
    previous_values_ = s.values;
    previous_samples_ = s.samples_used;
  }
  s.converged = converged_;
  return s;
}

}  // namespace inertia::online
