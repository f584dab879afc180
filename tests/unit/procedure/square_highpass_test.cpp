// Eq. 12's high pass s / (s + b) on the squares (procedure/square_highpass.hpp): its response
// against the analytic transfer function of the prewarped bilinear transform, its start-up and
// block continuation against a reference recursion written here, the filter restarted per case,
// and the corner search's residual against a direct least-squares solve.
#include "analyzer/procedure/square_highpass.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "common/parallel.hpp"
#include "tests/support/reference_highpass.hpp"

namespace inertia::procedure {
namespace {

using Eigen::Index;

using inertia::testing::reference_highpass;

TEST(SquareHighpass, ConstantInputGivesZero) {
  // Zero DC gain and a settled start: a constant never leaves the filter.
  Eigen::VectorXd x = Eigen::VectorXd::Constant(500, 96.2);
  highpass_in_place(x, 500.0, 1e-3);
  EXPECT_EQ(x, Eigen::VectorXd::Zero(500));
}

TEST(SquareHighpass, SinusoidFollowsTheAnalyticTransferFunction) {
  // Bilinear transform prewarped at b: H(e^{j w T}) = H_a(j W), W = b tan(w T / 2) / tan(b T / 2),
  // H_a(s) = s / (s + b); at w = b exactly the analog corner: gain 1/sqrt(2), phase +45 degrees.
  const double b = 500.0, period = 1e-3;
  const Index n = 2000, settled = 400;   // the start-up decays as p^k, p ~ 0.59 here
  for (const double w : {50.0, 500.0, 2000.0}) {
    const double warped = b * std::tan(w * period / 2.0) / std::tan(b * period / 2.0);
    const std::complex<double> h = std::complex<double>(0.0, warped) / std::complex<double>(b, warped);
    if (w == b) {
      EXPECT_NEAR(std::abs(h), 1.0 / std::numbers::sqrt2, 1e-15);
      EXPECT_NEAR(std::arg(h), std::numbers::pi / 4.0, 1e-15);
    }
    Eigen::VectorXd x(n);
    for (Index k = 0; k < n; ++k) x(k) = std::sin(w * period * static_cast<double>(k));
    highpass_in_place(x, b, period);
    double worst = 0.0;
    for (Index k = settled; k < n; ++k) {
      const double expected = std::abs(h) * std::sin(w * period * static_cast<double>(k) + std::arg(h));
      worst = std::max(worst, std::abs(x(k) - expected));
    }
    EXPECT_LT(worst, 1e-12) << "w = " << w;
  }
}

TEST(SquareHighpass, StepResponseIsGTimesPToTheK) {
  // A unit step at sample 10: h(10 + m) = g p^m with p, g from the bilinear map of s / (s + b).
  const double b = 200.0, period = 2e-3;
  const double c = b / std::tan(b * period / 2.0);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(60);
  x.tail(50).setOnes();
  highpass_in_place(x, b, period);
  for (Index k = 0; k < 10; ++k) EXPECT_EQ(x(k), 0.0);
  for (Index m = 0; m < 50; ++m) {
    const double expected = c / (c + b) * std::pow((c - b) / (c + b), static_cast<double>(m));
    EXPECT_NEAR(x(10 + m), expected, 1e-14) << m;
  }
}

TEST(SquareHighpass, BlocksContinueAsOneSignal) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(1.0, 2.0);
  Eigen::VectorXd x(1000);
  for (Index k = 0; k < x.size(); ++k) x(k) = g(rng);
  const Eigen::VectorXd expected = reference_highpass(x, 700.0, 1e-3);
  Eigen::VectorXd whole = x;
  highpass_in_place(whole, 700.0, 1e-3);
  EXPECT_LT((whole - expected).cwiseAbs().maxCoeff(), 1e-12);
  // Blocks of 1, 7, 300, 0 and the rest, one state carried between them.
  HighpassState state;
  Eigen::VectorXd blocks = x;
  Index at = 0;
  for (const Index len : {Index{1}, Index{7}, Index{300}, Index{0}, Index{692}}) {
    highpass_in_place(blocks.segment(at, len), 700.0, 1e-3, state);
    at += len;
  }
  ASSERT_EQ(at, x.size());
  EXPECT_LT((blocks - expected).cwiseAbs().maxCoeff(), 1e-12);
}

dataset::Dataset two_case_dataset(double period_a, double period_b) {
  dataset::Dataset d;
  d.cases.resize(2);
  d.cases[0].sample_period_s = period_a;
  d.cases[1].sample_period_s = period_b;
  return d;
}

TEST(SquareHighpass, ColumnsRestartAtEveryCase) {
  const dataset::Dataset data = two_case_dataset(1e-3, 2e-3);
  const std::vector<CaseRows> layout = {CaseRows{0, 0, 300, 0}, CaseRows{1, 300, 200, 0}};
  std::mt19937_64 rng(4);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd x(500, 3);
  for (Index k = 0; k < 500; ++k) x.row(k) << g(rng), g(rng), (k < 300 ? 1.0 : 5.0);
  const Eigen::MatrixXd original = x;
  highpass_columns(x, {0, 2}, layout, data, 300.0);
  // Column 0 filtered per case, each at its own period, each starting settled.
  const Eigen::VectorXd a = reference_highpass(original.col(0).head(300), 300.0, 1e-3);
  const Eigen::VectorXd b = reference_highpass(original.col(0).tail(200), 300.0, 2e-3);
  EXPECT_LT((x.col(0).head(300) - a).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((x.col(0).tail(200) - b).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(x.col(1), original.col(1)) << "a column not asked for is left alone";
  // A level that is constant within each case: zero throughout. Run across the boundary, the
  // step 1 -> 5 would give 4 g there.
  EXPECT_EQ(x.col(2), Eigen::VectorXd::Zero(500));
}

TEST(SquareHighpass, MaxCornerIsBelowTheSlowestCasesNyquist) {
  const std::vector<CaseRows> layout = {CaseRows{0, 0, 10, 0}, CaseRows{1, 10, 10, 0}};
  EXPECT_DOUBLE_EQ(max_corner(layout, two_case_dataset(1e-3, 2e-3)), 0.9 * std::numbers::pi / 2e-3);
  EXPECT_EQ(max_corner(layout, two_case_dataset(1e-3, 0.0)), 0.0);
}

TEST(SquareHighpass, SquareTerms) {
  for (const char* t : {"a_i^2", "a_p^2", "a_o^2", "a_o^2[k-1]", "abs(a_i)^2"}) EXPECT_TRUE(is_square_term(ident::parse_term(t))) << t;
  for (const char* t : {"1", "a_i", "a_i^3", "a_i*a_p", "a_x^2", "w_i^2", "a_i*abs(a_i)", "T^2"})
    EXPECT_FALSE(is_square_term(ident::parse_term(t))) << t;
}

/// A stacked problem over two cases: columns 1, a_i, a_i^2, a_p^2 of random specific force, and
/// y = phi theta with the squares through s / (s + corner) (none: static), plus white noise.
struct CornerProblem {
  dataset::Dataset data = two_case_dataset(1e-3, 1e-3);
  StackedRegression s;
  Eigen::MatrixXd raw;   // phi with static squares
};

CornerProblem corner_problem(std::optional<double> corner, double noise_sd, std::uint64_t seed, Index n0 = 1500, Index n1 = 1000) {
  CornerProblem p;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  p.s.cases = {CaseRows{0, 0, n0, 0}, CaseRows{1, n0, n1, 0}};
  p.s.labels = {"1", "a_i", "a_i^2", "a_p^2"};
  p.raw.resize(n0 + n1, 4);
  for (Index k = 0; k < n0 + n1; ++k) {
    const double ai = 9.8 + 20.0 * g(rng), ap = 15.0 * g(rng);
    p.raw.row(k) << 1.0, ai, ai * ai, ap * ap;
  }
  Eigen::MatrixXd truth_columns = p.raw;
  if (corner) {
    for (const CaseRows& r : p.s.cases)
      for (Index j : {2, 3}) truth_columns.col(j).segment(r.begin, r.rows) = reference_highpass(p.raw.col(j).segment(r.begin, r.rows), *corner, 1e-3);
  }
  const Eigen::Vector4d theta(0.02, 0.09, 4e-4, -3e-4);
  p.s.phi = p.raw;
  p.s.y = truth_columns * theta;
  for (Index k = 0; k < p.s.y.size(); ++k) p.s.y(k) += noise_sd * g(rng);
  return p;
}

/// The residual sum of squares of y on `phi` by a rank-revealing QR solve on the rows.
double direct_rss(const Eigen::MatrixXd& phi, const Eigen::VectorXd& y) {
  const Eigen::VectorXd theta = phi.colPivHouseholderQr().solve(y);
  return (y - phi * theta).squaredNorm();
}

TEST(SquareCornerSearch, RssEqualsADirectSolveStaticAndFiltered) {
  const CornerProblem p = corner_problem(250.0, 0.05, 8);
  const SquareCornerSearch search(p.s, {2, 3}, p.data);
  EXPECT_NEAR(search.rss(std::nullopt), direct_rss(p.raw, p.s.y), 1e-8 * direct_rss(p.raw, p.s.y));
  for (const double b : {30.0, 250.0, 1800.0}) {
    Eigen::MatrixXd filtered = p.raw;
    for (const CaseRows& r : p.s.cases)
      for (Index j : {2, 3}) filtered.col(j).segment(r.begin, r.rows) = reference_highpass(p.raw.col(j).segment(r.begin, r.rows), b, 1e-3);
    const double expected = direct_rss(filtered, p.s.y);
    EXPECT_NEAR(search.rss(b), expected, 1e-8 * expected) << "b = " << b;
  }
}

TEST(SquareCornerSearch, RssIsTheSameBitsOnAnyNumberOfJobs) {
  // The corner's products are formed over blocks of rows that a case's filter runs through; with
  // more than one job the blocks' filter states are found first. Cases of 1500 and 1000 rows
  // span blocks, and neither is a whole number of them.
  const CornerProblem p = corner_problem(250.0, 0.05, 12);
  std::vector<double> serial;
  parallel::set_jobs(1);
  {
    const SquareCornerSearch search(p.s, {2, 3}, p.data);
    for (const double b : {3.0, 250.0, 4000.0}) serial.push_back(search.rss(b));
  }
  for (const int jobs : {2, 3}) {
    parallel::set_jobs(jobs);
    const SquareCornerSearch search(p.s, {2, 3}, p.data);
    std::size_t k = 0;
    for (const double b : {3.0, 250.0, 4000.0}) EXPECT_EQ(search.rss(b), serial[k++]) << "jobs " << jobs << ", b = " << b;
  }
  parallel::set_jobs(1);
}

TEST(SquareCornerSearch, MoreBlocksThanAWindowGiveTheSameBitsOnAnyNumberOfJobs) {
  // Cases of 72,000 and 32,000 rows are 71 + 32 = 103 blocks of 1024, more than a window of 64:
  // the second window holds the first case's last block and the second's first, whose filter must
  // restart there with the second case's sample period.
  CornerProblem p = corner_problem(250.0, 0.05, 14, 72'000, 32'000);
  p.data.cases[1].sample_period_s = 2e-3;
  const std::vector<double> corners{3.0, 250.0, 1200.0};   // below both cases' Nyquist
  std::vector<double> serial;
  parallel::set_jobs(1);
  {
    const SquareCornerSearch search(p.s, {2, 3}, p.data);
    serial = search.rss(std::span<const double>(corners));
    for (std::size_t k = 0; k < corners.size(); ++k) {
      Eigen::MatrixXd filtered = p.raw;
      for (const CaseRows& r : p.s.cases)
        for (Index j : {2, 3})
          filtered.col(j).segment(r.begin, r.rows) =
              reference_highpass(p.raw.col(j).segment(r.begin, r.rows), corners[k], p.data.cases[r.case_index].sample_period_s);
      const double expected = direct_rss(filtered, p.s.y);
      EXPECT_NEAR(serial[k], expected, 1e-8 * expected) << "b = " << corners[k];
    }
  }
  for (const int jobs : {2, 3}) {
    parallel::set_jobs(jobs);
    const SquareCornerSearch search(p.s, {2, 3}, p.data);
    const std::vector<double> together = search.rss(std::span<const double>(corners));
    for (std::size_t k = 0; k < corners.size(); ++k) EXPECT_EQ(together[k], serial[k]) << "jobs " << jobs << ", b = " << corners[k];
  }
  parallel::set_jobs(1);
}

TEST(SquareCornerSearch, SeveralCornersInOnePassGiveEachCornersBits) {
  // The search's grid is one pass over the rows for all its corners; each corner's residual must
  // be what a pass of its own gives, on one job and on several.
  const CornerProblem p = corner_problem(250.0, 0.05, 13);
  const std::vector<double> corners{3.0, 40.0, 250.0, 251.0, 4000.0};
  for (const int jobs : {1, 2, 3}) {
    parallel::set_jobs(jobs);
    const SquareCornerSearch search(p.s, {2, 3}, p.data);
    const std::vector<double> together = search.rss(std::span<const double>(corners));
    ASSERT_EQ(together.size(), corners.size());
    for (std::size_t k = 0; k < corners.size(); ++k) EXPECT_EQ(together[k], search.rss(corners[k])) << "jobs " << jobs << ", b = " << corners[k];
  }
  parallel::set_jobs(1);
}

TEST(SquareCornerSearch, DependentColumnsLeaveTheResidualAlone) {
  // A column repeated: the residual is that of the distinct columns (the search's pseudo-inverse).
  CornerProblem p = corner_problem(std::nullopt, 0.05, 9);
  const Eigen::VectorXd expected_rss = Eigen::VectorXd::Constant(1, direct_rss(p.raw, p.s.y));
  Eigen::MatrixXd doubled(p.raw.rows(), 5);
  doubled << p.raw, p.raw.col(1);
  p.s.phi = doubled;
  const SquareCornerSearch search(p.s, {2, 3}, p.data);
  EXPECT_NEAR(search.rss(std::nullopt), expected_rss(0), 1e-8 * expected_rss(0));
}

TEST(SquareCornerSearch, FindsTheCornerOfNoiselessData) {
  const double corner = 250.0;
  const CornerProblem p = corner_problem(corner, 0.0, 10);
  const SquareCornerSearch search(p.s, {2, 3}, p.data);
  const double yy = p.s.y.squaredNorm();
  EXPECT_LT(std::abs(search.rss(corner)), 1e-10 * yy) << "the true corner explains every sample";
  const std::optional<double> best = search.best(1.0, max_corner(p.s.cases, p.data));
  ASSERT_TRUE(best.has_value());
  // Brent's method stops within about 2 * 2^-13 of log b (14 bits) of the minimum.
  EXPECT_NEAR(std::log(*best), std::log(corner), 3.0 * std::ldexp(1.0, -13) * std::log(corner));
}

TEST(SquareCornerSearch, StaticSquaresWinOnStaticData) {
  const CornerProblem p = corner_problem(std::nullopt, 0.0, 11);
  const SquareCornerSearch search(p.s, {2, 3}, p.data);
  EXPECT_FALSE(search.best(1.0, max_corner(p.s.cases, p.data)).has_value());
  EXPECT_EQ(search.best(420.0, 420.0), std::optional<double>(420.0)) << "a given corner is used as given";
  EXPECT_FALSE(search.best(0.0, 100.0).has_value());
  EXPECT_FALSE(search.best(100.0, 10.0).has_value());
}

}  // namespace
}  // namespace inertia::procedure
