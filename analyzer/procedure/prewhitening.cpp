#include "analyzer/procedure/prewhitening.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/parallel.hpp"

namespace inertia::procedure {

ArWhitener ArWhitener::fit(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout, int max_order) {
  ArWhitener w;
  if (max_order <= 0) return w;
  // Autocovariances summed within cases (a lag never pairs samples of two cases).
  Eigen::VectorXd acov = Eigen::VectorXd::Zero(max_order + 1);
  double n = 0.0;
  for (const CaseRows& c : layout) {
    const auto e = residuals.segment(c.begin, c.rows);   // read in place: the products' sums do not depend on where it starts
    n += static_cast<double>(c.rows);
    // The lags split over parallel::jobs() threads; a lag's sum does not depend on its thread.
    const int lags = static_cast<int>(std::min<Eigen::Index>(max_order + 1, c.rows));
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(parallel::threads_for(lags))
#endif
    for (int lag = 0; lag < lags; ++lag) {
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

void ar_filter_column(const Eigen::VectorXd& a, const double* x, double* out, Eigen::Index n) {
  constexpr Eigen::Index kRows = 16;
  using Rows = Eigen::Array<double, kRows, 1>;
  const Eigen::Index m = a.size();
  Eigen::Index r = 0;
  for (; r + kRows <= n; r += kRows) {
    Rows sum = Eigen::Map<const Rows>(x + r + m);
    for (Eigen::Index j = 1; j <= m; ++j) sum -= a(j - 1) * Eigen::Map<const Rows>(x + r + m - j);
    Eigen::Map<Rows>(out + r) = sum;
  }
  for (; r < n; ++r) {
    double sum = x[r + m];
    for (Eigen::Index j = 1; j <= m; ++j) sum -= a(j - 1) * x[r + m - j];
    out[r] = sum;
  }
}

namespace {

/// The rows an AR filter of order m keeps of the stacked `cases`: each case loses its first m,
/// and the rest move up to follow the previous case's.
std::vector<CaseRows> filtered_layout(const std::vector<CaseRows>& cases, Eigen::Index m) {
  std::vector<CaseRows> out;
  Eigen::Index begin = 0;
  for (const CaseRows& c : cases) {
    const Eigen::Index rows = c.rows - m;
    if (rows <= 0) continue;
    out.push_back(CaseRows{c.case_index, begin, rows, c.first_sample + m});
    begin += rows;
  }
  return out;
}

/// x (one stacked vector, rows laid out as `from`) filtered by A(q) case by case into the rows
/// of `to` (filtered_layout). Row r of a case's result is sample r + m of the case:
/// x[k] - sum a_j x[k - j], into `scratch`, then copied to rows already consumed
/// (to.begin <= from.begin), so in place is safe.
template <class X>
void filter_stacked(const Eigen::VectorXd& a, X&& x, const std::vector<CaseRows>& from, const std::vector<CaseRows>& to,
                    Eigen::VectorXd& scratch) {
  const Eigen::Index m = a.size();
  std::size_t k = 0;
  for (const CaseRows& c : from) {
    if (c.rows - m <= 0) continue;
    const CaseRows& out = to[k++];
    ar_filter(a, x.segment(c.begin, out.rows + m), scratch.head(out.rows));
    x.segment(out.begin, out.rows) = scratch.head(out.rows);
  }
}

Eigen::Index longest(const std::vector<CaseRows>& cases) {
  Eigen::Index rows = 0;
  for (const CaseRows& c : cases) rows = std::max(rows, c.rows);
  return rows;
}

/// Every column of x through filter_stacked, the columns split over parallel::jobs() threads
/// (each column's arithmetic is the same on any thread), each thread with its own scratch.
void filter_columns(const Eigen::VectorXd& a, Eigen::MatrixXd& x, const std::vector<CaseRows>& from,
                    const std::vector<CaseRows>& to) {
  const Eigen::Index columns = x.cols();
#ifdef _OPENMP
#pragma omp parallel num_threads(parallel::threads_for(columns))
#endif
  {
    Eigen::VectorXd scratch(longest(to));
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
    for (Eigen::Index col = 0; col < columns; ++col) filter_stacked(a, x.col(col), from, to, scratch);
  }
}

/// Keeps x's first `rows` rows in place. conservativeResize of a column-major matrix's rows
/// builds a new matrix and copies into it, for a moment holding the stack twice. Here each column's leading rows move down to where a
/// matrix of `rows` rows keeps them, and the buffer shrinks by realloc: Eigen leaves the
/// coefficients unchanged when resize() keeps their number, and conservativeResize() of a
/// column-major matrix that keeps its rows reallocates.
void keep_leading_rows(Eigen::MatrixXd& x, Eigen::Index rows) {
  const Eigen::Index n = x.rows(), cols = x.cols();
  if (rows >= n) return;
  double* data = x.data();
  for (Eigen::Index j = 1; j < cols; ++j)
    std::memmove(data + j * rows, data + j * n, static_cast<std::size_t>(rows) * sizeof(double));
  x.resize(1, n * cols);
  x.conservativeResize(1, rows * cols);
  x.resize(rows, cols);
}

Eigen::Index total_rows(const std::vector<CaseRows>& cases) {
  Eigen::Index rows = 0;
  for (const CaseRows& c : cases) rows += c.rows;
  return rows;
}

}  // namespace

void ArWhitener::apply(StackedRegression& s) const {
  const int m = order();
  if (m == 0) return;
  std::vector<CaseRows> cases = filtered_layout(s.cases, m);
  {
    Eigen::VectorXd scratch(longest(cases));
    filter_stacked(a_, s.y, s.cases, cases, scratch);
  }
  filter_columns(a_, s.phi, s.cases, cases);
  // The factors of output-multiplied columns are not filtered (stacked_regression.hpp): they only
  // lose the same first rows.
  if (s.rational.factors.rows() > 0) {
    std::size_t k = 0;
    for (const CaseRows& c : s.cases) {
      if (c.rows - m <= 0) continue;
      const CaseRows& out = cases[k++];
      s.rational.factors.middleRows(out.begin, out.rows) = s.rational.factors.middleRows(c.begin + m, out.rows).eval();
    }
  }
  const Eigen::Index out = total_rows(cases);
  keep_leading_rows(s.phi, out);
  s.y.conservativeResize(out);
  if (s.rational.factors.rows() > 0) keep_leading_rows(s.rational.factors, out);
  s.cases = std::move(cases);
}

void ArWhitener::apply_to_columns(Eigen::MatrixXd& x, const std::vector<CaseRows>& cases) const {
  const int m = order();
  if (m == 0) return;
  const std::vector<CaseRows> filtered = filtered_layout(cases, m);
  filter_columns(a_, x, cases, filtered);
  keep_leading_rows(x, total_rows(filtered));
}

}  // namespace inertia::procedure
