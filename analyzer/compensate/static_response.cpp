#include "analyzer/compensate/static_response.hpp"

#include <algorithm>
#include <cmath>

#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/procedure/square_highpass.hpp"

namespace inertia::compensate {

using ident::FactorFunction;
using ident::Variable;

namespace {

double coefficient_of(const model::ModelFile& model, std::size_t j, const Eigen::VectorXd& theta) {
  return theta.size() > 0 ? theta(static_cast<Eigen::Index>(j)) : model.terms[j].coefficient;
}

}  // namespace

double static_output(const model::ModelFile& model, const InputValues& values, const std::function<bool(const ident::Term&)>& kept,
                     const Eigen::VectorXd& theta) {
  double numerator = 0.0, denominator = 1.0;
  for (std::size_t j = 0; j < model.terms.size(); ++j) {
    const ident::Term& term = model.terms[j].term;
    if (term.is_noise_term() || (kept && !kept(term))) continue;
    if (model.square_highpass_rad_s && procedure::is_square_term(term)) continue;
    double product = coefficient_of(model, j, theta);
    int y_power = 0;
    bool unlagged_y = false;
    for (const ident::Factor& f : term.factors()) {
      if (f.variable == Variable::Y) {
        y_power += f.power;
        unlagged_y = unlagged_y || f.lag == 0;
        continue;
      }
      product *= factor_value(f, values[static_cast<std::size_t>(f.variable)]);
    }
    if (y_power == 0) {
      numerator += product;
    } else if (y_power == 1) {
      // Unlagged y*p: a denominator coefficient; a lagged y: the settled output on the right.
      denominator += unlagged_y ? product : -product;
    } else {
      return std::nan("");
    }
  }
  return denominator != 0.0 ? numerator / denominator : std::nan("");
}

double static_sensitivity(const model::ModelFile& model, Variable input, const Eigen::VectorXd& theta) {
  double gain = 0.0, feedback = 0.0;
  for (std::size_t j = 0; j < model.terms.size(); ++j) {
    const auto& f = model.terms[j].term.factors();
    if (f.size() != 1 || f[0].power != 1 || f[0].function != FactorFunction::Plain) continue;
    if (f[0].variable == input) gain += coefficient_of(model, j, theta);
    if (f[0].variable == Variable::Y && f[0].lag > 0) feedback += coefficient_of(model, j, theta);
  }
  return gain / (1.0 - feedback);
}

}  // namespace inertia::compensate
