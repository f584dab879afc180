// AR prewhitening: recovers a known AR process and whitens it; respects case boundaries.
#include "analyzer/procedure/prewhitening.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace inertia::procedure {
namespace {

Eigen::VectorXd ar2(Eigen::Index n, double a1, double a2, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd e(n);
  double x1 = 0, x2 = 0;
  for (Eigen::Index k = -500; k < n; ++k) {   // burn-in so the series is stationary
    const double x = a1 * x1 + a2 * x2 + g(rng);
    x2 = x1;
    x1 = x;
    if (k >= 0) e(k) = x;
  }
  return e;
}

TEST(ArWhitener, RecoversAr2CoefficientsWithinTheirSamplingSpread) {
  const Eigen::Index n = 100000;
  const Eigen::VectorXd e = ar2(n, 1.2, -0.5, 11);
  const std::vector<CaseRows> layout = {CaseRows{0, 0, n, 0}};
  const ArWhitener w = ArWhitener::fit(e, layout, 10);
  ASSERT_GE(w.order(), 2);
  // Asymptotic sd of AR(2) estimates: sqrt((1 - a2^2) / N) = 0.0027 at N = 1e5; allow 4 sd.
  const double sd = std::sqrt((1.0 - 0.25) / static_cast<double>(n));
  EXPECT_NEAR(w.coefficients()(0), 1.2, 4 * sd);
  EXPECT_NEAR(w.coefficients()(1), -0.5, 4 * sd);
  for (int j = 2; j < w.order(); ++j) EXPECT_NEAR(w.coefficients()(j), 0.0, 4 * sd);
  // Innovation variance 1 against the process variance of this AR(2).
  const double process_var = e.squaredNorm() / static_cast<double>(n);
  EXPECT_NEAR(w.variance_ratio(), 1.0 / process_var, 0.02 / process_var);
}

TEST(ArWhitener, WhiteInputNeedsNoFilter) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd e(50000);
  for (Eigen::Index k = 0; k < e.size(); ++k) e(k) = g(rng);
  const ArWhitener w = ArWhitener::fit(e, {CaseRows{0, 0, e.size(), 0}}, 10);
  // AIC may keep a spurious small order now and then; its coefficients must be tiny.
  for (int j = 0; j < w.order(); ++j) EXPECT_LT(std::abs(w.coefficients()(j)), 4.0 / std::sqrt(5e4));
}

TEST(ArWhitener, FiltersEachCaseWithoutCrossingItsStart) {
  StackedRegression s;
  s.phi = Eigen::MatrixXd(10, 1);
  s.y = Eigen::VectorXd(10);
  for (int k = 0; k < 10; ++k) {
    s.phi(k, 0) = k;
    s.y(k) = 100 + k;
  }
  s.cases = {CaseRows{0, 0, 4, 0}, CaseRows{1, 4, 6, 0}};
  s.labels = {"a_i"};
  const Eigen::VectorXd e = ar2(20000, 0.5, 0.0, 2);
  const ArWhitener w = ArWhitener::fit(e, {CaseRows{0, 0, e.size(), 0}}, 1);
  ASSERT_EQ(w.order(), 1);
  const double a = w.coefficients()(0);
  w.apply(s);
  ASSERT_EQ(s.y.size(), 8);   // each case lost its first row
  EXPECT_DOUBLE_EQ(s.y(0), 101 - a * 100);        // case 0, sample 1
  EXPECT_DOUBLE_EQ(s.y(3), 105 - a * 104);        // case 1, sample 1 (sample 0 is row 4, not row 3)
  EXPECT_DOUBLE_EQ(s.phi(3, 0), 5 - a * 4);
  EXPECT_EQ(s.cases[1].begin, 3);
  EXPECT_EQ(s.cases[1].first_sample, 1);
}

