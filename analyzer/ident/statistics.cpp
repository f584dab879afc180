#include "analyzer/ident/statistics.hpp"

#include <map>
#include <stdexcept>

#include <boost/math/distributions/binomial.hpp>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace inertia::ident {
namespace {

constexpr double kBand95 = 1.959963984540054;  // two-sided 95% normal quantile

// Largest outside-count consistent with whiteness: 99% quantile of Binomial(L, 0.05).
int allowed_outside(int lags) {
  if (lags <= 0) return 0;
  const boost::math::binomial_distribution<double> dist(lags, 0.05);
  int c = 0;
  while (c < lags && boost::math::cdf(dist, c) < 0.99) ++c;
  return c;
}

void finish_check(CorrelationCheck& check, double samples) {
  const int lags = static_cast<int>(check.values.size());
  check.outside = static_cast<int>((check.values.array().abs() > check.band).count());
  check.allowed = allowed_outside(lags);
  // Family-wise 1% band for the largest lag (Bonferroni over the lags): catches a few strong lags
  // (AR(1), an input leaking at one lag) that the count alone lets through.
  const boost::math::normal_distribution<double> normal;
  check.max_band = boost::math::quantile(boost::math::complement(normal, 0.005 / std::max(lags, 1))) /
                   std::sqrt(samples);
  const double largest = lags > 0 ? check.values.cwiseAbs().maxCoeff() : 0.0;
  check.pass = check.outside <= check.allowed && largest <= check.max_band;
}

}  // namespace

double student_t_two_sided_p(double t, double dof) {
  if (std::isnan(t) || !(dof > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (std::isinf(t)) return 0.0;
  const boost::math::students_t dist(dof);
  return 2.0 * boost::math::cdf(boost::math::complement(dist, std::abs(t)));
}

ParameterTTest parameter_t_test(const Eigen::Ref<const Eigen::VectorXd>& theta,
                                const Eigen::Ref<const Eigen::VectorXd>& std_dev,
                                Eigen::Index samples) {
  if (theta.size() != std_dev.size())
    throw std::invalid_argument("t-test: theta and std_dev differ in size");
  ParameterTTest out;
  const Eigen::Index p = theta.size();
  out.dof = static_cast<double>(samples - p - 1);
  out.t.resize(p);
  out.p_value.resize(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    if (std_dev[j] > 0.0) {
      out.t[j] = theta[j] / std_dev[j];
    } else {
      out.t[j] = theta[j] == 0.0 ? 0.0 : std::copysign(std::numeric_limits<double>::infinity(), theta[j]);
    }
    out.p_value[j] = student_t_two_sided_p(out.t[j], out.dof);
  }
  return out;
}

double aic_from_variance(double sigma2_ml, Eigen::Index samples, Eigen::Index parameters) {
  if (!(sigma2_ml > 0.0)) return -std::numeric_limits<double>::infinity();
  return static_cast<double>(samples) * std::log(sigma2_ml) + 2.0 * static_cast<double>(parameters);
}

double aic(const Eigen::Ref<const Eigen::VectorXd>& residuals, Eigen::Index parameters) {
  const Eigen::Index n = residuals.size();
  return aic_from_variance(residuals.squaredNorm() / static_cast<double>(n), n, parameters);
}

Eigen::VectorXd relative_likelihood(const Eigen::Ref<const Eigen::VectorXd>& aic_values) {
  double best = std::numeric_limits<double>::infinity();
  for (double a : aic_values)
    if (!std::isnan(a)) best = std::min(best, a);
  Eigen::VectorXd out(aic_values.size());
  for (Eigen::Index i = 0; i < aic_values.size(); ++i)
    out[i] = std::isnan(aic_values[i]) ? aic_values[i] : std::exp((best - aic_values[i]) / 2.0);
  return out;
}

ResidualMeanTest residual_mean_test(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                    bool effective_size) {
  const Eigen::Index n = residuals.size();
  if (n < 3) throw std::invalid_argument("residual mean test needs at least 3 samples");
  ResidualMeanTest out;
  out.mean = residuals.mean();
  const Eigen::VectorXd c = residuals.array() - out.mean;
  const double ss = c.squaredNorm();
  const double s2 = ss / static_cast<double>(n - 1);
  out.lag1_autocorrelation = ss > 0.0 ? c.head(n - 1).dot(c.tail(n - 1)) / ss : 0.0;
  double n_eff = static_cast<double>(n);
  if (effective_size) {
    const double r1 = std::clamp(out.lag1_autocorrelation, -0.999, 0.999);
    n_eff = std::clamp(static_cast<double>(n) * (1.0 - r1) / (1.0 + r1), 2.0, static_cast<double>(n));
  }
  out.effective_samples = n_eff;
  out.std_error = std::sqrt(s2 / n_eff);
  if (out.std_error > 0.0) {
    out.t = out.mean / out.std_error;
    out.p_value = student_t_two_sided_p(out.t, n_eff - 1.0);
  } else {
    // Constant residual: exactly zero is a perfect fit, anything else a certain offset.
    out.t = out.mean == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
    out.p_value = out.mean == 0.0 ? 1.0 : 0.0;
  }
  return out;
}

CorrelationCheck residual_autocorrelation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                          int max_lag) {
  const Eigen::Index n = residuals.size();
  if (max_lag < 1 || max_lag >= n) throw std::invalid_argument("autocorrelation: bad max_lag");
  const Eigen::VectorXd c = residuals.array() - residuals.mean();
  const double ss = c.squaredNorm();
  CorrelationCheck out;
  out.lags = Eigen::VectorXd::LinSpaced(max_lag, 1.0, max_lag);
  out.values.resize(max_lag);
  for (int tau = 1; tau <= max_lag; ++tau)
    out.values[tau - 1] = ss > 0.0 ? c.head(n - tau).dot(c.tail(n - tau)) / ss : 0.0;
  out.band = kBand95 / std::sqrt(static_cast<double>(n));
  finish_check(out, static_cast<double>(n));
  return out;
}

CorrelationCheck residual_input_correlation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                            const Eigen::Ref<const Eigen::VectorXd>& input,
                                            int max_lag) {
  const Eigen::Index n = residuals.size();
  if (input.size() != n) throw std::invalid_argument("cross-correlation: sizes differ");
  if (max_lag < 0 || max_lag >= n) throw std::invalid_argument("cross-correlation: bad max_lag");
  const Eigen::VectorXd e = residuals.array() - residuals.mean();
  const Eigen::VectorXd u = input.array() - input.mean();
  const double norm = std::sqrt(e.squaredNorm() * u.squaredNorm());
  CorrelationCheck out;
  const int count = 2 * max_lag + 1;
  out.lags = Eigen::VectorXd::LinSpaced(count, -max_lag, max_lag);
  out.values.resize(count);
  for (int i = 0; i < count; ++i) {
    const int tau = i - max_lag;
    const Eigen::Index m = n - std::abs(tau);
    // tau > 0: e_k with u_{k-tau}; tau < 0: e_k with u_{k+|tau|}.
    const double s = tau >= 0 ? e.tail(m).dot(u.head(m)) : e.head(m).dot(u.tail(m));
    out.values[i] = norm > 0.0 ? s / norm : 0.0;
  }
  out.band = kBand95 / std::sqrt(static_cast<double>(n));
  finish_check(out, static_cast<double>(n));
  return out;
}

