#include "analyzer/ident/static_gain.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace inertia::ident {
namespace {

// y[k] = 0.9 y[k-1] + 0.5 a_i[k] - 0.3 a_i[k-1] + 0.02 a_i[k-1]*a_p[k-1] + 0.1 + e[k]: static
// gains a_i (0.5 - 0.3) / 0.1 = 2, a_i*a_p 0.2, bias 1.
struct Arx {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
};

Arx simulate(unsigned seed, Eigen::Index n) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd ai(n), ap(n), y(n);
  for (Eigen::Index k = 0; k < n; ++k) ai(k) = g(rng), ap(k) = g(rng);
  y(0) = 0.0;
  for (Eigen::Index k = 1; k < n; ++k)
    y(k) = 0.9 * y(k - 1) + 0.5 * ai(k) - 0.3 * ai(k - 1) + 0.02 * ai(k - 1) * ap(k - 1) + 0.1 + 0.05 * g(rng);
  Arx a;
  const Eigen::Index rows = n - 1;
  a.phi.resize(rows, 5);
  a.phi.col(0).setOnes();
  a.phi.col(1) = ai.tail(rows);
  a.phi.col(2) = ai.head(rows);
  a.phi.col(3) = (ai.head(rows).array() * ap.head(rows).array()).matrix();
  a.phi.col(4) = y.head(rows);
  a.y = y.tail(rows);
  return a;
}

const std::vector<std::string> kLabels = {"1", "a_i", "a_i[k-1]", "a_i[k-1]*a_p[k-1]", "y[k-1]"};

TEST(StaticGain, ArxGainsAndTheirSpreadOverSeeds) {
  const int seeds = 200;
  Eigen::MatrixXd gains(seeds, 3);
  Eigen::MatrixXd reported(seeds, 3);
  for (int s = 0; s < seeds; ++s) {
    const Arx a = simulate(100u + unsigned(s), 2000);
    const std::vector<StaticGain> g = static_gains(uls_batch(a.phi, a.y, kLabels, {}, UlsOptions{}));
    ASSERT_EQ(g.size(), 3u);
    EXPECT_EQ(g[0].term, "1");
    EXPECT_EQ(g[1].term, "a_i");
    EXPECT_EQ(g[1].lagged, (std::vector<std::string>{"a_i", "a_i[k-1]"}));
    EXPECT_EQ(g[2].term, "a_i*a_p");
    for (int j = 0; j < 3; ++j) {
      gains(s, j) = g[static_cast<std::size_t>(j)].gain;
      reported(s, j) = g[static_cast<std::size_t>(j)].std_dev;
    }
  }
  const double truth[3] = {1.0, 2.0, 0.2};
  for (int j = 0; j < 3; ++j) {
    const double mean = gains.col(j).mean();
    const double spread = std::sqrt((gains.col(j).array() - mean).square().sum() / (seeds - 1));
    const double typical = reported.col(j).mean();
    // Unbiased to 4 standard errors of the mean over seeds; the delta method's sd matches the
    // spread over seeds within the 10% a sample sd of 200 draws allows (plus its first-order error).
    EXPECT_NEAR(mean, truth[j], 4.0 * spread / std::sqrt(double(seeds))) << j;
    EXPECT_NEAR(typical / spread, 1.0, 0.15) << j;
  }
}

TEST(StaticGain, StaticModelHasNone) {
  UlsResult fit;
  fit.labels = {"1", "a_i", "a_i^2"};
  fit.process_terms = 3;
  fit.theta = Eigen::VectorXd{{0.1, 2.0, 0.01}};
  fit.covariance = Eigen::MatrixXd::Identity(3, 3);
  EXPECT_TRUE(static_gains(fit).empty());
}

TEST(StaticGain, LaggedInputsWithoutOutputLagsAreSummed) {
  UlsResult fit;
  fit.labels = {"a_i", "a_i[k-1]", "a_i[k-2]", "e[k-1]"};
  fit.process_terms = 3;
  fit.theta = Eigen::VectorXd{{1.0, 0.5, -0.25, 0.3}};
  fit.covariance = Eigen::VectorXd{{0.01, 0.04, 0.09, 1.0}}.asDiagonal();
  const std::vector<StaticGain> g = static_gains(fit);
  ASSERT_EQ(g.size(), 1u);
  EXPECT_DOUBLE_EQ(g[0].gain, 1.25);
  EXPECT_NEAR(g[0].std_dev, std::sqrt(0.14), 1e-12);   // the noise term's variance stays out
}

}  // namespace
}  // namespace inertia::ident
