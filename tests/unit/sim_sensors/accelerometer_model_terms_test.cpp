// The model-file terms of the accelerometer truth, checked by evaluating them at SI inputs and
// comparing with equation 12 evaluated by hand in g.
#include "hal/sim/sensors/accelerometer_model_terms.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

namespace inertia::sim {
namespace {

constexpr double g0 = 9.80665;

// Value of a canonical term at sensor-frame accelerations (m/s^2) and T; independent parser of
// the few factors used here.
double term_value(const std::string& term, double ai, double ap, double ao, double t) {
  const std::map<std::string, double> factor = {
      {"1", 1.0},        {"a_i", ai},        {"a_p", ap},      {"a_o", ao},      {"T", t},
      {"a_i^2", ai * ai}, {"a_p^2", ap * ap}, {"a_o^2", ao * ao}, {"T^2", t * t},
      {"sign(a_i)", ai > 0 ? 1.0 : (ai < 0 ? -1.0 : 0.0)}, {"abs(a_i)", std::fabs(ai)}};
  double v = 1.0;
  std::size_t start = 0;
  while (start <= term.size()) {
    const std::size_t end = term.find('*', start);
    const std::string f = term.substr(start, end == std::string::npos ? std::string::npos : end - start);
    v *= factor.at(f);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return v;
}

// Equation 12 (high-pass terms at their high-frequency gain) with the temperature extension, in g.
double eq12_instantaneous(const AccelerometerParams& p, double ai, double ap, double ao, double t) {
  ai /= g0, ap /= g0, ao /= g0;
  const double sgn = ai > 0 ? 1.0 : (ai < 0 ? -1.0 : 0.0);
  return p.k_i * (1 + p.scale_tc_per_degc * t) *
         (p.k_b + p.bias_tc_g_per_degc * t + ai + p.k_s * sgn + p.k_a * std::fabs(ai) +
          p.k_oq * ai * std::fabs(ai) + p.k_ip * ai * ap + p.k_io * ai * ao + p.k_po * ap * ao +
          p.k_ii * ai * ai + p.k_pp * ap * ap + p.k_oo * ao * ao);
}

double evaluate(const std::vector<std::pair<std::string, double>>& terms, double ai, double ap, double ao, double t) {
  double y = 0.0;
  for (const auto& [name, c] : terms) y += c * term_value(name, ai, ap, ao, t);
  return y;
}

TEST(AccelerometerModelTerms, Table1TermsInSiUnits) {
  const AccelerometerParams p;   // table 1
  const auto terms = accelerometer_model_terms(p);
  std::map<std::string, double> by_name(terms.begin(), terms.end());
  EXPECT_EQ(by_name.size(), terms.size());
  // Table 1 has K_s = K_a = K_oq = 0 and no temperature terms: those are left out.
  const std::map<std::string, double> expected = {
      {"1", 0.86 * 4e-3},          {"a_i", 0.86 / g0},           {"a_i*a_p", 0.86 * 1e-3 / (g0 * g0)},
      {"a_i*a_o", 0.86e-3 / (g0 * g0)}, {"a_p*a_o", 0.86e-3 / (g0 * g0)}, {"a_i^2", 0.86 * 60e-6 / (g0 * g0)},
      {"a_p^2", 0.86 * 60e-6 / (g0 * g0)}, {"a_o^2", 0.86 * 60e-6 / (g0 * g0)}};
  ASSERT_EQ(by_name.size(), expected.size());
  for (const auto& [name, c] : expected) {
    ASSERT_TRUE(by_name.count(name)) << name;
    EXPECT_NEAR(by_name[name], c, 1e-15 * std::fabs(c)) << name;
  }
  EXPECT_EQ(terms.front().first, "1");
}

TEST(AccelerometerModelTerms, EvaluateToEquation12AtAnyInput) {
  AccelerometerParams p;
  p.k_s = 2e-3;
  p.k_a = 3e-3;
  p.k_oq = -4e-3;
  p.k_io = -2e-3;
  p.bias_tc_g_per_degc = 1e-4;
  p.scale_tc_per_degc = 2e-4;
  const auto terms = accelerometer_model_terms(p);
  for (const auto& [name, c] : terms) EXPECT_NE(c, 0.0) << name;
  for (const double t : {0.0, 17.0, -30.0}) {
    for (const Eigen::Vector3d& a : {Eigen::Vector3d(g0, 0, 0), Eigen::Vector3d(-3 * g0, 2 * g0, 0.5 * g0),
                                    Eigen::Vector3d(25 * g0, -10 * g0, 8 * g0), Eigen::Vector3d(0, 4 * g0, -g0)}) {
      const double expected = eq12_instantaneous(p, a(0), a(1), a(2), t);
      EXPECT_NEAR(evaluate(terms, a(0), a(1), a(2), t), expected, 1e-12 * (1 + std::fabs(expected)))
          << a.transpose() << " T " << t;
    }
  }
}

}  // namespace
}  // namespace inertia::sim
