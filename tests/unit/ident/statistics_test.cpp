#include "analyzer/ident/statistics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

namespace inertia::ident {
namespace {

TEST(Statistics, StudentTTableValues) {
  // Two-sided 5% critical values from the standard table (rounded to 3 decimals there).
  EXPECT_NEAR(student_t_two_sided_p(2.228, 10), 0.05, 2e-4);
  EXPECT_NEAR(student_t_two_sided_p(12.706, 1), 0.05, 2e-4);
  EXPECT_NEAR(student_t_two_sided_p(2.086, 20), 0.05, 2e-4);
  EXPECT_NEAR(student_t_two_sided_p(3.169, 10), 0.01, 1e-4);   // 1% column
  EXPECT_NEAR(student_t_two_sided_p(-2.228, 10), 0.05, 2e-4);  // symmetric
  EXPECT_NEAR(student_t_two_sided_p(1.959964, 1e7), 0.05, 1e-6);  // normal limit
  EXPECT_DOUBLE_EQ(student_t_two_sided_p(0.0, 5), 1.0);
}

TEST(Statistics, ParameterTTestUsesEquation11Dof) {
  const Eigen::Vector3d theta(2.228, -0.1, 0.0);
  const Eigen::Vector3d sd(1.0, 1.0, 1.0);
  const ParameterTTest tt = parameter_t_test(theta, sd, 14);  // nu = 14 - 3 - 1 = 10
  EXPECT_DOUBLE_EQ(tt.dof, 10.0);
  EXPECT_NEAR(tt.p_value[0], 0.05, 2e-4);
  EXPECT_NEAR(tt.t[1], -0.1, 1e-15);
  EXPECT_DOUBLE_EQ(tt.p_value[2], 1.0);
}

TEST(Statistics, AicAndRelativeLikelihood) {
  const Eigen::Vector4d e(1.0, -2.0, 2.0, -1.0);  // sum e^2 / N = 10 / 4
  EXPECT_NEAR(aic(e, 3), 4.0 * std::log(2.5) + 6.0, 1e-12);
  const Eigen::Vector4d values(100.0, 102.0, 110.0, std::nan(""));
  const Eigen::VectorXd p = relative_likelihood(values);
  EXPECT_DOUBLE_EQ(p[0], 1.0);
  EXPECT_NEAR(p[1], std::exp(-1.0), 1e-15);
  EXPECT_NEAR(p[2], std::exp(-5.0), 1e-15);
  EXPECT_TRUE(std::isnan(p[3]));
  EXPECT_DOUBLE_EQ(fitness(0.5, p[1]), 0.5 * std::exp(-1.0));
}

Eigen::VectorXd ar1(std::mt19937_64& rng, Eigen::Index n, double phi) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd x(n);
  double prev = g(rng) / std::sqrt(1.0 - phi * phi);  // stationary start
  for (Eigen::Index k = 0; k < n; ++k) prev = x[k] = phi * prev + g(rng);
  return x;
}

// Zero-mean AR(1) residuals: the N_eff test rejects at about its nominal 5%, the naive one far
// more often (the reason for N_eff, statistics.hpp).
TEST(Statistics, ResidualMeanTestFalseAlarmRate) {
  const int seeds = 400;
  const double phi = 0.8;
  std::mt19937_64 rng(77);
  int effective = 0, naive = 0, white = 0;
  for (int s = 0; s < seeds; ++s) {
    const Eigen::VectorXd e = ar1(rng, 2000, phi);
    effective += residual_mean_test(e, true).p_value < 0.05;
    naive += residual_mean_test(e, false).p_value < 0.05;
    white += residual_mean_test(ar1(rng, 2000, 0.0), true).p_value < 0.05;
  }
  const double sd = std::sqrt(0.05 * 0.95 / seeds);  // binomial sd of a 5% rate
  const double rate = double(effective) / seeds, naive_rate = double(naive) / seeds;
  std::cout << "[ residual mean ] AR(1) phi=0.8, 400 seeds: false alarms N_eff " << rate
            << ", naive " << naive_rate << ", white (N_eff) " << double(white) / seeds << "\n";
  EXPECT_NEAR(rate, 0.05, 3.0 * sd);
  EXPECT_NEAR(double(white) / seeds, 0.05, 3.0 * sd);
  // Naive: the t statistic is inflated by sqrt((1+phi)/(1-phi)) = 3, P(|Z| > 1.96/3) ~ 0.51.
  EXPECT_GT(naive_rate, 0.4);
  // A real offset of 6 long-run standard errors (sqrt(1/((1-phi)^2 N)) = 0.112) is found.
  const Eigen::VectorXd shifted = ar1(rng, 2000, phi).array() + 6.0 * std::sqrt(25.0 / 2000.0);
  EXPECT_LT(residual_mean_test(shifted, true).p_value, 0.05);
}

TEST(Statistics, WhitenessVerdict) {
  std::mt19937_64 rng(8);
  std::normal_distribution<double> g(0.0, 1.0);
  const int seeds = 100;
  int white_pass = 0, colored_pass = 0, cross_pass = 0, leak_pass = 0;
  for (int s = 0; s < seeds; ++s) {
    const Eigen::Index n = 2000;
    Eigen::VectorXd u(n), e(n), leak(n);
    for (Eigen::Index k = 0; k < n; ++k) u[k] = g(rng), e[k] = g(rng);
    leak = e;
    leak.tail(n - 2) += 0.3 * u.head(n - 2);  // residual still contains u[k-2]
    const Eigen::MatrixXd inputs = u;
    white_pass += residual_whiteness(e, inputs, 20).pass;
    colored_pass += residual_autocorrelation(ar1(rng, n, 0.5), 20).pass;
    cross_pass += residual_input_correlation(e, u, 20).pass;
    const CorrelationCheck c = residual_input_correlation(leak, u, 20);
    leak_pass += c.pass;
    if (s == 0) {
      EXPECT_GT(c.values[20 + 2], c.band);  // the lag that leaks
    }
  }
  std::cout << "[ whiteness ] pass rates over 100 seeds: white " << white_pass << "%, AR(1) 0.5 "
            << colored_pass << "%, independent input " << cross_pass << "%, leaking input "
            << leak_pass << "%\n";
  // The verdict is a 99% test per check; the white case runs two checks (auto + one cross).
  EXPECT_GE(white_pass, 93);
  EXPECT_GE(cross_pass, 95);
  EXPECT_EQ(colored_pass, 0);
  EXPECT_EQ(leak_pass, 0);
}

}  // namespace
}  // namespace inertia::ident
