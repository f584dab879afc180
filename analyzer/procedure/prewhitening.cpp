#include "analyzer/procedure/prewhitening.hpp"

#include <algorithm>

#include <cmath>
#include <limits>

namespace inertia::procedure {

ArWhitener ArWhitener::fit(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout, int max_order) {
  ArWhitener w;
  if (max_order <= 0) return w;
  // Autocovariances summed within cases (a lag never pairs samples of two cases).
  Eigen::VectorXd acov = Eigen::VectorXd::Zero(max_order + 1);
  double n = 0.0;
  for (const CaseRows& c : layout) {
    const Eigen::VectorXd e = residuals.segment(c.begin, c.rows);
    n += static_cast<double>(c.rows);
    for (int lag = 0; lag <= max_order && lag < c.rows; ++lag) {
      acov(lag) += e.head(c.rows - lag).dot(e.tail(c.rows - lag));
    }
  }
  if (n < 10.0 * max_order || !(acov(0) > 0.0)) return w;
  acov /= n;

  double innovation = 0.0;
  w.a_ = ar_from_autocovariance(acov, n, &innovation);
  w.variance_ratio_ = innovation / acov(0);
  return w;
}

Eigen::VectorXd ar_from_autocovariance(const Eigen::VectorXd& acov, double n, double* innovation_variance) {
  const int max_order = static_cast<int>(acov.size()) - 1;
  if (innovation_variance != nullptr) *innovation_variance = acov.size() > 0 ? acov(0) : 0.0;
  if (max_order <= 0 || !(acov(0) > 0.0) || n < 10.0 * max_order) return {};
  // Levinson-Durbin: AR(m) coefficients and innovation variance for every m, AIC picks m.
  Eigen::VectorXd phi = Eigen::VectorXd::Zero(max_order), prev = phi;
  double variance = acov(0);
  double best_aic = n * std::log(variance), best_variance = variance;
  int best_order = 0;
  Eigen::VectorXd best = Eigen::VectorXd();
  for (int m = 1; m <= max_order; ++m) {
    double acc = acov(m);
    for (int j = 1; j < m; ++j) acc -= prev(j - 1) * acov(m - j);
    const double k = acc / variance;
    if (!std::isfinite(k) || std::abs(k) >= 1.0) break;   // numerically non-stationary: stop here
    phi(m - 1) = k;
    for (int j = 1; j < m; ++j) phi(j - 1) = prev(j - 1) - k * prev(m - j - 1);
    variance *= 1.0 - k * k;
    prev = phi;
    const double aic = n * std::log(variance) + 2.0 * m;
    if (aic < best_aic) {
      best_aic = aic;
      best_order = m;
      best = phi.head(m);
      best_variance = variance;
    }
  }
  if (innovation_variance != nullptr) *innovation_variance = best_variance;
  return best_order > 0 ? best : Eigen::VectorXd();
}

void ArWhitener::apply(StackedRegression& s) const {
  const int m = order();
  if (m == 0) return;
  Eigen::Index out = 0;
  std::vector<CaseRows> cases;
  for (const CaseRows& c : s.cases) {
    const Eigen::Index rows = c.rows - m;
    if (rows <= 0) continue;
    // Row r of the result (r >= 0) is sample r + m of the case: x[k] - sum a_j x[k - j]. Per lag a
    // whole block of rows at once (vectorized; the same per-sample order of operations as a scalar
    // loop) into a scratch vector, then copied to rows already consumed (out <= c.begin), so in
    // place is safe. Blocks of kBlock rows keep the m passes over a block in L1/L2: whole-case
    // segments (3 MB on the paper's rotation table) made every lag a trip to memory.
    constexpr Eigen::Index kBlock = 2048;
    Eigen::VectorXd scratch(rows);
    const auto filter_into = [&](auto&& x) {
      for (Eigen::Index b = 0; b < rows; b += kBlock) {
        const Eigen::Index n = std::min(kBlock, rows - b);
        ar_filter(a_, x.segment(c.begin + b, n + m), scratch.segment(b, n));
      }
      x.segment(out, rows) = scratch;
    };
    filter_into(s.y);
    for (Eigen::Index col = 0; col < s.phi.cols(); ++col) filter_into(s.phi.col(col));
    // The factors of output-multiplied columns are not filtered (stacked_regression.hpp): they
    // only lose the same first rows.
    if (s.rational.factors.rows() > 0) s.rational.factors.middleRows(out, rows) = s.rational.factors.middleRows(c.begin + m, rows).eval();
    cases.push_back(CaseRows{c.case_index, out, rows, c.first_sample + m});
    out += rows;
  }
  s.phi.conservativeResize(out, Eigen::NoChange);
  s.y.conservativeResize(out);
  if (s.rational.factors.rows() > 0) s.rational.factors.conservativeResize(out, Eigen::NoChange);
  s.cases = std::move(cases);
}

}  // namespace inertia::procedure
