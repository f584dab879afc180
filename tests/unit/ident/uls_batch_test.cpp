#include "analyzer/ident/uls_batch.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "tests/unit/ident/ident_test_data.hpp"

namespace inertia::ident {
namespace {

using testing::column_mean_sd;

TEST(UlsBatch, LinearModelMatchesClosedForm) {
  const Eigen::Index n = 500;
  const double sigma = 0.3;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd phi(n, 4);
  Eigen::VectorXd y(n);
  const Eigen::Vector4d truth(0.5, -1.5, 2.0, 0.25);
  for (Eigen::Index k = 0; k < n; ++k) {
    phi.row(k) << 1.0, g(rng), 10.0 * g(rng), 1e-3 * g(rng);  // very different column scales
    y[k] = phi.row(k).dot(truth) + sigma * g(rng);
  }
  const std::vector<std::string> labels{"1", "a", "b", "c"};
  const UlsResult fit = uls_batch(phi, y, labels, {}, UlsOptions{});
  // Closed form by Householder QR, and s^2 (Phi'Phi)^-1 for the covariance.
  const Eigen::VectorXd ls = phi.householderQr().solve(y);
  const Eigen::VectorXd e = y - phi * ls;
  const Eigen::MatrixXd cov = e.squaredNorm() / double(n - 4) * (phi.transpose() * phi).inverse();
  for (int j = 0; j < 4; ++j) {
    EXPECT_NEAR(fit.theta[j], ls[j], 1e-9 * std::abs(ls[j]) + 1e-12) << labels[j];
    EXPECT_NEAR(fit.std_dev[j], std::sqrt(cov(j, j)), 1e-9 * std::sqrt(cov(j, j))) << labels[j];
    EXPECT_NEAR(fit.theta[j], truth[j], 4.0 * fit.std_dev[j]) << labels[j];
  }
  EXPECT_EQ(fit.covariance_kind, CovarianceKind::Classical);
  EXPECT_NEAR(fit.residual_variance, e.squaredNorm() / double(n - 4), 1e-12);
  EXPECT_TRUE((fit.residuals - e).cwiseAbs().maxCoeff() < 1e-9);
  EXPECT_TRUE(fit.converged);
}

// Billings-Zhu 1991: ULS unbiased within Monte-Carlo spread, LS visibly biased.
TEST(UlsBatch, BillingsZhuRationalExampleIsUnbiased) {
  const int runs = 20;
  const Eigen::Index n = 3000;
  const double sigma = 0.1;
  Eigen::MatrixXd uls(runs, 5), ls(runs, 5), sd(runs, 5);
  Eigen::VectorXd sigma2(runs);
  for (int r = 0; r < runs; ++r) {
    const auto ex = testing::rational_example(100 + r, n, sigma);
    const OutputMultiplied rational{ex.output_multiplied, ex.factors};
    const UlsResult fit = uls_batch(ex.phi, ex.y, ex.labels, rational, UlsOptions{});
    ASSERT_TRUE(fit.converged);
    EXPECT_EQ(fit.covariance_kind, CovarianceKind::Sandwich);
    uls.row(r) = fit.theta.transpose();
    sd.row(r) = fit.std_dev.transpose();
    sigma2[r] = fit.sigma2;
    // Plain LS in the same sign convention: y = a - theta_b (y p_b).
    Eigen::MatrixXd lin = ex.phi;
    lin.rightCols(2) *= -1.0;
    ls.row(r) = lin.householderQr().solve(ex.y).transpose();
  }
  const auto [mean, mc_sd] = column_mean_sd(uls);
  const Eigen::VectorXd ls_mean = column_mean_sd(ls).first;
  const Eigen::VectorXd truth = testing::RationalExample{}.truth;
  for (int j = 0; j < 5; ++j) {
    const double se_mean = mc_sd[j] / std::sqrt(double(runs));
    EXPECT_NEAR(mean[j], truth[j], 4.0 * se_mean) << "ULS parameter " << j;
    // Reported (sandwich) sd agrees with the Monte-Carlo spread: it was found within
    // -5%..+35%; allow the sampling error of a 20-run sd (~16%) on top.
    const double ratio = sd.col(j).mean() / mc_sd[j];
    EXPECT_GT(ratio, 0.6) << j;
    EXPECT_LT(ratio, 1.8) << j;
  }
  // LS: the denominator coefficients are pulled far from 1 (about 0.28 at sigma = 0.1).
  for (int j = 3; j < 5; ++j) {
    EXPECT_GT(std::abs(ls_mean[j] - 1.0), 10.0 * mc_sd[j]) << "LS should be biased, parameter " << j;
  }
  // sigma^2 from the ratio estimator: within a few percent (sd of a variance estimate ~ sqrt(2/N)).
  EXPECT_NEAR(sigma2.mean(), sigma * sigma, 4.0 * sigma * sigma * std::sqrt(2.0 / double(n * runs)));
}

// uls_coefficients is uls_batch's theta without the residuals: the same numbers for every column
// set (all, a subset in another order), with output-multiplied columns, and with noise lags.
TEST(UlsBatch, CoefficientsAloneAreTheFullFitsTheta) {
  const auto ex = testing::rational_example(7, 3000, 0.1);
  const OutputMultiplied rational{ex.output_multiplied, ex.factors};
  UlsOptions els;
  els.noise_lags = 1;
  const std::vector<Index> subset{4, 0, 1};
  for (const UlsOptions& options : {UlsOptions{}, els}) {
    for (const std::vector<Index>& columns : {std::vector<Index>{}, subset}) {
      const Eigen::VectorXd alone = uls_coefficients(ex.phi, ex.y, ex.labels, rational, options, columns);
      const UlsResult full = uls_batch(ex.phi, ex.y, ex.labels, rational, options, columns);
      ASSERT_EQ(alone.size(), full.theta.size()) << options.noise_lags << " lags, " << columns.size() << " columns";
      for (Eigen::Index j = 0; j < alone.size(); ++j)
        EXPECT_EQ(alone(j), full.theta(j)) << options.noise_lags << " lags, " << columns.size() << " columns, " << j;
    }
  }
  EXPECT_THROW((void)uls_coefficients(ex.phi, ex.y, {"1"}, rational, UlsOptions{}), std::invalid_argument);
}

// ELS beside output-multiplied columns: on the Billings-Zhu model with white noise the passes
// keep the rational part unbiased and find no noise lag (its coefficient zero within the spread).
TEST(UlsBatch, ExtendedLeastSquaresOnARationalModelFindsNoLagInWhiteNoise) {
  const int runs = 20;
  const Eigen::Index n = 3000;
  UlsOptions options;
  options.noise_lags = 1;
  Eigen::MatrixXd theta(runs, 6);
  for (int r = 0; r < runs; ++r) {
    const auto ex = testing::rational_example(300 + r, n, 0.1);
    const UlsResult fit = uls_batch(ex.phi, ex.y, ex.labels, OutputMultiplied{ex.output_multiplied, ex.factors}, options);
    ASSERT_EQ(fit.process_terms, 5);
    EXPECT_TRUE(fit.converged) << fit.noise_iterations;
    theta.row(r) = fit.theta.transpose();
  }
  const auto [mean, mc_sd] = column_mean_sd(theta);
  Eigen::VectorXd truth = Eigen::VectorXd::Zero(6);
  truth.head(5) = testing::RationalExample{}.truth;
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(mean[j], truth[j], 4.0 * mc_sd[j] / std::sqrt(double(runs))) << j;
}

// ELS on an ARMAX-like model with MA(1) noise (LS 0.288, ELS 0.2003 in the SysIdentPy book).
TEST(UlsBatch, ExtendedLeastSquaresRemovesMaBias) {
  const int runs = 20;
  const Eigen::Index n = 3000;
  Eigen::MatrixXd els(runs, 4), ls(runs, 3);
  UlsOptions options;
  options.noise_lags = 1;
  for (int r = 0; r < runs; ++r) {
    const auto ex = testing::armax_example(200 + r, n, 0.2);
    const UlsResult fit = uls_batch(ex.phi, ex.y, ex.labels, {}, options);
    ASSERT_EQ(fit.process_terms, 3);
    ASSERT_EQ(fit.labels.back(), "e[k-1]");
    EXPECT_TRUE(fit.converged) << fit.noise_iterations;
    els.row(r) = fit.theta.transpose();
    ls.row(r) = uls_batch(ex.phi, ex.y, ex.labels, {}, UlsOptions{}).theta.transpose();
  }
  const auto [mean, mc_sd] = column_mean_sd(els);
  const Eigen::VectorXd ls_mean = column_mean_sd(ls).first;
  const Eigen::Vector4d truth(0.2, 0.1, 0.9, 0.8);
  for (int j = 0; j < 4; ++j)
    EXPECT_NEAR(mean[j], truth[j], 4.0 * mc_sd[j] / std::sqrt(double(runs))) << "ELS parameter " << j;
  EXPECT_GT(std::abs(ls_mean[0] - 0.2), 10.0 * mc_sd[0] / std::sqrt(double(runs)));
}

// The passes say what the coefficients still moved by: below the tolerance when they settled, and
// above it when the passes ran out first (what the report states of an unsettled noise model).
TEST(UlsBatch, ExtendedLeastSquaresReportsTheLastPassesChange) {
  const auto ex = testing::armax_example(7, 3000, 0.2);
  UlsOptions options;
  options.noise_lags = 1;
  const UlsResult settled = uls_batch(ex.phi, ex.y, ex.labels, {}, options);
  ASSERT_TRUE(settled.converged);
  EXPECT_LE(settled.noise_last_change, options.tolerance);
  EXPECT_GT(settled.noise_last_change, 0.0);
  options.max_noise_iterations = 2;
  const UlsResult cut = uls_batch(ex.phi, ex.y, ex.labels, {}, options);
  EXPECT_FALSE(cut.converged);
  EXPECT_EQ(cut.noise_iterations, 2);
  EXPECT_GT(cut.noise_last_change, 1e3 * options.tolerance);
}

// The passes' fixed point: the noise columns built from the returned residuals themselves, one
// more least-squares fit returns the same coefficients. MA(1) noise with c = 0.8 is where plain
// passes (each turning the residuals' error by C(q) - 1 once) crawl, by up to 0.8 per pass;
// residuals self-consistent for the coefficients at hand, mixed over the last passes, settle in
// a few.
TEST(UlsBatch, ExtendedLeastSquaresSettlesOnItsFixedPointInFewPasses) {
  for (unsigned seed = 0; seed < 5; ++seed) {
    const auto ex = testing::armax_example(40 + seed, 5000, 0.2);
    UlsOptions options;
    options.noise_lags = 1;
    const UlsResult fit = uls_batch(ex.phi, ex.y, ex.labels, {}, options);
    ASSERT_TRUE(fit.converged) << seed;
    EXPECT_LE(fit.noise_iterations, 20) << seed;
    Eigen::MatrixXd x(ex.phi.rows(), 4);
    x.leftCols(3) = ex.phi;
    x(0, 3) = 0.0;
    x.col(3).tail(x.rows() - 1) = fit.residuals.head(x.rows() - 1);
    const Eigen::VectorXd refit = x.colPivHouseholderQr().solve(ex.y);
    EXPECT_LE((refit - fit.theta).norm(), 1e-6 * fit.theta.norm()) << seed;
    EXPECT_LE((ex.y - x * fit.theta - fit.residuals).norm(), 1e-6 * fit.residuals.norm()) << seed;
  }
}

// a_i^2 + a_p^2 + a_o^2 = g^2 on rotation-table data: with the bias these four are collinear.
TEST(UlsBatch, CollinearTermsAreReportedByName) {
  const Eigen::Index n = 400;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * M_PI);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd phi(n, 6);
  Eigen::VectorXd y(n);
  const double gravity = 9.80665;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = angle(rng), s = angle(rng);
    const double ai = gravity * std::cos(t), ap = gravity * std::sin(t) * std::cos(s),
                 ao = gravity * std::sin(t) * std::sin(s);
    phi.row(k) << 1.0, ai, ap, ai * ai, ap * ap, ao * ao;
    y[k] = 0.01 + 0.9 * ai + 1e-3 * ai * ai + 1e-3 * g(rng);
  }
  const std::vector<std::string> labels{"1", "a_i", "a_p", "a_i^2", "a_p^2", "a_o^2"};
  try {
    (void)uls_batch(phi, y, labels, {}, UlsOptions{});
    FAIL() << "collinear set was not reported";
  } catch (const IdentifiabilityError& e) {
    std::vector<std::string> got = e.labels();
    std::sort(got.begin(), got.end());
    const std::vector<std::string> want{"1", "a_i^2", "a_o^2", "a_p^2"};
    EXPECT_EQ(got, want) << e.what();
    EXPECT_LT(e.rcond(), UlsOptions{}.min_rcond);
    EXPECT_NE(std::string(e.what()).find("a_o^2"), std::string::npos);
  }
  // Dropping one member of the dependence makes the set identifiable again.
  const std::vector<Index> keep{0, 1, 2, 3, 4};
  const UlsResult fit = uls_batch(phi, y, labels, {}, UlsOptions{}, keep);
  EXPECT_NEAR(fit.theta[1], 0.9, 4.0 * fit.std_dev[1]);
}

TEST(UlsBatch, ZeroColumnAndBadInputAreRejected) {
  Eigen::MatrixXd phi = Eigen::MatrixXd::Random(50, 2);
  phi.col(1).setZero();
  const Eigen::VectorXd y = Eigen::VectorXd::Random(50);
  EXPECT_THROW((void)uls_batch(phi, y, {"a", "dead"}, {}, UlsOptions{}), IdentifiabilityError);
  EXPECT_THROW((void)uls_batch(phi, y, {"a"}, {}, UlsOptions{}), std::invalid_argument);
  UlsOptions bad;
  bad.max_correction = 1.5;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("max_correction"), std::string::npos);
}

}  // namespace
}  // namespace inertia::ident
