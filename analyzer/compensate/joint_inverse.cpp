#include "analyzer/compensate/joint_inverse.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::compensate {

using Eigen::Index;
using ident::Variable;

namespace {

constexpr int kStill = -1, kNonlinear = -2;

/// The row of `variable` among an equation's solved inputs, or -1 where it is known.
int solved_index(const JointEquation& e, Variable variable) {
  for (std::size_t s = 0; s < e.solved.size(); ++s) {
    if (e.solved[s].first == variable) return static_cast<int>(s);
  }
  return -1;
}

}  // namespace

JointInverse::JointInverse(std::vector<JointEquation> equations, std::vector<Eigen::VectorXd> fallback_starts)
    : equations_(std::move(equations)), fallback_starts_(std::move(fallback_starts)) {
  unknowns_ = static_cast<Index>(equations_.size());
  if (unknowns_ != 1 && unknowns_ != 3 && unknowns_ != 6)
    throw std::invalid_argument(fmt::format("a joint inverse solves 1, 3 or 6 equations, not {}", unknowns_));
  tolerance_scale_ = 0.0;
  for (const JointEquation& e : equations_) {
    if (e.model == nullptr) throw std::invalid_argument("a joint equation without its model");
    for (const auto& [variable, row] : e.solved) {
      if (row.size() != unknowns_)
        throw std::invalid_argument(fmt::format("the row of {} has {} entries for {} unknowns", ident::variable_name(variable), row.size(), unknowns_));
    }
    bool reads_solved_now = false;
    for (const InverseModel::CompiledTerm& t : e.model->terms()) {
      int solved_factors = 0;
      for (const ident::Factor& f : t.factors) {
        if (solved_index(e, f.variable) < 0) continue;
        reads_solved_now = reads_solved_now || f.lag == 0;
        ++solved_factors;
        linear_ = linear_ && f.function == ident::FactorFunction::Plain && f.power == 1;
      }
      linear_ = linear_ && solved_factors <= 1 && !(t.square_filtered && solved_factors > 0);
    }
    if (!reads_solved_now) throw std::invalid_argument("a joint equation reads none of the unknowns at the current sample");
    first_row_ = std::max(first_row_, e.model->first_row());
    tolerance_scale_ = std::max(tolerance_scale_, e.model->tolerance_scale());
  }
  for (const Eigen::VectorXd& start : fallback_starts_) {
    if (start.size() != unknowns_) throw std::invalid_argument("a fallback start of another length than the unknowns");
  }
}

JointCompensation JointInverse::compensate(const std::vector<const ident::SignalSet*>& records, double sample_period_s,
                                           const CompensationOptions& options) const {
  if (records.size() != equations_.size())
    throw std::invalid_argument(fmt::format("{} records for {} equations", records.size(), equations_.size()));
  switch (unknowns_) {
    case 1: return solve<1>(records, sample_period_s, options);
    case 3: return solve<3>(records, sample_period_s, options);
    default: return solve<6>(records, sample_period_s, options);
  }
}

