#include "analyzer/procedure/model_simulation.hpp"

#include <stdexcept>
#include <vector>

#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

using ident::FactorFunction;
using ident::Term;
using ident::Variable;

/// The lag j of a term that is exactly y[k-j], or 0.
int pure_output_lag(const Term& term) {
  const auto& f = term.factors();
  if (f.size() == 1 && f[0].variable == Variable::Y && f[0].lag > 0 && f[0].power == 1 &&
      f[0].function == FactorFunction::Plain) {
    return f[0].lag;
  }
  return 0;
}

/// For an output-multiplied term y*p_b: p_b as a term (the other factors), else nullopt.
std::optional<Term> denominator_factor(const Term& term) {
  if (!term.is_output_multiplied()) return std::nullopt;
  std::vector<ident::Factor> rest;
  for (const ident::Factor& f : term.factors()) {
    if (f.variable == Variable::Y && f.lag == 0) {
      if (f.power != 1 || f.function != FactorFunction::Plain) return std::nullopt;
      continue;
    }
    rest.push_back(f);
  }
  return Term::from_factors(rest);
}

}  // namespace

Eigen::VectorXd simulate_model(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                               const ident::SignalSet& signals, Eigen::Index first_row,
                               std::optional<double> square_highpass_rad_s, double sample_period_s) {
  if (square_highpass_rad_s && !(sample_period_s > 0.0)) {
    throw std::invalid_argument("simulate_model: a square high pass needs the sample period");
  }
  if (static_cast<Eigen::Index>(terms.size()) != theta.size()) {
    throw std::invalid_argument("simulate_model: one coefficient per term needed");
  }
  const Eigen::Index n = signals.size();
  first_row = std::max(first_row, ident::first_usable_row(terms));
  if (first_row >= n) return Eigen::VectorXd();

  // Split the terms: inputs only (one regression), pure output lags, denominators, noise (dropped).
  std::vector<Term> input_terms, den_terms;
  std::vector<double> input_theta, den_theta;
  std::vector<std::pair<int, double>> lags;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    const Term& t = terms[j];
    const double c = theta(static_cast<Eigen::Index>(j));
    if (t.is_noise_term()) continue;
    if (const int lag = pure_output_lag(t)) {
      lags.emplace_back(lag, c);
    } else if (const auto p = denominator_factor(t)) {
      den_terms.push_back(*p);
      den_theta.push_back(c);
    } else if (t.uses(Variable::Y)) {
      throw InputError("term '" + t.to_string() + "' cannot be simulated: the output enters it other than as y[k-j] or y*p");
    } else {
      input_terms.push_back(t);
      input_theta.push_back(c);
    }
  }
  const Eigen::Index rows = n - first_row;
  Eigen::VectorXd numerator = Eigen::VectorXd::Zero(rows);
  if (!input_terms.empty()) {
    Eigen::MatrixXd phi(rows, static_cast<Eigen::Index>(input_terms.size()));
    ident::fill_regressors(input_terms, signals, first_row, phi);
    if (square_highpass_rad_s) {
      for (std::size_t j = 0; j < input_terms.size(); ++j) {
        if (is_square_term(input_terms[j])) {
          highpass_in_place(phi.col(static_cast<Eigen::Index>(j)), *square_highpass_rad_s, sample_period_s);
        }
      }
    }
    numerator = phi * Eigen::Map<const Eigen::VectorXd>(input_theta.data(), static_cast<Eigen::Index>(input_theta.size()));
  }
  Eigen::VectorXd denominator = Eigen::VectorXd::Ones(rows);
  if (!den_terms.empty()) {
    Eigen::MatrixXd p(rows, static_cast<Eigen::Index>(den_terms.size()));
    ident::fill_regressors(den_terms, signals, first_row, p);
    denominator += p * Eigen::Map<const Eigen::VectorXd>(den_theta.data(), static_cast<Eigen::Index>(den_theta.size()));
  }
  // Output lags reach back into the measured output for the first rows only.
  Eigen::VectorXd y(n);
  if (!lags.empty()) y.head(first_row) = signals.get(Variable::Y).head(first_row);
  for (Eigen::Index r = 0; r < rows; ++r) {
    const Eigen::Index k = first_row + r;
    double a = numerator(r);
    for (const auto& [lag, c] : lags) a += c * y(k - lag);
    y(k) = a / denominator(r);
  }
  return y.tail(rows);
}

}  // namespace inertia::procedure