WhitenessReport residual_whiteness(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                   const Eigen::Ref<const Eigen::MatrixXd>& inputs, int max_lag) {
  WhitenessReport out;
  out.autocorrelation = residual_autocorrelation(residuals, max_lag);
  out.pass = out.autocorrelation.pass;
  for (Eigen::Index j = 0; j < inputs.cols(); ++j) {
    out.cross.push_back(residual_input_correlation(residuals, inputs.col(j), max_lag));
    out.pass = out.pass && out.cross.back().pass;
  }
  return out;
}

Eigen::MatrixXd cluster_robust_covariance(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                          const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                          const std::vector<int>& cluster, int* clusters) {
  const Eigen::Index n = x.rows(), p = x.cols();
  if (residuals.size() != n || static_cast<Eigen::Index>(cluster.size()) != n)
    throw std::invalid_argument("cluster_robust_covariance: x, residuals and cluster ids differ in length");
  std::map<int, Eigen::VectorXd> scores;   // per cluster: X_g' e_g
  for (Eigen::Index k = 0; k < n; ++k) {
    auto [it, fresh] = scores.try_emplace(cluster[static_cast<std::size_t>(k)]);
    if (fresh) it->second = Eigen::VectorXd::Zero(p);
    it->second.noalias() += x.row(k).transpose() * residuals(k);
  }
  const auto g = static_cast<int>(scores.size());
  if (clusters != nullptr) *clusters = g;
  if (g < 2 || n <= p) throw std::invalid_argument("cluster_robust_covariance: needs at least two clusters and N > p");
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(p, p);
  for (const auto& [id, score] : scores) meat.noalias() += score * score.transpose();
  const Eigen::LDLT<Eigen::MatrixXd> bread(x.transpose() * x);
  const Eigen::MatrixXd left = bread.solve(meat);
  const Eigen::MatrixXd v = bread.solve(left.transpose()).transpose();
  const double correction = static_cast<double>(g) / static_cast<double>(g - 1) * static_cast<double>(n - 1) /
                            static_cast<double>(n - p);
  return correction * 0.5 * (v + v.transpose());
}

}  // namespace inertia::ident
