#pragma once
// Simulated data with known parameters for the identification tests.
#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace inertia::ident::testing {

/// Billings & Zhu (1991) rational example:
///   y(k) = (0.2 y(k-1) + 0.1 y(k-1) u(k-1) + u(k-1)) / (1 + y(k-1)^2 + y(k-2)^2) + e(k),
/// u ~ U(-1, 1), e ~ N(0, sigma^2). Columns: y[k-1], y[k-1]*u[k-1], u[k-1] (numerator) and the
/// output-multiplied y*y[k-1]^2, y*y[k-2]^2 (denominator), truth (0.2, 0.1, 1, 1, 1).
struct RationalExample {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  Eigen::MatrixXd factors;  // y[k-1]^2, y[k-2]^2
  Eigen::MatrixXd phi_clean;  // same columns built with the noise-free output y0 in the products
  Eigen::VectorXd y_clean;
  std::vector<std::string> labels{"y[k-1]", "y[k-1]*u[k-1]", "u[k-1]", "y*y[k-1]^2", "y*y[k-2]^2"};
  std::vector<Eigen::Index> output_multiplied{3, 4};
  Eigen::VectorXd truth = (Eigen::VectorXd(5) << 0.2, 0.1, 1.0, 1.0, 1.0).finished();
};

inline RationalExample rational_example(unsigned seed, Eigen::Index samples, double sigma) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Index warm = 50;  // let the start-up transient die out
  const Eigen::Index total = samples + warm + 2;
  Eigen::VectorXd u(total), y(total), y0(total);
  y.setZero();
  y0.setZero();
  for (Eigen::Index k = 0; k < total; ++k) u[k] = uni(rng);
  for (Eigen::Index k = 2; k < total; ++k) {
    const double num = 0.2 * y[k - 1] + 0.1 * y[k - 1] * u[k - 1] + u[k - 1];
    const double den = 1.0 + y[k - 1] * y[k - 1] + y[k - 2] * y[k - 2];
    y0[k] = num / den;
    y[k] = y0[k] + noise(rng);
  }
  RationalExample ex;
  ex.phi.resize(samples, 5);
  ex.phi_clean.resize(samples, 5);
  ex.factors.resize(samples, 2);
  ex.y.resize(samples);
  ex.y_clean.resize(samples);
  for (Eigen::Index i = 0; i < samples; ++i) {
    const Eigen::Index k = i + warm + 2;
    const double y1 = y[k - 1], y2 = y[k - 2], u1 = u[k - 1];
    ex.y[i] = y[k];
    ex.y_clean[i] = y0[k];
    ex.factors(i, 0) = y1 * y1;
    ex.factors(i, 1) = y2 * y2;
    ex.phi.row(i) << y1, y1 * u1, u1, y[k] * y1 * y1, y[k] * y2 * y2;
    ex.phi_clean.row(i) << y1, y1 * u1, u1, y0[k] * y1 * y1, y0[k] * y2 * y2;
  }
  return ex;
}

/// SysIdentPy book ARMAX-like example:
///   y = 0.2 y[k-1] + 0.1 y[k-1] x[k-1] + 0.9 x[k-2] + e,  e = nu + 0.8 nu[k-1],  nu ~ N(0, sigma^2)
/// x ~ U(-1, 1). Columns y[k-1], y[k-1]*x[k-1], x[k-2]; truth (0.2, 0.1, 0.9), MA coefficient 0.8.
struct ArmaxExample {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  std::vector<std::string> labels{"y[k-1]", "y[k-1]*x[k-1]", "x[k-2]"};
  Eigen::VectorXd truth = (Eigen::VectorXd(3) << 0.2, 0.1, 0.9).finished();
  double ma = 0.8;
};

inline ArmaxExample armax_example(unsigned seed, Eigen::Index samples, double sigma) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Index warm = 50;
  const Eigen::Index total = samples + warm + 2;
  Eigen::VectorXd x(total), y = Eigen::VectorXd::Zero(total), nu(total);
  for (Eigen::Index k = 0; k < total; ++k) {
    x[k] = uni(rng);
    nu[k] = noise(rng);
  }
  for (Eigen::Index k = 2; k < total; ++k)
    y[k] = 0.2 * y[k - 1] + 0.1 * y[k - 1] * x[k - 1] + 0.9 * x[k - 2] + nu[k] + 0.8 * nu[k - 1];
  ArmaxExample ex;
  ex.phi.resize(samples, 3);
  ex.y.resize(samples);
  for (Eigen::Index i = 0; i < samples; ++i) {
    const Eigen::Index k = i + warm + 2;
    ex.y[i] = y[k];
    ex.phi.row(i) << y[k - 1], y[k - 1] * x[k - 1], x[k - 2];
  }
  return ex;
}

/// Mean and standard deviation of each column of a runs x params matrix.
inline std::pair<Eigen::VectorXd, Eigen::VectorXd> column_mean_sd(const Eigen::MatrixXd& runs) {
  const Eigen::VectorXd mean = runs.colwise().mean().transpose();
  const Eigen::MatrixXd c = runs.rowwise() - mean.transpose();
  const Eigen::VectorXd sd =
      (c.colwise().squaredNorm().transpose() / static_cast<double>(runs.rows() - 1)).cwiseSqrt();
  return {mean, sd};
}

}  // namespace inertia::ident::testing
