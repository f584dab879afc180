// The DF2T filter against the difference equation written out, and its stability check.
#include "hal/sim/sensors/discrete_filter.hpp"

#include <gtest/gtest.h>

#include <array>
#include <stdexcept>
#include <vector>

namespace inertia::sim {
namespace {

TEST(DiscreteFilter, MatchesTheDifferenceEquation) {
  const DiscreteTransferFunction<3> tf{{0.3, -0.2, 0.15, 0.05}, {1.0, -1.1, 0.5, -0.08}};
  DiscreteFilter<3> f(tf, "test");
  std::array<double, 4> u{}, y{};   // u[j] = u(k-j), y[j] = y(k-j)
  for (int k = 0; k < 200; ++k) {
    const double in = std::sin(0.37 * k) + (k % 7 == 0 ? 1.0 : 0.0);
    for (int j = 3; j > 0; --j) { u[j] = u[j - 1]; y[j] = y[j - 1]; }
    u[0] = in;
    y[0] = tf.num[0] * u[0] + tf.num[1] * u[1] + tf.num[2] * u[2] + tf.num[3] * u[3] -
           tf.den[1] * y[1] - tf.den[2] * y[2] - tf.den[3] * y[3];
    EXPECT_NEAR(f.step(in), y[0], 1e-12) << "k = " << k;
  }
}

TEST(DiscreteFilter, SettleHoldsTheDcResponse) {
  DiscreteFilter<2> f({{0.1, 0.2, -0.05}, {1.0, -0.6, 0.1}}, "test");
  f.settle(4.0);
  const double dc = (0.1 + 0.2 - 0.05) / (1.0 - 0.6 + 0.1);
  for (int k = 0; k < 10; ++k) EXPECT_NEAR(f.step(4.0), 4.0 * dc, 1e-14);
}

TEST(DiscreteFilter, StateSpaceReproducesTheFilter) {
  const DiscreteTransferFunction<3> tf{{0.3, -0.2, 0.15, 0.05}, {1.0, -1.1, 0.5, -0.08}};
  DiscreteFilter<3> f(tf, "test");
  DiscreteFilter<3>::StateMatrix a;
  DiscreteFilter<3>::StateVector b, s = DiscreteFilter<3>::StateVector::Zero();
  f.state_space(a, b);
  for (int k = 0; k < 50; ++k) {
    const double u = std::cos(0.8 * k);
    const double y_ss = s(0) + tf.num[0] * u;
    s = a * s + b * u;
    EXPECT_NEAR(f.step(u), y_ss, 1e-12);
  }
}

TEST(DiscreteFilter, RejectsUnstableAndUnnormalisedDenominators) {
  using Tf = DiscreteTransferFunction<2>;
  EXPECT_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, -1.0, 0.0}}, "x"), std::invalid_argument);   // pole at 1
  EXPECT_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, 1.0, 0.0}}, "x"), std::invalid_argument);    // pole at -1
  EXPECT_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, 0.0, 1.0}}, "x"), std::invalid_argument);    // +-j
  EXPECT_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, -0.3, -0.8}}, "x"), std::invalid_argument);  // poles 1.06, -0.76
  EXPECT_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {0.0, 1.0, 0.0}}, "x"), std::invalid_argument);
  EXPECT_NO_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, -1.6, 0.63}}, "x"));   // poles 0.9, 0.7
  EXPECT_NO_THROW(DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, 0.0, 0.0}}, "x"));
  try {
    DiscreteFilter<2>(Tf{{1, 0, 0}, {1.0, -2.0, 1.0}}, "FogParams.g_sens_i (D/C)");
    FAIL();
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("FogParams.g_sens_i"), std::string::npos) << what;
    EXPECT_NE(what.find("unit circle"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace inertia::sim
