#include "analyzer/compensate/inverse_model.hpp"

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
using ident::FactorFunction;
using ident::Variable;

const char* to_string(SampleFlag flag) {
  switch (flag) {
    case SampleFlag::Ok: return "ok";
    case SampleFlag::OutsideRange: return "outside_range";
    case SampleFlag::NotConverged: return "not_converged";
  }
  return "?";
}

namespace {

double integer_power(double v, int power) {
  double r = 1.0;
  for (int i = 0; i < power; ++i) r *= v;
  return r;
}

double sign_of(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

}  // namespace

double factor_value(const ident::Factor& f, double v) {
  switch (f.function) {
    case FactorFunction::Plain: return integer_power(v, f.power);
    case FactorFunction::Abs: return integer_power(std::abs(v), f.power);
    case FactorFunction::Sign: return integer_power(sign_of(v), f.power);
  }
  return 0.0;
}

double factor_slope(const ident::Factor& f, double v) {
  switch (f.function) {
    case FactorFunction::Plain: return f.power * integer_power(v, f.power - 1);
    case FactorFunction::Abs: return f.power * integer_power(std::abs(v), f.power - 1) * sign_of(v);
    case FactorFunction::Sign: return 0.0;
  }
  return 0.0;
}

InverseModel::InverseModel(const model::ModelFile& model) {
  sensed_ = model.sensor == dataset::SensorKind::Accelerometer ? Variable::Ai : Variable::Wi;
  noise_sd_ = model.output_sd.value_or(model.white_sd.value_or(0.0));
  square_corner_ = model.square_highpass_rad_s;
  range_ = model.range;
  bool reads_sensed_now = false;
  for (std::size_t j = 0; j < model.terms.size(); ++j) {
    const ident::Term& term = model.terms[j].term;
    if (term.is_noise_term()) continue;
    CompiledTerm t;
    t.coefficient = model.terms[j].coefficient;
    for (const ident::Factor& f : term.factors()) {
      if (f.variable == Variable::Y && f.lag == 0) {
        if (f.power != 1 || f.function != FactorFunction::Plain) {
          throw InputError(fmt::format("term '{}' cannot be compensated: the output enters it unlagged other than as y*p",
                                       term.to_string()));
        }
        t.denominator = true;
        continue;
      }
      if (f.variable == sensed_ && f.lag == 0) reads_sensed_now = true;
      if (f.variable != Variable::Y && f.variable != sensed_) known_.set(static_cast<std::size_t>(f.variable));
      t.factors.push_back(f);
    }
    t.square_filtered = square_corner_.has_value() && procedure::is_square_term(term);
    first_row_ = std::max<Index>(first_row_, term.max_lag());
    terms_.push_back(std::move(t));
    model_index_.push_back(static_cast<Index>(j));
  }
  if (!reads_sensed_now) {
    throw InputError(fmt::format("the model has no term in {} at the current sample: its output does not tell the input",
                                 ident::variable_name(sensed_)));
  }
  const auto n = static_cast<Index>(terms_.size());
  covariance_ = Eigen::MatrixXd::Zero(n, n);
  has_covariance_ = model.covariance.rows() == static_cast<Index>(model.terms.size()) && model.covariance.rows() > 0;
  for (Index a = 0; a < n; ++a) {
    const Index ma = model_index_[static_cast<std::size_t>(a)];
    if (!has_covariance_) {
      covariance_(a, a) = std::pow(model.terms[static_cast<std::size_t>(ma)].std.value_or(0.0), 2);
      continue;
    }
    for (Index b = 0; b < n; ++b) covariance_(a, b) = model.covariance(ma, model_index_[static_cast<std::size_t>(b)]);
  }
}

std::array<double, 3> InverseModel::fallback_starts() const {
  const double lo = range_.count(sensed_) ? range_.at(sensed_).lowest : -1.0;
  const double hi = range_.count(sensed_) ? range_.at(sensed_).highest : 1.0;
  return {0.5 * (lo + hi), hi, lo};
}

double InverseModel::tolerance_scale() const {
  const double span = range_.count(sensed_) ? range_.at(sensed_).highest - range_.at(sensed_).lowest : 0.0;
  return span > 0.0 ? span : 1.0;
}

CompensatedSignal InverseModel::compensate(const ident::SignalSet& signals, double sample_period_s,
                                           const CompensationOptions& options) const {
  for (std::size_t v = 0; v < static_cast<std::size_t>(ident::kVariableCount); ++v) {
    if ((known_.test(v) || v == static_cast<std::size_t>(Variable::Y)) && !signals.has(static_cast<Variable>(v))) {
      throw InputError(fmt::format("compensation needs '{}' ({}), which {} lacks", ident::variable_name(static_cast<Variable>(v)),
                                   ident::source_of(static_cast<Variable>(v)),
                                   signals.origin().empty() ? "the record" : signals.origin()));
    }
  }
  const bool filtered = std::any_of(terms_.begin(), terms_.end(), [](const CompiledTerm& t) { return t.square_filtered; });
  if (filtered && !(sample_period_s > 0.0)) {
    throw std::invalid_argument("compensate: the model's square high pass needs the sample period");
  }
  const procedure::HighpassCoefficients highpass =
      filtered ? procedure::highpass_coefficients(*square_corner_, sample_period_s) : procedure::HighpassCoefficients{};

  const Index n = signals.size();
  CompensatedSignal out;
  out.first_row = first_row_;
  const Index rows = std::max<Index>(0, n - first_row_);
  out.value.resize(rows);
  out.u_coefficients.resize(rows);
  out.u_noise.resize(rows);
  out.flag.assign(static_cast<std::size_t>(rows), SampleFlag::Ok);
  if (rows == 0) return out;

  const Eigen::VectorXd& y = signals.get(Variable::Y);
  std::array<const Eigen::VectorXd*, ident::kVariableCount> column{};
  for (int v = 0; v < ident::kVariableCount; ++v) {
    const auto variable = static_cast<Variable>(v);
    if (variable != sensed_ && signals.has(variable)) column[static_cast<std::size_t>(v)] = &signals.get(variable);
  }
  const double step_scale = tolerance_scale();

  const auto t_count = terms_.size();
  std::vector<double> known(t_count);         // product of the factors that do not move with x
  std::vector<double> h_previous(t_count, 0.0), in_previous(t_count, 0.0);   // squares' high pass
  std::vector<double> value(t_count), slope(t_count);
  Eigen::VectorXd jacobian(static_cast<Index>(t_count)), covariance_jacobian(static_cast<Index>(t_count));
  // The range checks as flat bounds: the solved input (column null) or a known one.
  struct Bound {
    const Eigen::VectorXd* column;
    double lowest, highest;
  };
  std::vector<Bound> bounds;
  for (const auto& [variable, span] : range_) {
    const double margin = options.range_margin * (span.highest - span.lowest);
    if (variable != sensed_ && column[static_cast<std::size_t>(variable)] == nullptr) continue;
    bounds.push_back({variable == sensed_ ? nullptr : column[static_cast<std::size_t>(variable)], span.lowest - margin,
                      span.highest + margin});
  }
  // The sensed input as the lagged terms read it: each estimate, or across a sample without one
  // the last estimate held.
  Eigen::VectorXd history(rows);
  double x = 0.0, last_good = 0.0;

  for (Index k = first_row_; k < n; ++k) {
    const Index r = k - first_row_;
    // Whether a factor moves with this sample's x: the sensed input now, or before the first
    // estimate (the settled start).
    const auto moves = [&](const ident::Factor& f) { return f.variable == sensed_ && (f.lag == 0 || k - f.lag < first_row_); };
    const auto known_value = [&](const ident::Factor& f) {
      const Index at = k - f.lag;
      const double v = f.variable == sensed_ ? history(at - first_row_) : (*column[static_cast<std::size_t>(f.variable)])(at);
      return factor_value(f, v);
    };
    for (std::size_t t = 0; t < t_count; ++t) {
      double product = 1.0;
      for (const ident::Factor& f : terms_[t].factors) {
        if (!moves(f)) product *= known_value(f);
      }
      known[t] = product;
    }
    // Each term's value and slope at x. A filtered square's value is its high pass's output,
    // h(k) = p h(k-1) + g (s(k) - s(k-1)), settled (0) at the first row.
    const auto evaluate = [&](double at_x) {
      for (std::size_t t = 0; t < t_count; ++t) {
        const CompiledTerm& term = terms_[t];
        double v = known[t], d = 0.0;
        for (const ident::Factor& f : term.factors) {
          if (!moves(f)) continue;
          const double fv = factor_value(f, at_x), fd = factor_slope(f, at_x);
          d = d * fv + v * fd;
          v *= fv;
        }
        if (term.square_filtered) {
          if (k == first_row_) {
            v = 0.0;
            d = 0.0;
          } else {
            v = highpass.p * h_previous[t] + highpass.g * (v - in_previous[t]);
            d = highpass.g * d;
          }
        }
        value[t] = v;
        slope[t] = d;
      }
    };
    const double yk = y(k);
    const auto residual = [&](double& g, double& dg, double& denominator) {
      g = -yk;
      dg = 0.0;
      denominator = 1.0;
      for (std::size_t t = 0; t < t_count; ++t) {
        const double c = terms_[t].coefficient;
        if (terms_[t].denominator) {
          denominator += c * value[t];
          g -= yk * c * value[t];
          dg -= yk * c * slope[t];
        } else {
          g += c * value[t];
          dg += c * slope[t];
        }
      }
    };

    // Newton from the previous estimate; where it fails (a zero slope, no root nearby), from the
    // middle and the ends of the characterized range, or from 0 and +-1 without one.
    const std::array<double, 3> fallback = fallback_starts();
    const std::array<double, 4> starts{last_good, fallback[0], fallback[1], fallback[2]};
    bool converged = false;
    int iterations = 0;
    double g = 0.0, dg = 0.0, denominator = 1.0;
    for (const double start : starts) {
      x = start;
      for (int i = 0; i < options.max_iterations; ++i) {
        ++iterations;
        evaluate(x);
        residual(g, dg, denominator);
        if (!(std::isfinite(g) && std::isfinite(dg)) || dg == 0.0) break;
        const double step = g / dg;
        x -= step;
        if (std::abs(step) <= kStepTolerance * (std::abs(x) + step_scale)) {
          converged = true;
          break;
        }
      }
      if (converged) break;
    }
    out.most_iterations = std::max(out.most_iterations, iterations);
    // The terms' values as the root (the squares' filter state and the uncertainty read them).
    evaluate(x);
    residual(g, dg, denominator);
    if (!converged || !std::isfinite(x) || dg == 0.0) {
      out.value(r) = std::numeric_limits<double>::quiet_NaN();
      out.u_coefficients(r) = out.u_noise(r) = std::numeric_limits<double>::quiet_NaN();
      out.flag[static_cast<std::size_t>(r)] = SampleFlag::NotConverged;
      ++out.not_converged;
      history(r) = last_good;   // the squares' high pass keeps its state across the sample
      continue;
    }
    out.value(r) = x;
    history(r) = x;
    last_good = x;
    for (std::size_t t = 0; t < t_count; ++t) {
      const double dg_dc = terms_[t].denominator ? -yk * value[t] : value[t];
      jacobian(static_cast<Index>(t)) = -dg_dc / dg;
    }
    covariance_jacobian.noalias() = covariance_ * jacobian;
    out.u_coefficients(r) = std::sqrt(std::max(0.0, jacobian.dot(covariance_jacobian)));
    out.u_noise(r) = noise_sd_ * std::abs(denominator) / std::abs(dg);
    for (std::size_t t = 0; t < t_count; ++t) {
      if (!terms_[t].square_filtered) continue;
      // The filter's input at x: the square's unfiltered value.
      double s = known[t];
      for (const ident::Factor& f : terms_[t].factors) {
        if (moves(f)) s *= factor_value(f, x);
      }
      h_previous[t] = value[t];
      in_previous[t] = s;
    }
    // Inside the characterized range: the solved input and every known one at this sample.
    bool inside = true;
    for (const Bound& b : bounds) {
      const double v = b.column == nullptr ? x : (*b.column)(k);
      inside = inside && v >= b.lowest && v <= b.highest;
    }
    if (!inside) {
      out.flag[static_cast<std::size_t>(r)] = SampleFlag::OutsideRange;
      ++out.outside_range;
    }
  }
  return out;
}

}  // namespace inertia::compensate
