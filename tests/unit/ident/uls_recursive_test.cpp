#include "analyzer/ident/uls_recursive.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/unit/ident/ident_test_data.hpp"

namespace inertia::ident {
namespace {

// Every component within `rel` of the batch value, relative to its own magnitude.
void expect_relative(const Eigen::VectorXd& got, const Eigen::VectorXd& want, double rel) {
  ASSERT_EQ(got.size(), want.size());
  for (Eigen::Index j = 0; j < got.size(); ++j)
    EXPECT_NEAR(got[j], want[j], rel * std::abs(want[j])) << "parameter " << j;
}

struct PolynomialData {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  std::vector<std::string> labels{"1", "u", "u^2", "y[k-1]"};
};

PolynomialData polynomial_data(unsigned seed, Eigen::Index n) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  PolynomialData d;
  d.phi.resize(n, 4);
  d.y.resize(n);
  double prev = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double u = g(rng);
    d.phi.row(k) << 1.0, u, u * u, prev;
    d.y[k] = 0.3 + 2.0 * u - 0.5 * u * u + 0.6 * prev + 0.1 * g(rng);
    prev = d.y[k];
  }
  return d;
}

TEST(UlsRecursive, MatchesBatchPolynomial) {
  const auto d = polynomial_data(3, 3000);
  const UlsResult batch = uls_batch(d.phi, d.y, d.labels, {}, UlsOptions{});
  const Eigen::VectorXd none(0);
  // Batch initialization on the first 200 samples: no prior left, exact agreement expected.
  UlsRecursive rec(4, {}, RecursiveUlsOptions{});
  rec.initialize(d.phi.topRows(200), d.y.head(200), Eigen::MatrixXd(200, 0));
  for (Eigen::Index k = 200; k < d.phi.rows(); ++k) rec.update(d.phi.row(k).transpose(), d.y[k], none);
  const RecursiveEstimate est = rec.estimate();
  expect_relative(est.theta, batch.theta, 1e-6);
  expect_relative(est.std_dev, batch.std_dev, 1e-6);
  EXPECT_NEAR(est.residual_variance, batch.residual_variance, 1e-6 * batch.residual_variance);
  // P0 = 1e6 I from the first sample: the prior's weight is 1e-6 against N = 3000.
  UlsRecursive cold(4, {}, RecursiveUlsOptions{});
  for (Eigen::Index k = 0; k < d.phi.rows(); ++k) cold.update(d.phi.row(k).transpose(), d.y[k], none);
  expect_relative(cold.estimate().theta, batch.theta, 1e-6);
}

TEST(UlsRecursive, MatchesBatchRational) {
  for (double sigma : {0.05, 0.1, 0.2}) {
    const auto ex = testing::rational_example(7, 3000, sigma);
    const OutputMultiplied rational{ex.output_multiplied, ex.factors};
    const UlsResult batch = uls_batch(ex.phi, ex.y, ex.labels, rational, UlsOptions{});
    UlsRecursive rec(5, ex.output_multiplied, RecursiveUlsOptions{});
    rec.initialize(ex.phi.topRows(300), ex.y.head(300), ex.factors.topRows(300));
    for (Eigen::Index k = 300; k < ex.phi.rows(); ++k)
      rec.update(ex.phi.row(k).transpose(), ex.y[k], ex.factors.row(k).transpose());
    const RecursiveEstimate est = rec.estimate();
    EXPECT_TRUE(est.compensating);
    SCOPED_TRACE("sigma = " + std::to_string(sigma));
    expect_relative(est.theta, batch.theta, 1e-6);
    EXPECT_NEAR(est.sigma2, batch.sigma2, 1e-6 * batch.sigma2);
    // The per-sample estimate (3 fixed-point steps per sample) is already close.
    expect_relative(rec.theta(), batch.theta, 1e-3);
  }
}

