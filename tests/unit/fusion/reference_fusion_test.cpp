// Reference fusion against hand computations and noise theory.
#include "analyzer/fusion/reference_fusion.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/units.hpp"

namespace inertia::fusion {
namespace {

// Four single-axis monitors on a 45 degree cone about z_E (section 2.3).
MonitorLayout cone_layout(double sd) {
  MonitorLayout layout;
  for (int j = 0; j < 4; ++j) {
    const double az = kPi / 2.0 * j + kPi / 4.0;
    layout.axes.emplace_back(std::cos(az) * std::sin(kPi / 4), std::sin(az) * std::sin(kPi / 4), std::cos(kPi / 4));
    layout.noise_sd_mps2.push_back(sd);
  }
  return layout;
}

TEST(FuseMonitors, ExactWithoutNoiseAndBiasRemoved) {
  MonitorLayout layout = cone_layout(0.01);
  layout.bias_mps2 = {0.01, -0.02, 0.03, 0.0};
  Matrix3Columns truth(5, 3);
  truth << 0, 0, 9.8, 1, 2, 3, -4, 0.5, 9.8, 100, -50, 9.8, 0, 0, 0;
  Eigen::MatrixXd readings(5, 4);
  for (int j = 0; j < 4; ++j) readings.col(j) = truth * layout.axes[static_cast<std::size_t>(j)] + Eigen::VectorXd::Constant(5, layout.bias_mps2[static_cast<std::size_t>(j)]);
  double rms = -1.0;
  const Matrix3Columns a = fuse_monitors(readings, layout, &rms);
  EXPECT_LT((a - truth).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(rms, 1e-9);
}

TEST(FuseMonitors, ErrorSpreadMatchesWeightedLeastSquaresTheory) {
  const double sd = 0.05;
  const MonitorLayout layout = cone_layout(sd);
  const int n = 20000;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, sd);
  Matrix3Columns truth = Matrix3Columns::Zero(n, 3);
  truth.col(2).setConstant(kStandardGravity);
  Eigen::MatrixXd readings(n, 4);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < 4; ++j) readings(k, j) = truth.row(k).dot(layout.axes[static_cast<std::size_t>(j)]) + noise(rng);
  double rms = 0.0;
  const Matrix3Columns err = fuse_monitors(readings, layout, &rms) - truth;
  // Theory: cov = sd^2 (H^T H)^-1; for the 45 deg cone H^T H = diag(1, 1, 2) -> sd, sd, sd/sqrt(2).
  const double expected[3] = {sd, sd, sd / std::sqrt(2.0)};
  for (int c = 0; c < 3; ++c) {
    const double measured = std::sqrt(err.col(c).squaredNorm() / n);
    // The sample sd of n Gaussian errors has relative sd 1/sqrt(2n); allow 4 of those.
    EXPECT_NEAR(measured, expected[c], 4.0 * expected[c] / std::sqrt(2.0 * n)) << "axis " << c;
  }
  // One redundant monitor: the normalized residual RMS is 1 within its own sampling spread.
  EXPECT_NEAR(rms, 1.0, 4.0 / std::sqrt(2.0 * n));
}

TEST(FuseMonitors, RejectsLayoutThatDoesNotSpan3D) {
  MonitorLayout flat;
  flat.axes = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d(1, 1, 0)};
  flat.noise_sd_mps2 = {1, 1, 1};
  EXPECT_THROW(fuse_monitors(Eigen::MatrixXd::Zero(2, 3), flat, nullptr), std::invalid_argument);
  EXPECT_THROW(fuse_monitors(Eigen::MatrixXd::Zero(2, 2), cone_layout(1.0), nullptr), std::invalid_argument);
}