// Columns filtered on their own keep the rows, and the values, of the same columns filtered in
// a stacked regression: a case shorter than the order drops out of both, and the blocks of rows
// the filter works in (2048) are crossed.
TEST(ArWhitener, ColumnsAloneMatchTheStackedRegressionsRows) {
  const ArWhitener w = ArWhitener::of(Eigen::Vector3d(0.6, -0.2, 0.1));
  StackedRegression s;
  s.cases = {CaseRows{0, 0, 5000, 0}, CaseRows{1, 5000, 2, 0}, CaseRows{2, 5002, 3000, 7}};
  s.phi = Eigen::MatrixXd::Random(8002, 3);
  s.y = Eigen::VectorXd::Random(8002);
  s.labels = {"a_i", "a_p", "a_o"};
  const std::vector<CaseRows> layout = s.cases;
  Eigen::MatrixXd alone = s.phi.rightCols(2);
  w.apply(s);
  w.apply_to_columns(alone, layout);
  ASSERT_EQ(alone.rows(), s.phi.rows());
  EXPECT_EQ(alone.rows(), 4997 + 2997);
  EXPECT_EQ(alone, s.phi.rightCols(2));   // the same operations in the same order: equal, not near
  ASSERT_EQ(s.cases.size(), 2U);
  EXPECT_EQ(s.cases[1].begin, 4997);
  EXPECT_EQ(s.cases[1].first_sample, 10);
}

// A(q) inverts the AR process that made the series: the filtered series is its innovations,
// and the filter gives the same rows whether a series is filtered at once or in chunks that each
// carry the last m rows of the one before (the live estimator's segments).
TEST(ArFilter, UndoesTheArProcessAndChunksAgreeWithOnePass) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector2d a(1.2, -0.5);
  const Eigen::Index n = 400;
  Eigen::VectorXd e(n), x(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    e(k) = g(rng);
    x(k) = e(k) + (k >= 1 ? a(0) * x(k - 1) : 0.0) + (k >= 2 ? a(1) * x(k - 2) : 0.0);
  }
  Eigen::VectorXd whole;
  ar_filter(a, x, whole);
  ASSERT_EQ(whole.size(), n - 2);
  EXPECT_LT((whole - e.tail(n - 2)).cwiseAbs().maxCoeff(), 1e-12);
  Eigen::MatrixXd columns(n, 2);
  columns << x, 2.0 * x;
  Eigen::MatrixXd chunked(n - 2, 2);
  for (Eigen::Index begin = 2, length = 5; begin < n; begin += length, length += 7) {
    const Eigen::Index rows = std::min(length, n - begin);
    ar_filter(a, columns.middleRows(begin - 2, rows + 2), chunked.middleRows(begin - 2, rows));
  }
  EXPECT_EQ(chunked.col(0), whole);
  EXPECT_EQ(chunked.col(1), 2.0 * whole);
  Eigen::VectorXd none;
  ar_filter(Eigen::VectorXd(), x, none);
  EXPECT_EQ(none, x);
}

TEST(ArFilter, AHighOrderOnRowsNotAMultipleOfTheBlockIsTheScalarRecursion) {
  // The orders the procedure picks reach 120; rows are filtered 16 at a time and the rest one by
  // one. Both must be the plain sum x[k] - sum a_j x[k - j], to the rounding of m + 1 terms (a
  // compiler may fuse a product into the difference in one loop and not in the other).
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const Eigen::Index m : {1, 15, 16, 17, 120}) {
    Eigen::VectorXd a(m), x(m + 16 * 9 + 7);
    for (Eigen::Index j = 0; j < m; ++j) a(j) = g(rng) / static_cast<double>(m);
    for (Eigen::Index k = 0; k < x.size(); ++k) x(k) = g(rng);
    Eigen::VectorXd filtered;
    ar_filter(a, x, filtered);
    ASSERT_EQ(filtered.size(), x.size() - m);
    for (Eigen::Index r = 0; r < filtered.size(); ++r) {
      double expected = x(r + m), scale = std::abs(x(r + m));
      for (Eigen::Index j = 1; j <= m; ++j) {
        expected -= a(j - 1) * x(r + m - j);
        scale += std::abs(a(j - 1) * x(r + m - j));
      }
      EXPECT_NEAR(filtered(r), expected, static_cast<double>(m + 1) * std::numeric_limits<double>::epsilon() * scale)
          << "order " << m << ", row " << r;
    }
  }
}

}  // namespace
}  // namespace inertia::procedure
