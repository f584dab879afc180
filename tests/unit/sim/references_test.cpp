// Reference instruments: encoder quantization, monitoring accelerometer error model and noise.
#include <gtest/gtest.h>

#include <cmath>

#include "common/units.hpp"
#include "hal/sim/random_streams.hpp"
#include "hal/sim/references.hpp"

namespace {

using namespace inertia::sim;

TEST(Encoder, CountsFloorThePositionOnTheResolutionGrid) {
  const double res = 1e-7;
  RandomSource rng(5);
  double mean_error = 0.0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const double x = (rng.uniform() - 0.5) * 0.02;   // +-10 mm, both signs
    const std::int64_t c = encoder_counts(x, res);
    const double read = static_cast<double>(c) * res;
    ASSERT_LE(read, x + 4e-16 * std::abs(x)) << x;   // floor(x/res)*res rounds to within an ulp
    ASSERT_GT(read + res, x) << x;
    mean_error += (x - read) / n;
  }
  // Uniform error on [0, res): mean res/2, standard error res/sqrt(12 n); 5 sigma.
  EXPECT_NEAR(mean_error, res / 2, 5.0 * res / std::sqrt(12.0 * n));
  EXPECT_EQ(encoder_counts(0.0, res), 0);
  EXPECT_EQ(encoder_counts(-0.5 * res, res), -1);
  EXPECT_EQ(encoder_counts(3.0 * 0.25, 0.25), 3);   // exact grid points count as reached
}

TEST(MonitorAccelerometer, ScaleBiasMisalignmentAndNoise) {
  inertia::config::MonitorAccelerometer p;
  p.axis = Eigen::Vector3d(1, 1, 0).normalized();
  p.bias_mps2 = 0.02;
  p.scale_error = 1e-3;
  p.misalignment = {Eigen::Vector3d(0, 0, 1), inertia::deg_to_rad(0.5)};
  p.noise_sd_mps2 = 0.0;
  SingleAxisAccelerometer quiet(p, 1);
  // The true axis is the nominal one turned +0.5 deg about z (active): 45.5 deg from x_E.
  const double th = inertia::deg_to_rad(45.5);
  const Eigen::Vector3d n_true(std::cos(th), std::sin(th), 0);
  EXPECT_LT((quiet.true_axis() - n_true).norm(), 1e-15);
  const Eigen::Vector3d f(3.0, -1.0, inertia::kStandardGravity);
  EXPECT_NEAR(quiet.measure(f), 1.001 * n_true.dot(f) + 0.02, 1e-12);

  p.noise_sd_mps2 = 0.05;
  SingleAxisAccelerometer noisy(p, 2);
  const int n = 50000;
  double sum = 0.0, sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e = noisy.measure(f) - (1.001 * n_true.dot(f) + 0.02);
    sum += e;
    sum2 += e * e;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 5.0 * 0.05 / std::sqrt(n));
  EXPECT_NEAR(sd, 0.05, 5.0 * 0.05 / std::sqrt(2.0 * n));   // sd of a sample sd: sigma/sqrt(2n)
}

TEST(RandomStreams, NormalDrawsAreStandard) {
  RandomSource rng(123);
  const int n = 200000;
  double s1 = 0, s2 = 0, s4 = 0;
  for (int i = 0; i < n; ++i) {
    const double x = rng.normal();
    s1 += x;
    s2 += x * x;
    s4 += x * x * x * x;
  }
  EXPECT_NEAR(s1 / n, 0.0, 5.0 / std::sqrt(n));
  EXPECT_NEAR(s2 / n, 1.0, 5.0 * std::sqrt(2.0 / n));
  EXPECT_NEAR(s4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));   // var(x^4) = 105 - 9 = 96
  EXPECT_NE(derive_seed(1, {2, 3}), derive_seed(1, {3, 2}));
  EXPECT_EQ(derive_seed(1, {2, 3}), derive_seed(1, {2, 3}));
}

}  // namespace
