// The variance factor of rows kept unfiltered under an AR noise model, against the AR process's
// own long-run variance.
#include "analyzer/procedure/post_selection_inference.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "analyzer/procedure/prewhitening.hpp"

namespace inertia::procedure {
namespace {

/// `runs` runs of n rows of AR(1) noise x_k = phi x_{k-1} + e_k, each started stationary.
Eigen::VectorXd ar1_runs(int runs, Eigen::Index n, double phi, std::uint64_t seed, std::vector<CaseRows>& layout) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd x(runs * n);
  for (int r = 0; r < runs; ++r) {
    double previous = g(rng) / std::sqrt(1.0 - phi * phi);
    for (Eigen::Index k = 0; k < n; ++k) x(r * n + k) = previous = phi * previous + g(rng);
    layout.push_back(CaseRows{static_cast<std::size_t>(r), r * n, n, 0});
  }
  return x;
}

struct Spread {
  double mean = 0.0, standard_error = 0.0, min = 0.0;
};

/// The factor over `seeds` seeds of `runs` runs of n rows of AR(1) noise: its mean, the mean's
/// standard error from the seeds' scatter, and the smallest. `with_ar`: through the AR model fitted
/// to the rows (rows kept unfiltered), or the rows taken as whitened already.
Spread factor_over_seeds(double phi, int runs, Eigen::Index n, int seeds, bool with_ar) {
  std::vector<double> f;
  for (int seed = 0; seed < seeds; ++seed) {
    std::vector<CaseRows> layout;
    const Eigen::VectorXd x = ar1_runs(runs, n, phi, 100 + static_cast<std::uint64_t>(seed), layout);
    const Eigen::VectorXd ar = with_ar ? ArWhitener::fit(x, layout, 20).coefficients() : Eigen::VectorXd();
    f.push_back(unfiltered_long_run_ratio(x, layout, ar));
  }
  Spread out;
  out.min = f.front();
  for (double v : f) {
    out.mean += v / seeds;
    out.min = std::min(out.min, v);
  }
  double ss = 0.0;
  for (double v : f) ss += (v - out.mean) * (v - out.mean);
  out.standard_error = std::sqrt(ss / (seeds - 1) / seeds);
  return out;
}

// The fitted spectrum's low-frequency terms (flicker, random walk) are non-negative: what they
// pick up of the noise's scatter makes the factor conservative on average, never optimistic. The
// tests allow that by kConservative on top of the seeds' own scatter.
constexpr double kConservative = 0.05;

TEST(UnfilteredLongRunRatio, IsTheArProcesssLongRunVarianceOverItsVariance) {
  // AR(1): the run sum's variance over n is sigma_e^2 / (1 - phi)^2 and the rows' variance
  // sigma_e^2 / (1 - phi^2), so the ratio is (1 + phi) / (1 - phi) = 19 (the runs' edges change it
  // by about 2 phi / (n (1 - phi^2)), 5e-4 here).
  const double phi = 0.9, truth = (1.0 + phi) / (1.0 - phi);
  const Spread s = factor_over_seeds(phi, 4, 20000, 20, true);
  EXPECT_GT(s.mean, truth - 4.0 * s.standard_error);
  EXPECT_LT(s.mean, truth * (1.0 + kConservative) + 4.0 * s.standard_error);
}

TEST(UnfilteredLongRunRatio, WhiteNoiseKeepsItsVariance) {
  // Under white noise every column's least-squares variance is the classical one: the factor is 1,
  // never below (a dip of the estimated spectrum at zero is not taken as information), through an
  // AR model fitted to the rows or on rows taken as whitened.
  for (const bool with_ar : {true, false}) {
    const Spread s = factor_over_seeds(0.0, 3, 20000, 20, with_ar);
    EXPECT_GE(s.min, 1.0) << with_ar;
    EXPECT_LT(s.mean, 1.0 + kConservative + 4.0 * s.standard_error) << with_ar;
  }
}

TEST(UnfilteredLongRunRatio, NoRowsGiveTheClassicalVariance) {
  EXPECT_EQ(unfiltered_long_run_ratio(Eigen::VectorXd(), {}, Eigen::VectorXd()), 1.0);
  const Eigen::VectorXd zeros = Eigen::VectorXd::Zero(100);
  EXPECT_EQ(unfiltered_long_run_ratio(zeros, {CaseRows{0, 0, 100, 0}}, Eigen::VectorXd()), 1.0);
}

}  // namespace
}  // namespace inertia::procedure