TEST(ComplementaryVibration, PassesConsistentSignalUnchanged) {
  const double dt = 1e-4, f = 40.0, amp = 1e-3;   // 1 mm at 40 Hz
  const int n = 20000;
  Eigen::VectorXd x(n), a(n);
  for (int k = 0; k < n; ++k) {
    const double t = k * dt;
    x(k) = amp * std::sin(2 * kPi * f * t);
    a(k) = -amp * std::pow(2 * kPi * f, 2) * std::sin(2 * kPi * f * t);
  }
  const Eigen::VectorXd fused = complementary_vibration(a, x, dt, 5.0);
  // Central second differences are exact to (w dt)^2/12 relative; the low-pass suppresses that too.
  const double peak = amp * std::pow(2 * kPi * f, 2);
  EXPECT_LT((fused - a).segment(100, n - 200).cwiseAbs().maxCoeff(), 1e-4 * peak);
}

// The second difference is exact for a cubic on every sample (five points inside, three next to
// the ends, the ends' linear extrapolation of a linear second derivative), pushed in pieces of any
// length from 1 to 9 samples; the first difference is the three-point one.
TEST(CentralDifferences, SecondDifferenceExactForACubicOnEverySampleOfAnyLength) {
  const double dt = 0.01;
  const auto x = [](double t) { return 0.3 - 1.2 * t + 2.5 * t * t - 4.0 * t * t * t; };
  const auto second = [](double t) { return 5.0 - 24.0 * t; };
  for (int n = 1; n <= 9; ++n) {
    SCOPED_TRACE(n);
    CentralDifferences d(dt);
    for (int k = 0; k < n; ++k) d.push(x(0.7 + k * dt));
    d.finish();
    int k = 0;
    for (; d.ready(); ++k) {
      const CentralDifferences::Value v = d.pop();
      if (n < 3) {
        EXPECT_EQ(v.second, 0.0);
      } else if (n == 3) {
        EXPECT_NEAR(v.second, second(0.7 + dt), 1e-9) << "sample " << k;   // one value for all three
      } else {
        EXPECT_NEAR(v.second, second(0.7 + k * dt), 1e-9) << "sample " << k;
      }
      if (n >= 4 && k > 0 && k < n - 1) {
        EXPECT_NEAR(v.first, (x(0.7 + (k + 1) * dt) - x(0.7 + (k - 1) * dt)) / (2 * dt), 1e-12) << "sample " << k;
      }
    }
    EXPECT_EQ(k, n);
  }
}

// The shaker's low path at a slow output rate: a 4 Hz sine at 100 Hz (25 samples a cycle). The
// three-point second difference's gain 1 - (w dt)^2 / 12 read its amplitude 0.5 % low, and
// through the 5 Hz low-pass the fused sine came out 0.3 % high; the five-point stencil's
// 1 - (w dt)^4 / 90 is 4e-5.
TEST(ComplementaryVibration, ASlowSineAt25SamplesACycleKeepsItsAmplitude) {
  const double dt = 0.01, f = 4.0, amp = 0.03;   // 3 cm at 4 Hz: about 1.9 g
  const int n = 3000;
  const double w = 2 * kPi * f;
  Eigen::VectorXd x(n), a(n);
  for (int k = 0; k < n; ++k) {
    x(k) = amp * std::sin(w * k * dt);
    a(k) = -amp * w * w * std::sin(w * k * dt);
  }
  const Eigen::VectorXd fused = complementary_vibration(a, x, dt, 5.0);
  const double peak = amp * w * w;
  EXPECT_LT((fused - a).segment(500, n - 1000).cwiseAbs().maxCoeff(), 2.0 * std::pow(w * dt, 4) / 90.0 * peak);
}

