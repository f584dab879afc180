#include "analyzer/procedure/prewhitening.hpp"

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

  // Levinson-Durbin: AR(m) coefficients and innovation variance for every m, AIC picks m.
  Eigen::VectorXd phi = Eigen::VectorXd::Zero(max_order), prev = phi;
  double variance = acov(0);
  double best_aic = n * std::log(variance);
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
    }
  }
  w.a_ = best_order > 0 ? best : Eigen::VectorXd();
  w.variance_ratio_ = std::exp((best_aic - 2.0 * best_order) / n) / acov(0);
  return w;
}

void ArWhitener::apply(StackedRegression& s) const {
  const int m = order();
  if (m == 0) return;
  Eigen::Index out = 0;
  std::vector<CaseRows> cases;
  for (const CaseRows& c : s.cases) {
    const Eigen::Index rows = c.rows - m;
    if (rows <= 0) continue;
    // Row r of the result (r >= 0) is sample r + m of the case: x[k] - sum a_j x[k - j]. Written
    // front to back into rows that are already consumed (out <= c.begin + r), so in place is safe.
    for (Eigen::Index r = 0; r < rows; ++r) {
      const Eigen::Index k = c.begin + m + r;
      double y = s.y(k);
      for (int j = 1; j <= m; ++j) y -= a_(j - 1) * s.y(k - j);
      s.y(out + r) = y;
    }
    for (Eigen::Index col = 0; col < s.phi.cols(); ++col) {
      auto x = s.phi.col(col);
      for (Eigen::Index r = 0; r < rows; ++r) {
        const Eigen::Index k = c.begin + m + r;
        double v = x(k);
        for (int j = 1; j <= m; ++j) v -= a_(j - 1) * x(k - j);
        x(out + r) = v;
      }
    }
    cases.push_back(CaseRows{c.case_index, out, rows, c.first_sample + m});
    out += rows;
  }
  s.phi.conservativeResize(out, Eigen::NoChange);
  s.y.conservativeResize(out);
  s.cases = std::move(cases);
}

}  // namespace inertia::procedure
