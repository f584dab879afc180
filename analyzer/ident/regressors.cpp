#include "analyzer/ident/regressors.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <tuple>

#include <fmt/format.h>

#include "common/input_error.hpp"

namespace inertia::ident {

SignalSet::SignalSet(Eigen::Index samples, std::string origin) : samples_(samples), origin_(std::move(origin)) {}

void SignalSet::set(Variable v, Eigen::VectorXd values) {
  if (values.size() != samples_) {
    throw std::invalid_argument(fmt::format("SignalSet::set({}): {} samples, the set has {}", variable_name(v),
                                            values.size(), samples_));
  }
  values_[index(v)] = std::move(values);
}

const Eigen::VectorXd& SignalSet::get(Variable v) const {
  const auto& slot = values_[index(v)];
  if (!slot) throw std::out_of_range(fmt::format("SignalSet: no variable {}", variable_name(v)));
  return *slot;
}

SignalSet signals_from_case(const dataset::CaseData& c, const Eigen::Matrix3d& m_es, double t_ref,
                            std::string_view dataset_label) {
  std::string origin = fmt::format("case '{}'", c.name);
  if (!dataset_label.empty()) origin += fmt::format(" of dataset {}", dataset_label);
  SignalSet s(c.size(), std::move(origin));
  // Rows of a_e are samples: a_S^T = a_E^T (M_E^S)^T.
  const Eigen::Matrix<double, Eigen::Dynamic, 3> a_s = c.a_e * m_es.transpose();
  s.set(Variable::Ai, a_s.col(0));
  s.set(Variable::Ap, a_s.col(1));
  s.set(Variable::Ao, a_s.col(2));
  s.set(Variable::Ax, c.a_e.col(0));
  s.set(Variable::Ay, c.a_e.col(1));
  s.set(Variable::Az, c.a_e.col(2));
  if (c.w_e) {
    const Eigen::Matrix<double, Eigen::Dynamic, 3> w_s = *c.w_e * m_es.transpose();
    s.set(Variable::Wi, w_s.col(0));
    s.set(Variable::Wp, w_s.col(1));
    s.set(Variable::Wo, w_s.col(2));
    s.set(Variable::Wx, c.w_e->col(0));
    s.set(Variable::Wy, c.w_e->col(1));
    s.set(Variable::Wz, c.w_e->col(2));
  }
  if (c.temp) s.set(Variable::T, (c.temp->array() - t_ref).matrix());
  s.set(Variable::Y, c.y);
  return s;
}

SignalSet signals_from_dataset(const dataset::Dataset& data, std::size_t case_index, const Eigen::Matrix3d& m_es) {
  return signals_from_case(data.cases.at(case_index), m_es, data.t_ref, data.dir.string());
}

std::string source_of(Variable v) {
  switch (v) {
    case Variable::Ai: case Variable::Ap: case Variable::Ao:
    case Variable::Ax: case Variable::Ay: case Variable::Az: return "a_x, a_y, a_z";
    case Variable::Wi: case Variable::Wp: case Variable::Wo:
    case Variable::Wx: case Variable::Wy: case Variable::Wz: return "w_x, w_y, w_z";
    case Variable::T: return "temp";
    case Variable::Y: return "y";
    case Variable::E: return "e";
  }
  return "?";
}

void check_signals(std::span<const Term> terms, const SignalSet& signals) {
  const std::string where = signals.origin().empty() ? std::string("the signal set") : signals.origin();
  for (const Term& term : terms) {
    for (Variable v : term.variables()) {
      if (signals.has(v)) continue;
      if (v == Variable::E) {
        throw InputError(fmt::format("term '{}' needs the residual e, which the estimator has not supplied for {}",
                                     term.to_string(), where));
      }
      const std::string column = source_of(v);
      throw InputError(fmt::format("term '{}' needs column{} '{}', which {} lacks", term.to_string(),
                                   column.find(',') == std::string::npos ? "" : "s", column, where));
    }
  }
}

Eigen::Index first_usable_row(std::span<const Term> terms) {
  int lag = 0;
  for (const Term& t : terms) lag = std::max(lag, t.max_lag());
  return lag;
}

namespace {

// Vectors of f(v)^n over the whole case, computed once per build and shared by every term (and
// every lag of it: a lag is only a different segment of the same vector).
class FactorCache {
 public:
  explicit FactorCache(const SignalSet& signals) : signals_(signals) {}

