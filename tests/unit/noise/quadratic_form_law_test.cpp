// The tail of a weighted sum of chi-squares (analyzer/noise/quadratic_form_law.hpp) against
// distributions known in closed form.
#include <gtest/gtest.h>

#include <boost/math/distributions/chi_squared.hpp>

#include <cmath>
#include <iostream>
#include <vector>

#include "analyzer/noise/quadratic_form_law.hpp"

namespace inertia::noise {
namespace {

double chi2_tail(double dof, double q) {
  return boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), q));
}

/// Equal weights are a chi-square, whether kept as leading eigenvalues or given as the rest.
TEST(QuadraticFormLaw, EqualWeightsAreAChiSquare) {
  for (const int dof : {2, 8, 50}) {
    const QuadraticFormLaw kept = QuadraticFormLaw::from(Eigen::VectorXd::Ones(dof), dof, dof);
    QuadraticFormLaw rest;
    rest.rest_scale = 1.0;
    rest.rest_dof = dof;
    EXPECT_DOUBLE_EQ(kept.mean(), dof);
    EXPECT_DOUBLE_EQ(kept.variance(), 2.0 * dof);
    for (const double p : {0.3, 0.05, 1e-3, 1e-6, 1e-9}) {
      boost::math::chi_squared chi2(dof);
      const double q = boost::math::quantile(boost::math::complement(chi2, p));
      // Lugannani-Rice on a gamma of shape a = dof / 2: its relative error tends to Stirling's,
      // Gamma(a) / (sqrt(2 pi) a^(a - 1/2) e^-a) - 1 ~ 1 / 12a, far in the tail.
      const double tolerance = 1.0 / (6.0 * dof) + 0.005;
      EXPECT_NEAR(kept.upper_tail(q) / p, 1.0, tolerance) << "dof " << dof << " p " << p;
      EXPECT_NEAR(rest.upper_tail(q) / p, 1.0, tolerance) << "dof " << dof << " p " << p;
    }
  }
}

/// Distinct weights, each on two dof: P(sum l_i chi2_2 > q) = sum_i prod_{j != i} l_i / (l_i - l_j)
/// exp(-q / 2 l_i). The steep weights of slow noise; the scaled chi-square with the same mean and
/// variance misses the tail by orders of magnitude, the saddlepoint by a few percent.
TEST(QuadraticFormLaw, UnequalWeightsMatchTheirClosedForm) {
  const std::vector<double> weights{10.0, 3.0, 1.0, 0.3};
  Eigen::VectorXd leading(2 * static_cast<Eigen::Index>(weights.size()));
  for (std::size_t i = 0; i < weights.size(); ++i) leading(2 * i) = leading(2 * i + 1) = weights[i];
  const QuadraticFormLaw law = QuadraticFormLaw::from(leading, leading.sum(), leading.squaredNorm());
  EXPECT_EQ(law.rest_dof, 0.0);
  const auto exact = [&](double q) {
    double p = 0.0;
    for (std::size_t i = 0; i < weights.size(); ++i) {
      double c = 1.0;
      for (std::size_t j = 0; j < weights.size(); ++j)
        if (j != i) c *= weights[i] / (weights[i] - weights[j]);
      p += c * std::exp(-q / (2.0 * weights[i]));
    }
    return p;
  };
  const double dof = 2.0 * law.mean() * law.mean() / law.variance(), scale = law.mean() / dof;
  for (const double q : {40.0, 100.0, 200.0, 300.0}) {
    const double truth = exact(q), satterthwaite = chi2_tail(dof, q / scale);
    std::cout << "[ quadratic form ] q " << q << ": exact " << truth << ", saddlepoint " << law.upper_tail(q)
              << ", scaled chi-square " << satterthwaite << '\n';
    EXPECT_NEAR(law.upper_tail(q) / truth, 1.0, 0.05) << q;
  }
  // The point of it: far in the tail the scaled chi-square is wrong by a factor of ten or more.
  EXPECT_LT(chi2_tail(dof, 300.0 / scale) / exact(300.0), 0.1);
}

/// A dominant pair kept and many small weights as the rest: against the same weights all kept.
TEST(QuadraticFormLaw, TheRestMatchedOnTwoMomentsKeepsTheTail) {
  Eigen::VectorXd all(202);
  all.head(2).setConstant(20.0);
  all.tail(200).setConstant(0.1);
  const QuadraticFormLaw exact = QuadraticFormLaw::from(all, all.sum(), all.squaredNorm());
  const QuadraticFormLaw split = QuadraticFormLaw::from(all.head(2), all.sum(), all.squaredNorm());
  EXPECT_NEAR(split.rest_dof, 200.0, 1e-9);
  EXPECT_NEAR(split.rest_scale, 0.1, 1e-12);
  for (const double q : {80.0, 200.0, 400.0}) EXPECT_NEAR(split.upper_tail(q) / exact.upper_tail(q), 1.0, 1e-9) << q;
  EXPECT_EQ(exact.upper_tail(0.0), 1.0);
}

}  // namespace
}  // namespace inertia::noise
