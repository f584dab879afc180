#include "analyzer/ident/static_gain.hpp"

#include <algorithm>
#include <cmath>

#include "analyzer/ident/term.hpp"

namespace inertia::ident {
namespace {

bool is_output_lag(const Term& t) {
  const auto& f = t.factors();
  return f.size() == 1 && f[0].variable == Variable::Y && f[0].lag >= 1 && f[0].power == 1 &&
         f[0].function == FactorFunction::Plain;
}

/// The term shifted back to its smallest lag 0: a_i[k-1]*a_p[k-2] -> a_i*a_p[k-1].
Term unshifted(const Term& t) {
  std::vector<Factor> f = t.factors();
  if (f.empty()) return t;
  const int shift = std::min_element(f.begin(), f.end(), [](const Factor& a, const Factor& b) { return a.lag < b.lag; })->lag;
  for (Factor& x : f) x.lag -= shift;
  return Term::from_factors(std::move(f));
}

}  // namespace

std::vector<StaticGain> static_gains(const UlsResult& fit) {
  const Eigen::Index p = fit.process_terms;
  std::vector<Eigen::Index> output_lags;
  std::vector<Term> families;                        // input term at lag 0, first appearance order
  std::vector<std::vector<Eigen::Index>> members;    // parameter indices of each family
  bool dynamic = false;
  for (Eigen::Index j = 0; j < p; ++j) {
    const Term t = parse_term(fit.labels[static_cast<std::size_t>(j)]);
    if (is_output_lag(t)) {
      output_lags.push_back(j);
      dynamic = true;
      continue;
    }
    if (t.uses(Variable::Y) || t.uses(Variable::E)) continue;
    dynamic = dynamic || t.max_lag() > 0;
    const Term base = unshifted(t);
    const auto it = std::find(families.begin(), families.end(), base);
    if (it == families.end()) {
      families.push_back(base);
      members.push_back({j});
    } else {
      members[static_cast<std::size_t>(it - families.begin())].push_back(j);
    }
  }
  if (!dynamic) return {};
  double denominator = 1.0;
  for (Eigen::Index j : output_lags) denominator -= fit.theta(j);
  if (!(std::abs(denominator) > 1e-9)) return {};

  std::vector<StaticGain> out;
  for (std::size_t f = 0; f < families.size(); ++f) {
    StaticGain g;
    g.term = families[f].to_string();
    double numerator = 0.0;
    for (Eigen::Index j : members[f]) {
      numerator += fit.theta(j);
      g.lagged.push_back(fit.labels[static_cast<std::size_t>(j)]);
    }
    g.gain = numerator / denominator;
    // d gain / d b_l = 1 / D, d gain / d a_l = N / D^2.
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(fit.theta.size());
    for (Eigen::Index j : members[f]) gradient(j) = 1.0 / denominator;
    for (Eigen::Index j : output_lags) gradient(j) = numerator / (denominator * denominator);
    if (fit.covariance.rows() == fit.theta.size()) g.std_dev = std::sqrt(std::max(0.0, gradient.dot(fit.covariance * gradient)));
    out.push_back(std::move(g));
  }
  return out;
}

}  // namespace inertia::ident
