#include "analyzer/compensate/joint_inverse.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "analyzer/compensate/affine_samples.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::compensate {

using Eigen::Index;
using ident::Variable;

namespace {

// How a term moves with the sample's x: kStill, kNonlinear, or the row of its one plain factor.
constexpr int kStill = -1, kNonlinear = -2;
// newton_converged's regime per unit of the scale.
const double kRegime = std::sqrt(InverseModel::kStepTolerance);

/// The row of `variable` among an equation's solved inputs, or -1 where it is known.
int solved_index(const JointEquation& e, Variable variable) {
  for (std::size_t s = 0; s < e.solved.size(); ++s) {
    if (e.solved[s].first == variable) return static_cast<int>(s);
  }
  return -1;
}

/// The inverse of `a` by Gauss-Jordan elimination with partial pivoting, the generated C's
/// invert() (joint_c_export.cpp) step for step; false where a pivot is zero or a value is not
/// finite. Fixed loops the compiler unrolls (D is at most 6), where an LU's inverse takes Eigen's
/// general blocked path.
template <int D>
bool gauss_jordan_inverse(const Eigen::Matrix<double, D, D>& a, Eigen::Matrix<double, D, D>& inverse) {
  // Row-major working copies: elimination works on rows. Of m only the columns right of the
  // pivot are read again, so only those are updated.
  std::array<std::array<double, D>, D> m{}, v{};
  for (int i = 0; i < D; ++i) {
    for (int j = 0; j < D; ++j) m[i][j] = a(i, j);
    v[i][i] = 1.0;
  }
#pragma GCC unroll 6
  for (int k = 0; k < D; ++k) {
    int p = k;
    double best = std::abs(m[k][k]);
    for (int i = k + 1; i < D; ++i) {
      if (std::abs(m[i][k]) > best) {
        best = std::abs(m[i][k]);
        p = i;
      }
    }
    if (!(best > 0.0) || !std::isfinite(best)) return false;
    if (p != k) {
      std::swap(m[k], m[p]);
      std::swap(v[k], v[p]);
    }
    const double pivot = 1.0 / m[k][k];
#pragma GCC unroll 6
    for (int j = k + 1; j < D; ++j) m[k][j] *= pivot;
#pragma GCC unroll 6
    for (int j = 0; j < D; ++j) v[k][j] *= pivot;
    for (int i = 0; i < D; ++i) {
      const double f = m[i][k];
      if (i == k || f == 0.0) continue;
#pragma GCC unroll 6
      for (int j = k + 1; j < D; ++j) m[i][j] -= f * m[k][j];
#pragma GCC unroll 6
      for (int j = 0; j < D; ++j) v[i][j] -= f * v[k][j];
    }
  }
  for (int i = 0; i < D; ++i)
    for (int j = 0; j < D; ++j) {
      if (!std::isfinite(v[i][j])) return false;
      inverse(i, j) = v[i][j];
    }
  return true;
}

/// The inverse of a 3 x 3 matrix by its cofactors; false where it is singular or the determinant
/// is not finite.
bool cofactor_inverse(const Eigen::Matrix3d& a, Eigen::Matrix3d& inverse) {
  double determinant = 0.0;
  bool invertible = false;
  a.computeInverseAndDetWithCheck(inverse, determinant, invertible, 0.0);
  return invertible && std::isfinite(determinant);
}

/// The inverse of a 6 x 6 matrix [A 0; G B] (its first three equations read none of the last
/// three unknowns: a unit's accelerometers, beside gyroscopes whose g-sensitivity reads the
/// specific force) from its diagonal blocks': [A^-1 0; -B^-1 G A^-1 B^-1].
bool block_triangular_inverse(const Eigen::Matrix<double, 6, 6>& j, Eigen::Matrix<double, 6, 6>& inverse) {
  Eigen::Matrix3d a_inverse, b_inverse;
  if (!cofactor_inverse(j.topLeftCorner<3, 3>(), a_inverse) || !cofactor_inverse(j.bottomRightCorner<3, 3>(), b_inverse))
    return false;
  inverse.topLeftCorner<3, 3>() = a_inverse;
  inverse.topRightCorner<3, 3>().setZero();
  inverse.bottomRightCorner<3, 3>() = b_inverse;
  inverse.bottomLeftCorner<3, 3>().noalias() = -(b_inverse * j.bottomLeftCorner<3, 3>()) * a_inverse;
  return inverse.allFinite();
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
  JointCompensation out;
  switch (unknowns_) {
    case 1: solve<1>(records, sample_period_s, options, out); break;
    case 3: solve<3>(records, sample_period_s, options, out); break;
    default: solve<6>(records, sample_period_s, options, out); break;
  }
  return out;
}

template <int D>
void JointInverse::solve(const std::vector<const ident::SignalSet*>& records, double sample_period_s,
                         const CompensationOptions& options, JointCompensation& out) const {
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
  using Bound = AffineEquation::Bound;
  struct Equation {
    std::vector<Term> terms;
    std::vector<Vector> rows;
    std::vector<double> solved_value;   // each row . x at the point evaluated
    std::array<const Eigen::VectorXd*, ident::kVariableCount> column{};
    const Eigen::VectorXd* y = nullptr;
    // The coefficients' covariance C as a' C a reads it, in blocks of 4 rows: each column padded
    // with zeros to a multiple of 4 rows.
    std::vector<double> covariance_padded;
    Index padded_rows = 0;
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
    // Once settled, the factors of each term's known part: its known inputs and lagged solved
    // ones, flat in term order.
    std::vector<std::pair<std::size_t, Factor>> settled_factors;
    std::vector<std::size_t> settled_terms;   // the terms with settled factors; the others' known part is 1
    // A linear system's A row and b from the terms whose known part is 1 at every sample, and
    // the other terms.
    Vector constant_a = Vector::Zero();
    double constant_b = 0.0;
    std::vector<std::size_t> varying_terms;
    // A constant Jacobian's terms of one solved factor: (term, row), dg/dc at the root row . x.
    std::vector<std::pair<std::size_t, std::size_t>> row_terms;
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
    const Eigen::MatrixXd& covariance = model.covariance();
    e.padded_rows = (covariance.rows() + 3) / 4 * 4;
    e.covariance_padded.assign(static_cast<std::size_t>(e.padded_rows * covariance.cols()), 0.0);
    for (Index j = 0; j < covariance.cols(); ++j)
      for (Index i = 0; i < covariance.rows(); ++i) e.covariance_padded[static_cast<std::size_t>(j * e.padded_rows + i)] = covariance(i, j);
    e.noise_sd = model.noise_sd();
    if (std::any_of(e.terms.begin(), e.terms.end(), [](const Term& t) { return t.square_filtered; })) {
      if (!(sample_period_s > 0.0)) throw std::invalid_argument("compensate: the model's square high pass needs the sample period");
      e.highpass = procedure::highpass_coefficients(*model.square_corner(), sample_period_s);
    }
    for (const auto& [variable, span] : model.range()) {
      const double margin = options.range_margin * (span.highest - span.lowest);
      const int s = solved_index(source, variable);
      if (s < 0 && e.column[static_cast<std::size_t>(variable)] == nullptr) continue;
      e.bounds.push_back({s, s < 0 ? e.column[static_cast<std::size_t>(variable)]->data() : nullptr, span.lowest - margin, span.highest + margin});
    }
    const std::size_t t_count = e.terms.size();
    e.known.assign(t_count, 0.0);
    e.h_previous.assign(t_count, 0.0);
    e.in_previous.assign(t_count, 0.0);
    e.value.assign(t_count, 0.0);
    e.mover.assign(t_count, kStill);
    e.slope.assign(t_count, Vector::Zero());
    e.dg_dc = Eigen::VectorXd::Zero(e.padded_rows);   // zero past the terms: C's padding
    for (std::size_t t = 0; t < t_count; ++t) {
      if (e.terms[t].square_filtered) e.filtered.push_back(t);
      for (const Factor& f : e.terms[t].factors)
        if (f.solved < 0 || f.factor.lag > 0) e.settled_factors.emplace_back(t, f);
      const bool settled_factors = !e.settled_factors.empty() && e.settled_factors.back().first == t;
      if (settled_factors) e.settled_terms.push_back(t);
      // A linear system's term of no settled factor, unfiltered and not over y, is c or c row . x
      // at every sample: summed into A and b once (a nonlinear system evaluates every term).
      if (!linear_) continue;
      const Term& term = e.terms[t];
      if (settled_factors || term.square_filtered || term.denominator) {
        e.varying_terms.push_back(t);
      } else if (term.factors.empty()) {
        e.constant_b += term.coefficient;
      } else {
        e.constant_a += term.coefficient * e.rows[static_cast<std::size_t>(term.factors.front().solved)];
        e.row_terms.emplace_back(t, static_cast<std::size_t>(term.factors.front().solved));
      }
    }
  }

  // A linear system none of whose varying terms reads a solved input has the same A at every
  // sample (a linear unit's bias, scale, cross-axis and g-sensitivity, with T in b): A and its
  // inverse are made once, and each sample only sums b.
  bool constant_jacobian = linear_;
  for (const Equation& e : eqs)
    for (const std::size_t t : e.varying_terms)
      for (const Factor& f : e.terms[t].factors) constant_jacobian = constant_jacobian && f.solved < 0;
  // Then, without squares through the high pass (whose filter state moves with x), the samples
  // are independent: b, x = -A^-1 b and the uncertainty's sums, a few samples side by side
  // (affine_samples.hpp; below, where the inverse is made).
  const bool affine_only =
      constant_jacobian && std::all_of(eqs.begin(), eqs.end(), [](const Equation& e) { return e.filtered.empty(); });

  // From this row on no lagged solved input moves with the sample's x.
  Index settling_rows = 0;
  for (const Equation& e : eqs) {
    for (const Term& term : e.terms) {
      for (const Factor& f : term.factors) {
        if (f.solved >= 0 && f.factor.lag > 0) settling_rows = std::max<Index>(settling_rows, f.factor.lag);
      }
    }
  }

  out.first_row = first_row_;
  const Index rows = std::max<Index>(0, n - first_row_);
  out.value.resize(rows, D);
  out.u_coefficients.resize(rows, D);
  out.u_noise.resize(rows, D);
  out.flag.assign(static_cast<std::size_t>(rows), SampleFlag::Ok);
  if (rows == 0) return;

  // The solved inputs as the lagged terms read them, the last settling_rows + 1 in a ring: each
  // estimate, or across a sample without one the last estimate held. A lagged solved factor reads
  // it only from row settling_rows on (before, it moves with x).
  Index ring = 1;   // a power of 2, so that a row's place is a mask
  while (ring <= settling_rows) ring *= 2;
  Eigen::Matrix<double, Eigen::Dynamic, D> history(ring, D);
  const auto history_row = [&](Index row) { return history.row(row & (ring - 1)); };
  Vector x = Vector::Zero(), last_good = Vector::Zero();
  std::vector<Vector> starts(1 + fallback_starts_.size());
  for (std::size_t s = 0; s < fallback_starts_.size(); ++s) starts[s + 1] = fallback_starts_[s];
  Vector residuals;
  Matrix jacobian, inverse, inverse_squared;
  Matrix inverted = Matrix::Constant(std::numeric_limits<double>::quiet_NaN());   // the Jacobian `inverse` inverts
  bool inverse_holds = false;   // a constant Jacobian's inverse, made: no comparison needed
  if (constant_jacobian)
    for (std::size_t m = 0; m < eqs.size(); ++m) jacobian.row(static_cast<Index>(m)) = eqs[m].constant_a.transpose();
  // The Jacobian's inverse and its entries squared (the uncertainty's), or false where it is
  // singular or a value not finite. Up to 3 unknowns the inverse is the cofactors'; 6 take
  // them per triad where the system is block triangular (a unit's), else Gauss-Jordan elimination.
  const auto invert = [&]() {
    if (!jacobian.allFinite()) return false;
    if constexpr (D == 1) {
      if (jacobian(0, 0) == 0.0) return false;
      inverse(0, 0) = 1.0 / jacobian(0, 0);
    } else if constexpr (D == 3) {
      if (!cofactor_inverse(jacobian, inverse)) return false;
    } else if (jacobian.template topRightCorner<3, 3>().isZero(0.0)) {
      if (!block_triangular_inverse(jacobian, inverse)) return false;
    } else if (!gauss_jordan_inverse<D>(jacobian, inverse)) {
      return false;
    }
    inverted = jacobian;
    inverse_holds = constant_jacobian;
    inverse_squared = inverse.array().square().matrix();
    return true;
  };
  if (affine_only) {
    const bool invertible = invert();
    std::vector<AffineEquation> affine(eqs.size());
    for (std::size_t m = 0; m < eqs.size(); ++m) {
      const Equation& e = eqs[m];
      AffineEquation& a = affine[m];
      a.y = e.y->data();
      a.constant_b = e.constant_b;
      for (const std::size_t t : e.varying_terms) {
        const Term& term = e.terms[t];
        AffineEquation::VaryingTerm& v =
            a.varying.emplace_back(AffineEquation::VaryingTerm{static_cast<Index>(t), term.coefficient, term.denominator, {}});
        for (const Factor& f : term.factors) v.factors.push_back({f.factor, f.known});
      }
      for (const auto& [t, row] : e.row_terms) a.row_terms.emplace_back(static_cast<Index>(t), static_cast<Index>(row));
      for (std::size_t t = 0; t < e.terms.size(); ++t)
        if (e.terms[t].factors.empty() && !e.terms[t].denominator) a.unit_terms.push_back(static_cast<Index>(t));
      a.rows.resize(static_cast<Index>(e.rows.size()), D);
      for (std::size_t r = 0; r < e.rows.size(); ++r) a.rows.row(static_cast<Index>(r)) = e.rows[r].transpose();
      a.covariance = equations_[m].model->covariance();
      a.noise_sd = e.noise_sd;
      a.bounds = e.bounds;
    }
    out.most_iterations = 1;
    solve_affine_samples<D>(affine, inverse, invertible, first_row_, n, out);
    return;
  }
  for (Index k = first_row_; k < n; ++k) {
    const Index r = k - first_row_;
    const auto moves = [&](const Factor& f) { return r < f.moving_until; };
    // Each term's known part; while lagged solved inputs still move (the first rows), how it moves.
    const bool settled = r > settling_rows;
    const auto factor_at = [&](const Equation& e, const Factor& f) {
      const Index at = k - f.factor.lag;
      const double v = f.solved >= 0 ? e.rows[static_cast<std::size_t>(f.solved)].dot(history_row(at - first_row_).transpose()) : f.known[at];
      return factor_value(f.factor, v);
    };
    for (Equation& e : eqs) {
      if (settled) {
        for (const std::size_t t : e.settled_terms) e.known[t] = 1.0;
        for (const auto& [t, f] : e.settled_factors) e.known[t] *= factor_at(e, f);
        continue;
      }
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
          product *= factor_at(e, f);
        }
        e.known[t] = product;
        e.mover[t] = moving > 1 ? kNonlinear : mover;
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
    // A system linear in the unknowns is g(x) = A x + b: each term is its known part, or that
    // times one row . x. The constant terms' share of A and b, and the other terms' now; a still
    // filtered square's value is its high pass's output, kept for the values at the root. The
    // root is x = -A^-1 b.
    const auto evaluate_affine = [&]() {
      for (std::size_t m = 0; m < eqs.size(); ++m) {
        Equation& e = eqs[m];
        const double yk = (*e.y)(k);
        double b = e.constant_b - yk;
        Vector a = e.constant_a;
        for (const std::size_t t : e.varying_terms) {
          const Term& term = e.terms[t];
          double v = e.known[t];
          if (term.square_filtered) {
            v = k == first_row_ ? 0.0 : e.highpass.p * e.h_previous[t] + e.highpass.g * (v - e.in_previous[t]);
            e.value[t] = v;
          }
          const double weighted = (term.denominator ? -yk * term.coefficient : term.coefficient) * v;
          const int mover = e.mover[t];
          if (mover >= 0)
            a += weighted * e.rows[static_cast<std::size_t>(mover)];
          else
            b += weighted;
        }
        residuals(static_cast<Index>(m)) = b;
        if (!constant_jacobian) jacobian.row(static_cast<Index>(m)) = a.transpose();
      }
    };
    // Newton's step, or false where the Jacobian is singular or a value not finite.
    const auto newton_step = [&](Vector& step) {
      if (!residuals.allFinite()) return false;
      if (inverse_holds || jacobian == inverted) {   // the Jacobian of the last inverse: often every sample's (a linear unit)
        step.noalias() = inverse * residuals;
        return step.allFinite();
      }
      if (!invert()) return false;
      if constexpr (D == 1) {
        step(0) = residuals(0) / jacobian(0, 0);
      } else {
        step.noalias() = inverse * residuals;
      }
      return step.allFinite();
    };

    // Newton from the previous estimate; where it fails (a singular Jacobian, no root nearby), from
    // the fallback starts.
    starts[0] = last_good;
    bool converged = false;
    int iterations = 0;
    Vector step;
    if (linear_) {
      // Its root in one solve; a singular A has none from any start.
      iterations = 1;
      evaluate_affine();
      converged = newton_step(step);
      if (converged) x = -step;
    } else {
      for (const Vector& start : starts) {
        x = start;
        double previous_step = 0.0;
        for (int i = 0; i < options.max_iterations; ++i) {
          ++iterations;
          evaluate(x);
          if (!newton_step(step)) break;
          x -= step;
          const double largest_step = step.cwiseAbs().maxCoeff(), scale = x.cwiseAbs().maxCoeff() + tolerance_scale_;
          if (newton_converged(largest_step, previous_step, InverseModel::kStepTolerance * scale, kRegime * scale)) {
            converged = true;
            break;
          }
          previous_step = largest_step;
        }
        if (converged) break;
      }
    }
    out.most_iterations = std::max(out.most_iterations, iterations);
    // The terms' values at the root (the squares' filter state and the uncertainty read them). A
    // linear system's: each moving term's known part times its row . x. Otherwise the last
    // evaluation's, moved the last step along their slopes: within that step's square, which the
    // stopping rule holds to the tolerance's order. The Jacobian and its inverse (the uncertainty's)
    // stay the last evaluation's, one step from the root: u's relative error is of the order of
    // that step (at most kRegime of the scale) times the model's curvature.
    // With them, each value's derivative of g by its coefficient (the value, times -y for a
    // denominator term), and each solved row's value at the root, which the squares' filter and
    // the range checks read.
    if (converged) {
      for (Equation& e : eqs) {
        const double yk = (*e.y)(k);
        double denominator = 1.0;
        const std::size_t term_count = e.terms.size();
        double* dg_dc = e.dg_dc.data();
        for (std::size_t s = 0; s < e.rows.size(); ++s) e.solved_value[s] = e.rows[s].dot(x);
        const auto at_root = [&](std::size_t t, double v) {
          e.value[t] = v;
          if (e.terms[t].denominator) {
            denominator += e.terms[t].coefficient * v;
            v *= -yk;
          }
          dg_dc[t] = v;
        };
        if (linear_) {
          for (std::size_t t = 0; t < term_count; ++t) {
            const int mover = e.mover[t];
            const double v = e.terms[t].square_filtered ? e.value[t] : e.known[t];
            at_root(t, mover >= 0 ? v * e.solved_value[static_cast<std::size_t>(mover)] : v);
          }
        } else {
          for (std::size_t t = 0; t < term_count; ++t) at_root(t, e.mover[t] != kStill ? e.value[t] - e.slope[t].dot(step) : e.value[t]);
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
      history_row(r) = last_good.transpose();   // the squares' high pass keeps its state across the sample
      continue;
    }
    out.value.row(r) = x.transpose();
    history_row(r) = x.transpose();
    last_good = x;
    Vector variance_c = Vector::Zero(), variance_n = Vector::Zero();
    bool inside = true;
    for (std::size_t m = 0; m < eqs.size(); ++m) {
      Equation& e = eqs[m];
      // a' C a, C a in blocks of 4 rows.
      const auto terms = static_cast<Index>(e.terms.size());
      const double* a = e.dg_dc.data();
      double quadratic = 0.0;
      for (Index block = 0; block < e.padded_rows; block += 4) {
        const double* column = e.covariance_padded.data() + block;
        Eigen::Vector4d c_a = Eigen::Vector4d::Zero();
        for (Index j = 0; j < terms; ++j, column += e.padded_rows) c_a += a[j] * Eigen::Map<const Eigen::Vector4d>(column);
        quadratic += c_a.dot(Eigen::Map<const Eigen::Vector4d>(a + block));
      }
      const double noise = e.noise_sd * e.denominator;
      variance_c += std::max(0.0, quadratic) * inverse_squared.col(static_cast<Index>(m));
      variance_n += (noise * noise) * inverse_squared.col(static_cast<Index>(m));
      for (const std::size_t t : e.filtered) {
        // The filter's input at x: the square's unfiltered value.
        double s = e.known[t];
        for (const Factor& f : e.terms[t].factors) {
          if (moves(f)) s *= factor_value(f.factor, e.solved_value[static_cast<std::size_t>(f.solved)]);
        }
        e.h_previous[t] = e.value[t];
        e.in_previous[t] = s;
      }
      // Inside the characterized range: every solved input and every known one at this sample.
      for (const Bound& b : e.bounds) {
        const double v = b.solved >= 0 ? e.solved_value[static_cast<std::size_t>(b.solved)] : b.column[k];
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
}

}  // namespace inertia::compensate