TEST(ComplementaryVibration, EncoderRemovesAccelerometerDriftAtLowFrequency) {
  const double dt = 1e-4;
  const int n = 100000;   // 10 s
  std::mt19937_64 rng(3);
  std::normal_distribution<double> white(0.0, 1.0);
  Eigen::VectorXd x(n), a_true(n), a_meas(n);
  double drift = 0.05;   // m/s^2 bias plus a random walk: what an accelerometer adds at low frequency
  const double resolution = 1e-7;   // 0.1 um encoder
  for (int k = 0; k < n; ++k) {
    const double t = k * dt;
    const double w = 2 * kPi * 2.0;   // 2 Hz motion, below the crossover
    const double xt = 5e-3 * std::sin(w * t);
    x(k) = resolution * std::round(xt / resolution);
    a_true(k) = -5e-3 * w * w * std::sin(w * t);
    drift += 1e-4 * white(rng);
    a_meas(k) = a_true(k) + drift;
  }
  const Eigen::VectorXd fused = complementary_vibration(a_meas, x, dt, 10.0);
  const Eigen::Index skip = 20000;   // the filters' start-up (a few time constants of 10 Hz)
  const double err_accel = (a_meas - a_true).segment(skip, n - 2 * skip).cwiseAbs().mean();
  const double err_fused = (fused - a_true).segment(skip, n - 2 * skip).cwiseAbs().mean();
  EXPECT_LT(err_fused, 0.05 * err_accel);
}

// A lost accelerometer sample in mid-vibration (its frame lost, the encoder's there): the filter
// coasts on the encoder, and the rows after the hole equal an unbroken filter's; exact for a
// consistent input with gravity along the axis (the predicted reading is the true one).
TEST(ComplementaryFilter, CoastsThroughLostAccelerometerSamples) {
  const double dt = 1e-3, f = 80.0, amp = 2e-5, g_axis = 3.0;   // 80 Hz sine on a tilted axis
  const int n = 3000, hole = 1500, lost = 3;
  const auto accel = [&](int k) { return -amp * std::pow(2 * kPi * f, 2) * std::sin(2 * kPi * f * k * dt); };
  ComplementaryFilter unbroken(dt, 5.0), coasting(dt, 5.0);
  double worst = 0.0;
  int rows_after = 0;
  for (int k = 0; k < n; ++k) {
    const double enc = accel(k), mon = accel(k) + g_axis;   // the accelerometer reads specific force
    const double want = unbroken.step(mon, enc);
    if (k >= hole && k < hole + lost) {
      coasting.coast(enc);
      continue;
    }
    const double got = coasting.step(mon, enc);
    if (k >= hole + lost) {
      worst = std::max(worst, std::abs(got - want));
      ++rows_after;
    }
  }
  EXPECT_EQ(rows_after, n - hole - lost);
  EXPECT_LT(worst, 1e-12 * g_axis);
}

TEST(TableSpecificForce, GravityTurnsWithTheTableAndCentripetalPointsInward) {
  const double dt = 1e-3, rate = 1.0;   // 1 rad/s
  const int n = 2000;
  Eigen::VectorXd angle(n);
  for (int k = 0; k < n; ++k) angle(k) = rate * k * dt;
  const Eigen::Vector3d f0(0, 0, kStandardGravity);
  // About x, no offset: after theta the lab's up is (0, g sin theta, g cos theta) in the table frame.
  Matrix3Columns w;
  const Matrix3Columns f = table_specific_force(angle, Eigen::Vector3d::UnitX(), f0, Eigen::Vector3d::Zero(), dt, &w);
  for (int k : {1, 500, 1570, 1998}) {
    const double th = angle(k);
    EXPECT_NEAR(f(k, 0), 0.0, 1e-12);
    EXPECT_NEAR(f(k, 1), kStandardGravity * std::sin(th), 1e-9);
    EXPECT_NEAR(f(k, 2), kStandardGravity * std::cos(th), 1e-9);
    EXPECT_NEAR(w(k, 0), rate, 1e-9);
  }
  // About z (vertical) with the sensor 0.2 m out on x: centripetal -w^2 r, gravity unchanged.
  const Matrix3Columns g = table_specific_force(angle, Eigen::Vector3d::UnitZ(), f0, Eigen::Vector3d(0.2, 0, 0), dt);
  EXPECT_NEAR(g(1000, 0), -rate * rate * 0.2, 1e-9);
  EXPECT_NEAR(g(1000, 1), 0.0, 1e-9);
  EXPECT_NEAR(g(1000, 2), kStandardGravity, 1e-12);
}

}  // namespace
}  // namespace inertia::fusion