template <int D>
JointCompensation JointInverse::solve(const std::vector<const ident::SignalSet*>& records, double sample_period_s,
                                      const CompensationOptions& options) const {
  using Vector = Eigen::Matrix<double, D, 1>;
  using Matrix = Eigen::Matrix<double, D, D>;
  struct Factor {
    ident::Factor factor;
    int solved = -1;                 // the row it is read through, -1 where known
    const double* known = nullptr;   // a known input's samples
    // It moves with the sample's x on rows r < moving_until: a solved input now, or a lagged one
    // before its first estimate (the settled start).
    Index moving_until = 0;
  };
  struct Term {
    std::vector<Factor> factors;
    double coefficient = 0.0;
    bool denominator = false, square_filtered = false;
  };
  // The range checks as flat bounds: a solved input (through its row) or a known one.
  struct Bound {
    int solved = -1;
    const Eigen::VectorXd* column = nullptr;
    double lowest = 0.0, highest = 0.0;
  };
  struct Equation {
    std::vector<Term> terms;
    std::vector<Vector> rows;
    std::vector<double> solved_value;   // each row . x at the point evaluated
    std::array<const Eigen::VectorXd*, ident::kVariableCount> column{};
    const Eigen::VectorXd* y = nullptr;
    const Eigen::MatrixXd* covariance = nullptr;
    double noise_sd = 0.0;
    procedure::HighpassCoefficients highpass{};
    std::vector<Bound> bounds;
    std::vector<double> known, h_previous, in_previous, value;   // per term
    // Per term, how it moves with x at this sample: kStill (no factor does), the row of its one
    // moving factor when that is plain and of power 1 (the term is known times row . x), or
    // kNonlinear.
    std::vector<int> mover;
    std::vector<Vector> slope;                                   // per term, d value / d x (not kept for kStill)
    std::vector<std::size_t> filtered;                           // the terms through the squares' high pass
    Eigen::VectorXd dg_dc;
    double g = 0.0, denominator = 1.0;
  };

  const Index n = records.front()->size();
  std::vector<Equation> eqs(equations_.size());
  for (std::size_t m = 0; m < equations_.size(); ++m) {
    const JointEquation& source = equations_[m];
    const InverseModel& model = *source.model;
    const ident::SignalSet& record = *records[m];
    if (record.size() != n)
      throw InputError(fmt::format("the records to compensate together differ in length: {} has {} samples, {} has {}",
                                   records.front()->origin(), n, record.origin(), record.size()));
    Equation& e = eqs[m];
    for (std::size_t v = 0; v < static_cast<std::size_t>(ident::kVariableCount); ++v) {
      const auto variable = static_cast<Variable>(v);
      const bool needed = variable == Variable::Y || (model.known_inputs().test(v) && solved_index(source, variable) < 0);
      if (needed && !record.has(variable)) {
        throw InputError(fmt::format("compensation needs '{}' ({}), which {} lacks", ident::variable_name(variable),
                                     ident::source_of(variable), record.origin().empty() ? "the record" : record.origin()));
      }
      if (solved_index(source, variable) < 0 && record.has(variable)) e.column[v] = &record.get(variable);
    }
    e.y = &record.get(Variable::Y);
    for (const auto& [variable, row] : source.solved) e.rows.push_back(row.transpose());
    e.solved_value.assign(e.rows.size(), 0.0);
    for (const InverseModel::CompiledTerm& t : model.terms()) {
      Term term{{}, t.coefficient, t.denominator, t.square_filtered};
      for (const ident::Factor& f : t.factors) {
        const int solved = solved_index(source, f.variable);
        const Eigen::VectorXd* column = e.column[static_cast<std::size_t>(f.variable)];
        const Index moving_until = solved < 0 ? 0 : (f.lag == 0 ? std::numeric_limits<Index>::max() : f.lag);
        term.factors.push_back({f, solved, solved < 0 && column != nullptr ? column->data() : nullptr, moving_until});
      }
      e.terms.push_back(std::move(term));
    }
    e.covariance = &model.covariance();
    e.noise_sd = model.noise_sd();
    if (std::any_of(e.terms.begin(), e.terms.end(), [](const Term& t) { return t.square_filtered; })) {
      if (!(sample_period_s > 0.0)) throw std::invalid_argument("compensate: the model's square high pass needs the sample period");
      e.highpass = procedure::highpass_coefficients(*model.square_corner(), sample_period_s);
    }
    for (const auto& [variable, span] : model.range()) {
      const double margin = options.range_margin * (span.highest - span.lowest);
      const int s = solved_index(source, variable);
      if (s < 0 && e.column[static_cast<std::size_t>(variable)] == nullptr) continue;
      e.bounds.push_back({s, s < 0 ? e.column[static_cast<std::size_t>(variable)] : nullptr, span.lowest - margin, span.highest + margin});
    }
    const std::size_t t_count = e.terms.size();
    e.known.assign(t_count, 0.0);
    e.h_previous.assign(t_count, 0.0);
    e.in_previous.assign(t_count, 0.0);
    e.value.assign(t_count, 0.0);
    e.mover.assign(t_count, kStill);
    e.slope.assign(t_count, Vector::Zero());
    e.dg_dc.resize(static_cast<Index>(t_count));
    for (std::size_t t = 0; t < t_count; ++t)
      if (e.terms[t].square_filtered) e.filtered.push_back(t);
  }

  // From this row on no lagged solved input moves with the sample's x.
  Index settling_rows = 0;
  for (const Equation& e : eqs) {
    for (const Term& term : e.terms) {
      for (const Factor& f : term.factors) {
        if (f.solved >= 0 && f.factor.lag > 0) settling_rows = std::max<Index>(settling_rows, f.factor.lag);
      }
    }
  }

  JointCompensation out;
  out.first_row = first_row_;
  const Index rows = std::max<Index>(0, n - first_row_);
  out.value.resize(rows, D);
  out.u_coefficients.resize(rows, D);
  out.u_noise.resize(rows, D);
  out.flag.assign(static_cast<std::size_t>(rows), SampleFlag::Ok);
  if (rows == 0) return out;

  // The solved inputs as the lagged terms read them: each estimate, or across a sample without one
  // the last estimate held.
  Eigen::Matrix<double, Eigen::Dynamic, D> history(rows, D);
  Vector x = Vector::Zero(), last_good = Vector::Zero();
  std::vector<Vector> starts(1 + fallback_starts_.size());
  for (std::size_t s = 0; s < fallback_starts_.size(); ++s) starts[s + 1] = fallback_starts_[s];
  Vector residuals;
  Matrix jacobian, inverse;
  Matrix inverted = Matrix::Constant(std::numeric_limits<double>::quiet_NaN());   // the Jacobian `inverse` inverts

  for (Index k = first_row_; k < n; ++k) {
    const Index r = k - first_row_;
    const auto moves = [&](const Factor& f) { return r < f.moving_until; };
    // Each term's known part; while lagged solved inputs still move (the first rows), how it moves.
    const bool settled = r > settling_rows;
    for (Equation& e : eqs) {
      const std::size_t term_count = e.terms.size();
      for (std::size_t t = 0; t < term_count; ++t) {
        double product = 1.0;
        int moving = 0, mover = kStill;
        for (const Factor& f : e.terms[t].factors) {
          if (moves(f)) {
            ++moving;
            mover = f.factor.function == ident::FactorFunction::Plain && f.factor.power == 1 ? f.solved : kNonlinear;
            continue;
          }
          const Index at = k - f.factor.lag;
          const double v = f.solved >= 0 ? e.rows[static_cast<std::size_t>(f.solved)].dot(history.row(at - first_row_).transpose())
                                         : f.known[at];
          product *= factor_value(f.factor, v);
        }
        e.known[t] = product;
        if (!settled) e.mover[t] = moving > 1 ? kNonlinear : mover;
      }
    }
    // Each term's value and gradient at x. A filtered square's value is its high pass's output,
    // h(k) = p h(k-1) + g (s(k) - s(k-1)), settled (0) at the first row; then each equation's
    // residual and gradient: a denominator term's weight is -y c.
    const auto evaluate = [&](const Vector& at_x) {
      for (std::size_t m = 0; m < eqs.size(); ++m) {
        Equation& e = eqs[m];
        const double yk = (*e.y)(k);
        double g = -yk, denominator = 1.0;
        Vector gradient = Vector::Zero();
        const std::size_t term_count = e.terms.size();
        for (std::size_t s = 0; s < e.rows.size(); ++s) e.solved_value[s] = e.rows[s].dot(at_x);
        for (std::size_t t = 0; t < term_count; ++t) {
          const Term& term = e.terms[t];
          const int mover = e.mover[t];
          double v = e.known[t];
          Vector& d = e.slope[t];
          if (mover >= 0) {
            d = v * e.rows[static_cast<std::size_t>(mover)];
            v *= e.solved_value[static_cast<std::size_t>(mover)];
          } else if (mover == kNonlinear) {
            d.setZero();
            for (const Factor& f : term.factors) {
              if (!moves(f)) continue;
              double slope = 0.0;
              const double fv = factor_value_and_slope(f.factor, e.solved_value[static_cast<std::size_t>(f.solved)], slope);
              d = d * fv + (v * slope) * e.rows[static_cast<std::size_t>(f.solved)];
              v *= fv;
            }
          }
          if (term.square_filtered) {
            if (k == first_row_) {
              v = 0.0;
              d.setZero();
            } else {
              v = e.highpass.p * e.h_previous[t] + e.highpass.g * (v - e.in_previous[t]);
              d *= e.highpass.g;
            }
          }
          e.value[t] = v;
          const double weight = term.denominator ? -yk * term.coefficient : term.coefficient;
          if (term.denominator) denominator += term.coefficient * v;
          g += weight * v;
          if (mover != kStill) gradient += weight * d;
        }
        e.g = g;
        e.denominator = denominator;
        residuals(static_cast<Index>(m)) = g;
        jacobian.row(static_cast<Index>(m)) = gradient.transpose();
      }
    };
    // Newton's step and the Jacobian's inverse, or false where the Jacobian is singular or a
    // value not finite. Up to 3 unknowns the inverse is the cofactors'; 6 take an LU.
    const auto newton_step = [&](Vector& step) {
      if (!residuals.allFinite()) return false;
      if (jacobian == inverted) {   // the Jacobian of the last inverse: often every sample's (a linear unit)
        step.noalias() = inverse * residuals;
        return step.allFinite();
      }
      if (!jacobian.allFinite()) return false;
      if constexpr (D == 1) {
        if (jacobian(0, 0) == 0.0) return false;
        inverse(0, 0) = 1.0 / jacobian(0, 0);
        step(0) = residuals(0) / jacobian(0, 0);
      } else if constexpr (D <= 4) {
        double determinant = 0.0;
        bool invertible = false;
        jacobian.computeInverseAndDetWithCheck(inverse, determinant, invertible, 0.0);
        if (!invertible || !std::isfinite(determinant)) return false;
        step.noalias() = inverse * residuals;
      } else {
        const Eigen::PartialPivLU<Matrix> lu(jacobian);
        const double determinant = lu.determinant();
        if (determinant == 0.0 || !std::isfinite(determinant)) return false;
        inverse = lu.inverse();
        step.noalias() = inverse * residuals;
      }
      inverted = jacobian;
      return step.allFinite();
    };

    // Newton from the previous estimate; where it fails (a singular Jacobian, no root nearby), from
    // the fallback starts.
    starts[0] = last_good;
    bool converged = false;
    int iterations = 0;
    Vector step;
    for (const Vector& start : starts) {
      x = start;
      for (int i = 0; i < options.max_iterations; ++i) {
        ++iterations;
        evaluate(x);
        if (!newton_step(step)) break;
        x -= step;
        // Linear in the unknowns, the first step lands on the root.
        if (linear_ || step.cwiseAbs().maxCoeff() <= InverseModel::kStepTolerance * (x.cwiseAbs().maxCoeff() + tolerance_scale_)) {
          converged = true;
          break;
        }
      }
      if (converged) break;
    }
    out.most_iterations = std::max(out.most_iterations, iterations);
    // The terms' values at the root (the squares' filter state and the uncertainty read them): the
    // last evaluation's, moved the last step along their slopes. That is exact for terms linear in
    // x, and within the square of the step tolerance otherwise; the Jacobian and its inverse stay
    // the last evaluation's, to the same order.
    // With them, each value's derivative of g by its coefficient: the value, times -y for a
    // denominator term.
    if (converged) {
      for (Equation& e : eqs) {
        const double yk = (*e.y)(k);
        double denominator = 1.0;
        const std::size_t term_count = e.terms.size();
        double* dg_dc = e.dg_dc.data();
        for (std::size_t t = 0; t < term_count; ++t) {
          double v = e.value[t];
          if (e.mover[t] != kStill) v -= e.slope[t].dot(step);
          e.value[t] = v;
          if (e.terms[t].denominator) {
            denominator += e.terms[t].coefficient * v;
            v *= -yk;
          }
          dg_dc[t] = v;
        }
        e.denominator = denominator;
      }
    }
    if (!converged || !x.allFinite()) {
      out.value.row(r).setConstant(std::numeric_limits<double>::quiet_NaN());
      out.u_coefficients.row(r).setConstant(std::numeric_limits<double>::quiet_NaN());
      out.u_noise.row(r).setConstant(std::numeric_limits<double>::quiet_NaN());
      out.flag[static_cast<std::size_t>(r)] = SampleFlag::NotConverged;
      ++out.not_converged;
      history.row(r) = last_good.transpose();   // the squares' high pass keeps its state across the sample
      continue;
    }
    out.value.row(r) = x.transpose();
    history.row(r) = x.transpose();
    last_good = x;
    Vector variance_c = Vector::Zero(), variance_n = Vector::Zero();
    bool inside = true;
    for (std::size_t m = 0; m < eqs.size(); ++m) {
      Equation& e = eqs[m];
      // a' C a, C symmetric: the diagonal, then twice the lower triangle.
      const Index terms = e.dg_dc.size();
      const double* a = e.dg_dc.data();
      double quadratic = 0.0;
      for (Index i = 0; i < terms; ++i) {
        const double* column = e.covariance->data() + i * terms;
        double below = 0.0;
        for (Index j = i + 1; j < terms; ++j) below += column[j] * a[j];
        quadratic += a[i] * (column[i] * a[i] + 2.0 * below);
      }
      const Vector column_squared = inverse.col(static_cast<Index>(m)).array().square().matrix();
      const double noise = e.noise_sd * e.denominator;
      variance_c += std::max(0.0, quadratic) * column_squared;
      variance_n += (noise * noise) * column_squared;
      for (const std::size_t t : e.filtered) {
        // The filter's input at x: the square's unfiltered value.
        double s = e.known[t];
        for (const Factor& f : e.terms[t].factors) {
          if (moves(f)) s *= factor_value(f.factor, e.rows[static_cast<std::size_t>(f.solved)].dot(x));
        }
        e.h_previous[t] = e.value[t];
        e.in_previous[t] = s;
      }
      // Inside the characterized range: every solved input and every known one at this sample.
      for (const Bound& b : e.bounds) {
        const double v = b.solved >= 0 ? e.rows[static_cast<std::size_t>(b.solved)].dot(x) : (*b.column)(k);
        inside = inside && v >= b.lowest && v <= b.highest;
      }
    }
    out.u_coefficients.row(r) = variance_c.cwiseSqrt().transpose();
    out.u_noise.row(r) = variance_n.cwiseSqrt().transpose();
    if (!inside) {
      out.flag[static_cast<std::size_t>(r)] = SampleFlag::OutsideRange;
      ++out.outside_range;
    }
  }
  return out;
}

}  // namespace inertia::compensate