// RELS with a-posteriori residuals (notes §4.2: 0.2025 for truth 0.2; LS 0.288).
TEST(UlsRecursive, RelsReducesMaBias) {
  const int runs = 20;
  Eigen::MatrixXd rels(runs, 4), els(runs, 4);
  RecursiveUlsOptions options;
  options.noise_lags = 1;
  UlsOptions batch_options;
  batch_options.noise_lags = 1;
  for (int r = 0; r < runs; ++r) {
    const auto ex = testing::armax_example(300 + r, 3000, 0.2);
    UlsRecursive rec(3, {}, options);
    rec.initialize(ex.phi.topRows(100), ex.y.head(100), Eigen::MatrixXd(100, 0));
    const Eigen::VectorXd none(0);
    for (Eigen::Index k = 100; k < ex.phi.rows(); ++k) rec.update(ex.phi.row(k).transpose(), ex.y[k], none);
    rels.row(r) = rec.estimate().theta.transpose();
    els.row(r) = uls_batch(ex.phi, ex.y, ex.labels, {}, batch_options).theta.transpose();
  }
  const auto [mean, sd] = testing::column_mean_sd(rels);
  const Eigen::VectorXd els_sd = testing::column_mean_sd(els).second;
  const Eigen::Vector4d truth(0.2, 0.1, 0.9, 0.8);
  // RELS forms residuals with the estimate of their time, so it is compared with the truth (not
  // with batch ELS): within 4 standard errors of the 20-run mean.
  for (int j = 0; j < 4; ++j)
    EXPECT_NEAR(mean[j], truth[j], 4.0 * sd[j] / std::sqrt(double(runs))) << j;
  // and its spread is that of the batch estimator (same information), within sampling error.
  for (int j = 0; j < 4; ++j) {
    EXPECT_LT(sd[j], 1.6 * els_sd[j]) << j;
    EXPECT_GT(sd[j], els_sd[j] / 1.6) << j;
  }
}

// Forgetting tracks a step in a parameter; covariance resetting fires under poor excitation.
TEST(UlsRecursive, ForgettingTracksStepAndResetsCovariance) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> g(0.0, 1.0);
  RecursiveUlsOptions options;
  options.forgetting = 0.99;  // memory ~100 samples
  options.initial_covariance = 1e2;  // trace(P0) = 200 on unit-scaled regressors
  options.reset_trace = 1e3;
  UlsRecursive rec(2, {}, options, Eigen::Vector2d(1.0, 1.0));
  const Eigen::VectorXd none(0);
  const double sigma = 0.01;
  for (int k = 0; k < 4000; ++k) {
    const double u = g(rng);
    const double gain = k < 2000 ? 1.0 : 1.5;
    rec.update(Eigen::Vector2d(1.0, u), 0.2 + gain * u + sigma * g(rng), none);
    // Exponentially weighted LS: var = sigma^2 (1 - lambda) / ((1 + lambda) var(u)).
    if (k == 1999) {
      EXPECT_NEAR(rec.theta()[1], 1.0, 6.0 * sigma * std::sqrt(0.01 / 1.99));
    }
  }
  // ~2000 samples = 20 memory lengths after the step: the old value is forgotten.
  const RecursiveEstimate est = rec.estimate();
  EXPECT_NEAR(est.theta[1], 1.5, 6.0 * est.std_dev[1] + 1e-6);
  EXPECT_NEAR(est.effective_samples, 1.0 / (1.0 - 0.99), 1.0);
  const int before = rec.resets();
  // Constant input: the u direction is not excited, P grows like 0.99^-k until the reset.
  for (int k = 0; k < 2000; ++k) rec.update(Eigen::Vector2d(1.0, 0.0), 0.2 + sigma * g(rng), none);
  EXPECT_GT(rec.resets(), before);
  EXPECT_TRUE(rec.estimate().theta.allFinite());
}

TEST(UlsRecursive, RejectsBadOptions) {
  RecursiveUlsOptions bad;
  bad.forgetting = 1.2;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("1.2"), std::string::npos);
  EXPECT_THROW(UlsRecursive(2, {}, bad), std::invalid_argument);
  EXPECT_THROW(UlsRecursive(2, {5}, RecursiveUlsOptions{}), std::invalid_argument);
  RecursiveUlsOptions low_reset;
  low_reset.forgetting = 0.99;
  low_reset.reset_trace = 10.0;  // below trace(P0) = 2e6: would reset on every sample
  EXPECT_THROW(UlsRecursive(2, {}, low_reset), std::invalid_argument);
}

}  // namespace
}  // namespace inertia::ident
