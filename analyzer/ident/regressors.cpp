#include "analyzer/ident/regressors.hpp"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <stdexcept>

#include <fmt/format.h>

#include "common/dataset/huge_pages.hpp"
#include "common/input_error.hpp"
#include "common/parallel.hpp"

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

VariableSet variables_of(std::span<const Term> terms) {
  VariableSet out;
  for (const Term& t : terms)
    for (const Variable v : t.variables()) out.set(static_cast<std::size_t>(v));
  return out;
}

SignalSet signals_from_case(const dataset::CaseData& c, const Eigen::Matrix3d& m_es, double t_ref,
                            std::string_view dataset_label, const std::optional<VariableSet>& only, const CaseReading& reading) {
  std::string origin = fmt::format("case '{}'", c.name);
  if (!dataset_label.empty()) origin += fmt::format(" of dataset {}", dataset_label);
  SignalSet s(c.size(), std::move(origin));
  const auto wanted = [&only](Variable v) { return !only || only->test(static_cast<std::size_t>(v)); };
  // Rows of a_e are samples: a_S^T = a_E^T (M_E^S)^T, each sensor axis straight into its own
  // vector (no N x 3 temporary copied out column by column).
  const auto sensed = [&m_es](const auto& e, Eigen::Index axis) -> Eigen::VectorXd { return e * m_es.row(axis).transpose(); };
  // The external variables as given, or turned into the reading's frame.
  const bool in_f_e = reading.external == Eigen::Matrix3d::Identity();
  const auto external = [&](const auto& e, Eigen::Index axis) -> Eigen::VectorXd {
    return in_f_e ? Eigen::VectorXd(e.col(axis)) : Eigen::VectorXd(e * reading.external.row(axis).transpose());
  };
  if (wanted(Variable::Ai)) s.set(Variable::Ai, sensed(c.a_e, 0));
  if (wanted(Variable::Ap)) s.set(Variable::Ap, sensed(c.a_e, 1));
  if (wanted(Variable::Ao)) s.set(Variable::Ao, sensed(c.a_e, 2));
  if (wanted(Variable::Ax)) s.set(Variable::Ax, external(c.a_e, 0));
  if (wanted(Variable::Ay)) s.set(Variable::Ay, external(c.a_e, 1));
  if (wanted(Variable::Az)) s.set(Variable::Az, external(c.a_e, 2));
  if (c.w_e) {
    if (wanted(Variable::Wi)) s.set(Variable::Wi, sensed(*c.w_e, 0));
    if (wanted(Variable::Wp)) s.set(Variable::Wp, sensed(*c.w_e, 1));
    if (wanted(Variable::Wo)) s.set(Variable::Wo, sensed(*c.w_e, 2));
    if (wanted(Variable::Wx)) s.set(Variable::Wx, external(*c.w_e, 0));
    if (wanted(Variable::Wy)) s.set(Variable::Wy, external(*c.w_e, 1));
    if (wanted(Variable::Wz)) s.set(Variable::Wz, external(*c.w_e, 2));
  }
  if (c.temp && wanted(Variable::T)) s.set(Variable::T, (c.temp->array() - t_ref).matrix());
  if (wanted(Variable::Y)) s.set(Variable::Y, reading.y_offset == 0.0 ? c.y : Eigen::VectorXd(c.y.array() - reading.y_offset));
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

// sign(0) = 0, as the paper's sign (eq. 1), MATLAB's sign and std's signum convention.
double signum(double a) { return a > 0.0 ? 1.0 : (a < 0.0 ? -1.0 : 0.0); }

// col = f(x)^n (first factor) or col *= f(x)^n, straight from the signal segment: no temporary
// vectors, so fill_regressors allocates nothing (fresh pages cost more than the extra multiplies;
// see common/dataset/huge_pages.hpp).
template <class Column, class Segment>
void apply_factor(Column&& col, const Segment& x, const Factor& f, bool first) {
  for (int n = 0; n < f.power; ++n) {
    const bool assign = first && n == 0;
    switch (f.function) {
      case FactorFunction::Plain:
        if (assign) col = x; else col.array() *= x.array();
        break;
      case FactorFunction::Abs:
        if (assign) col = x.cwiseAbs(); else col.array() *= x.array().abs();
        break;
      case FactorFunction::Sign:
        if (assign) col = x.unaryExpr(&signum); else col.array() *= x.unaryExpr(&signum).array();
        break;
    }
  }
}

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
  // The columns are independent: filled on the --jobs threads, each of which also takes the first
  // touch of the pages it writes.
  parallel::for_each_index(static_cast<long>(terms.size()), [&](long index) {
    const auto j = static_cast<std::size_t>(index);
    auto col = phi.col(static_cast<Eigen::Index>(j));
    const auto& factors = terms[j].factors();
    if (factors.empty()) {
      col.setOnes();
      return;
    }
    // Row r is sample first_row + r; a factor lagged by L reads sample first_row + r - L.
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const Factor& f = factors[i];
      apply_factor(col, signals.get(f.variable).segment(first_row - f.lag, rows), f, i == 0);
    }
  });
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
  dataset::advise_huge_pages(r.phi.data(), static_cast<std::size_t>(r.phi.size()) * sizeof(double));
  fill_regressors(terms, signals, r.first_row, r.phi);
  r.y = signals.get(Variable::Y).segment(r.first_row, rows);
  return r;
}

}  // namespace inertia::ident