  const Eigen::VectorXd& values(const Factor& f) {
    const Eigen::VectorXd& x = signals_.get(f.variable);
    if (f.function == FactorFunction::Plain && f.power == 1) return x;
    const auto key = std::make_tuple(f.variable, f.function, f.power);
    auto it = cache_.find(key);
    if (it != cache_.end()) return it->second;
    Eigen::VectorXd v(x.size());
    switch (f.function) {
      case FactorFunction::Plain: v = integer_power(x.array(), f.power); break;
      case FactorFunction::Abs: v = integer_power(x.array().abs(), f.power); break;
      // Paper eq. 1: sign(0) = 0, as std's signum and MATLAB's sign.
      case FactorFunction::Sign: v = x.unaryExpr([](double a) { return a > 0.0 ? 1.0 : (a < 0.0 ? -1.0 : 0.0); }); break;
    }
    return cache_.emplace(key, std::move(v)).first->second;
  }

 private:
  // Repeated multiplication, exact for the small powers terms use (std::pow is slower and, for
  // negative bases, needs an integer exponent anyway).
  template <class Expr>
  static Eigen::VectorXd integer_power(const Expr& base, int n) {
    Eigen::VectorXd b = base.matrix();
    Eigen::VectorXd r = b;
    for (int i = 1; i < n; ++i) r.array() *= b.array();
    return r;
  }

  const SignalSet& signals_;
  std::map<std::tuple<Variable, FactorFunction, int>, Eigen::VectorXd> cache_;
};

}  // namespace

void fill_regressors(std::span<const Term> terms, const SignalSet& signals, Eigen::Index first_row,
                     Eigen::Ref<Eigen::MatrixXd> phi) {
  check_signals(terms, signals);
  const Eigen::Index needed = first_usable_row(terms);
  if (first_row < needed) {
    throw std::invalid_argument(fmt::format("fill_regressors: first_row {} < largest lag {}", first_row, needed));
  }
  const Eigen::Index rows = signals.size() - first_row;
  if (rows <= 0) {
    throw InputError(fmt::format("{} has {} samples, too few for terms lagged by up to {} samples",
                                 signals.origin().empty() ? std::string("the signal set") : signals.origin(),
                                 signals.size(), first_row));
  }
  if (phi.rows() != rows || phi.cols() != static_cast<Eigen::Index>(terms.size())) {
    throw std::invalid_argument(fmt::format("fill_regressors: phi is {}x{}, expected {}x{}", phi.rows(), phi.cols(),
                                            rows, terms.size()));
  }
  FactorCache cache(signals);
  for (std::size_t j = 0; j < terms.size(); ++j) {
    auto col = phi.col(static_cast<Eigen::Index>(j));
    const auto& factors = terms[j].factors();
    if (factors.empty()) {
      col.setOnes();
      continue;
    }
    // Row r is sample first_row + r; a factor lagged by L reads sample first_row + r - L.
    const auto segment = [&](const Factor& f) { return cache.values(f).segment(first_row - f.lag, rows); };
    col = segment(factors[0]);
    for (std::size_t i = 1; i < factors.size(); ++i) col.array() *= segment(factors[i]).array();
  }
}

Regression build_regression(std::span<const Term> terms, const SignalSet& signals, Eigen::Index min_first_row) {
  check_signals(terms, signals);
  if (!signals.has(Variable::Y)) {
    throw InputError(fmt::format("{} has no output column 'y'",
                                 signals.origin().empty() ? std::string("the signal set") : signals.origin()));
  }
  Regression r;
  r.first_row = std::max(first_usable_row(terms), min_first_row);
  const Eigen::Index rows = signals.size() - r.first_row;
  if (rows <= 0) {
    throw InputError(fmt::format("{} has {} samples, too few for terms lagged by up to {} samples",
                                 signals.origin().empty() ? std::string("the signal set") : signals.origin(),
                                 signals.size(), r.first_row));
  }
  r.phi.resize(rows, static_cast<Eigen::Index>(terms.size()));
  fill_regressors(terms, signals, r.first_row, r.phi);
  r.y = signals.get(Variable::Y).segment(r.first_row, rows);
  return r;
}

}  // namespace inertia::ident
