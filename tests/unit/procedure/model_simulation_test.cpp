// Free-run model simulation against hand-written recursions.
#include "analyzer/procedure/model_simulation.hpp"

#include <gtest/gtest.h>

#include <random>

#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

using ident::parse_terms;
using ident::SignalSet;
using ident::Variable;

SignalSet random_signals(Eigen::Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  SignalSet s(n, "test");
  for (Variable v : {Variable::Ai, Variable::Ap, Variable::Ao, Variable::T, Variable::Wi, Variable::Y}) {
    Eigen::VectorXd x(n);
    for (Eigen::Index k = 0; k < n; ++k) x(k) = g(rng);
    s.set(v, x);
  }
  return s;
}

TEST(SimulateModel, ArxFeedsBackItsOwnOutputNotTheMeasuredOne) {
  const auto terms = parse_terms({"1", "a_i", "a_i[k-1]", "a_i*a_p", "y[k-1]", "y[k-2]", "e[k-1]"});
  Eigen::VectorXd theta(7);
  theta << 0.1, 2.0, -0.5, 0.03, 0.6, -0.2, 0.9;   // the noise term must be ignored
  const SignalSet s = random_signals(200, 1);
  const Eigen::VectorXd sim = simulate_model(terms, theta, s, 2);
  const Eigen::VectorXd& a = s.get(Variable::Ai);
  const Eigen::VectorXd& p = s.get(Variable::Ap);
  Eigen::VectorXd y = s.get(Variable::Y);   // only y(0), y(1) may seed the recursion
  for (Eigen::Index k = 2; k < 200; ++k) {
    y(k) = 0.1 + 2.0 * a(k) - 0.5 * a(k - 1) + 0.03 * a(k) * p(k) + 0.6 * y(k - 1) - 0.2 * y(k - 2);
  }
  ASSERT_EQ(sim.size(), 198);
  EXPECT_LT((sim - y.tail(198)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(SimulateModel, OutputMultipliedTermsDivide) {
  // y (1 + 0.01 T + 0.002 w_i) = 3 w_i + 0.5: the gyro form of eq. 5.
  const auto terms = parse_terms({"1", "w_i", "y*T", "y*w_i"});
  Eigen::VectorXd theta(4);
  theta << 0.5, 3.0, 0.01, 0.002;
  const SignalSet s = random_signals(50, 2);
  const Eigen::VectorXd sim = simulate_model(terms, theta, s, 0);
  const Eigen::VectorXd& w = s.get(Variable::Wi);
  const Eigen::VectorXd& t = s.get(Variable::T);
  for (Eigen::Index k = 0; k < 50; ++k) {
    EXPECT_NEAR(sim(k), (0.5 + 3.0 * w(k)) / (1.0 + 0.01 * t(k) + 0.002 * w(k)), 1e-12);
  }
}

TEST(SimulateModel, RefusesOutputInsideANonlinearFunction) {
  const auto terms = parse_terms({"y[k-1]*a_i"});
  EXPECT_THROW(simulate_model(terms, Eigen::VectorXd::Ones(1), random_signals(10, 3), 1), InputError);
}

}  // namespace
}  // namespace inertia::procedure
