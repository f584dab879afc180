// Paper eq. 12 (accelerometer truth model) checked against hand evaluation and measured
// responses; the expected values never come from the model under test.
#include "hal/sim/sensors/accelerometer_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "common/units.hpp"
#include "tests/unit/sim_sensors/spectral_tools.hpp"

namespace inertia::sim {
namespace {

constexpr double g0 = 9.80665;

AccelerometerParams quiet(AccelerometerParams p = {}) {
  p.white_sd_g = 0.0;
  p.pink_sd_g = 0.0;
  p.brown_sd_g = 0.0;
  return p;
}

// Frame rotations written out (rows = rotated axes in the old frame), independent of frames.hpp.
Eigen::Matrix3d r_about_second(double a) {
  Eigen::Matrix3d r;
  r << std::cos(a), 0, -std::sin(a), 0, 1, 0, std::sin(a), 0, std::cos(a);
  return r;
}
Eigen::Matrix3d r_about_third(double a) {
  Eigen::Matrix3d r;
  r << std::cos(a), std::sin(a), 0, -std::sin(a), std::cos(a), 0, 0, 0, 1;
  return r;
}

// Equation 12 without noise and with the high-pass terms at steady state (zero), in g.
double eq12_static(const AccelerometerParams& p, const Eigen::Vector3d& a_case, double t) {
  const Eigen::Vector3d a = r_about_third(p.alpha_o_rad) * r_about_second(p.alpha_p_rad) * a_case / g0;
  const double ai = a(0), ap = a(1), ao = a(2);
  const double sgn = ai > 0 ? 1.0 : (ai < 0 ? -1.0 : 0.0);
  return p.k_i * (1 + p.scale_tc_per_degc * t) *
         (p.k_b + p.bias_tc_g_per_degc * t + ai + p.k_s * sgn + p.k_a * std::fabs(ai) +
          p.k_oq * ai * std::fabs(ai) + p.k_ip * ai * ap + p.k_io * ai * ao + p.k_po * ap * ao);
}

AccelerometerParams every_static_term() {
  AccelerometerParams p = quiet();
  p.k_i = 0.86;
  p.k_b = 4e-3;
  p.k_s = 2e-3;
  p.k_a = 3e-3;
  p.k_oq = -4e-3;
  p.k_ip = 1e-2;
  p.k_io = -2e-2;
  p.k_po = 3e-2;
  p.alpha_p_rad = 0.02;    // large enough that a wrong rotation order or sign shows at 1e-12
  p.alpha_o_rad = -0.03;
  p.bias_tc_g_per_degc = 1e-4;
  p.scale_tc_per_degc = 2e-4;
  return p;
}

TEST(AccelerometerModel, MisalignmentIsOaAfterPaRotation) {
  AccelerometerParams p = quiet();
  p.alpha_p_rad = 0.02;
  p.alpha_o_rad = -0.03;
  const AccelerometerModel m(p, 1000.0, 1);
  const Eigen::Matrix3d expected = r_about_third(-0.03) * r_about_second(0.02);
  EXPECT_LT((m.m_cs() - expected).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(AccelerometerModel, StaticOutputMatchesEquation12ByHand) {
  const AccelerometerParams p = every_static_term();
  const std::vector<Eigen::Vector3d> inputs = {
      {g0, 0, 0},           {-g0, 0, 0},           {0.3 * g0, -0.8 * g0, 0.5 * g0},
      {-2.5 * g0, 1.5 * g0, -0.7 * g0}, {-0.1 * g0, 3 * g0, 2 * g0}, {12 * g0, -4 * g0, 6 * g0}};
  for (const double t : {0.0, -15.0, 40.0}) {
    for (const auto& a : inputs) {
      AccelerometerModel m(p, 10000.0, 3);   // fresh: settles the high-pass at this static input
      const double expected = eq12_static(p, a, t);
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(m.step(a, t), expected, 1e-12 * (1 + std::fabs(expected)))
            << "a_case = " << a.transpose() << ", T = " << t;
    }
  }
}

TEST(AccelerometerModel, SignOfZeroInputIsZero) {
  AccelerometerParams p = quiet();
  p.k_s = 5e-3;
  p.alpha_p_rad = p.alpha_o_rad = 0.0;
  AccelerometerModel m(p, 1000.0, 1);
  // a_i = 0 exactly: sign(0) = 0, so only the bias and K_po a_p a_o remain.
  EXPECT_NEAR(m.step({0.0, 2 * g0, 3 * g0}, 0.0), p.k_i * (p.k_b + p.k_po * 6.0), 1e-15);
}

// The high-pass K_jj(s) = K_jj s/(s + b) measured on each axis with a_j^2 = g^2 (1 + m sin wt):
// with alpha = 0 and only one axis excited every other term is known and subtracted.
double measured_high_pass_gain(int axis, double omega, double b, double fs) {
  AccelerometerParams p = quiet();
  p.alpha_p_rad = p.alpha_o_rad = 0.0;
  p.k_ip = p.k_io = p.k_po = 0.0;
  p.k_ii = 1e-3;
  p.k_pp = 2e-3;
  p.k_oo = 3e-3;
  p.b_ii_rad_s = p.b_pp_rad_s = p.b_oo_rad_s = b;
  const double k[3] = {p.k_ii, p.k_pp, p.k_oo};
  AccelerometerModel model(p, fs, 1);
  constexpr double kDepth = 0.5;
  // Settle 20 time constants of the slower of the corner and the excitation, then measure an
  // integer number of periods.
  const double settle_s = 20.0 / std::min(b, omega);
  const double period_s = 2 * kPi / omega;
  const double measure_s = period_s * std::ceil(std::max(0.5, 5 * period_s) / period_s);
  const auto n_settle = static_cast<long>(settle_s * fs);
  const auto n_measure = static_cast<long>(std::round(measure_s * fs));
  std::vector<double> hp;
  for (long i = 0; i < n_settle + n_measure; ++i) {
    const double t = static_cast<double>(i) / fs;
    const double a = g0 * std::sqrt(1.0 + kDepth * std::sin(omega * t));
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    v(axis) = a;
    double y = model.step(v, 0.0) / p.k_i - p.k_b;
    if (axis == 0) y -= a / g0;   // the linear term (the only other one on the input axis)
    if (i >= n_settle) hp.push_back(y);
  }
  // The fit's time origin is the first kept sample; the amplitude does not depend on it.
  return test::sine_amplitude(hp, omega, fs) / (kDepth * k[axis]);
}

double continuous_high_pass_gain(double omega, double b) { return omega / std::hypot(omega, b); }

TEST(AccelerometerModel, HighPassGainAtCornerIsMinus3dB) {
  for (int axis = 0; axis < 3; ++axis) {
    const double gain = measured_high_pass_gain(axis, 500.0, 500.0, 10000.0);
    EXPECT_NEAR(gain, 1.0 / std::sqrt(2.0), 0.01 / std::sqrt(2.0)) << "axis " << axis;
  }
  // Corner close to Nyquist: a design that only matches the corner at low b T would miss it.
  EXPECT_NEAR(measured_high_pass_gain(0, 1500.0, 1500.0, 1000.0), 1.0 / std::sqrt(2.0), 0.01 / std::sqrt(2.0));
}

TEST(AccelerometerModel, HighPassGainTendsToKAtHighAndZeroAtLowFrequency) {
  for (int axis = 0; axis < 3; ++axis) {
    const double high = measured_high_pass_gain(axis, 40 * 500.0, 500.0, 10000.0);
    EXPECT_NEAR(high, continuous_high_pass_gain(40 * 500.0, 500.0), 0.01) << "axis " << axis;
    const double low = measured_high_pass_gain(axis, 500.0 / 100, 500.0, 10000.0);
    EXPECT_NEAR(low, continuous_high_pass_gain(5.0, 500.0), 0.01 * 0.01) << "axis " << axis;
  }
}

TEST(AccelerometerModel, HighPassStepDecaysToZeroWithTimeConstantOneOverB) {
  AccelerometerParams p = quiet();
  p.alpha_p_rad = p.alpha_o_rad = 0.0;
  p.k_po = 0.0;
  p.k_pp = 1e-3;
  p.b_pp_rad_s = 500.0;
  const double fs = 10000.0;
  AccelerometerModel m(p, fs, 1);
  m.step({0, 0, 0}, 0.0);
  // a_p^2 steps from 0 to 4 g^2 between two samples. The continuous filter driven by the samples
  // joined by straight lines (a ramp over the last sample period T) answers, from the end of the
  // ramp on, 4 K_pp (1 - exp(-b T)) / (b T) exp(-b t).
  std::vector<double> hp;
  for (int k = 0; k < 4000; ++k) hp.push_back(m.step({0, 2 * g0, 0}, 0.0) / p.k_i - p.k_b);
  const double b = 500.0, period = 1.0 / fs;
  const double peak = 4e-3 * (1 - std::exp(-b * period)) / (b * period);
  EXPECT_NEAR(hp[0], peak, 0.01 * peak);
  const std::size_t k_2tau = 40;   // 2 / b seconds
  EXPECT_NEAR(hp[k_2tau], peak * std::exp(-2.0), 0.01 * peak * std::exp(-2.0));
  EXPECT_NEAR(hp.back(), 0.0, 4e-3 * 1e-6);   // 20 time constants later: DC gain is zero
}

TEST(AccelerometerModel, WhiteNoiseSdPerSample) {
  AccelerometerParams p = quiet();
  p.k_i = 2.0;
  p.k_b = 0.0;
  p.white_sd_g = 1e-4;
  const auto ms = test::over_seeds(20, [&](std::uint64_t seed) {
    AccelerometerModel m(p, 10000.0, seed);
    std::vector<double> y(20000);
    for (auto& v : y) v = m.step(Eigen::Vector3d::Zero(), 0.0) / p.k_i;
    return test::mean_square(y);
  });
  const double target = p.white_sd_g * p.white_sd_g;
  EXPECT_NEAR(ms.mean, target, 4 * ms.se);
  EXPECT_LT(ms.se, 0.01 * target);   // the check above is tight enough to mean something
  // White: no correlation between neighbours (sd of r1 ~ 1/sqrt(N)).
  AccelerometerModel m(p, 10000.0, 5);
  std::vector<double> y(200000);
  for (auto& v : y) v = m.step(Eigen::Vector3d::Zero(), 0.0);
  EXPECT_NEAR(test::autocorrelation(y, 1), 0.0, 4.0 / std::sqrt(200000.0));
}

std::vector<double> noise_only(const AccelerometerParams& p, double fs, std::uint64_t seed, std::size_t n) {
  AccelerometerModel m(p, fs, seed);
  std::vector<double> y(n);
  for (auto& v : y) v = m.step(Eigen::Vector3d::Zero(), 0.0) / p.k_i - p.k_b;
  return y;
}

TEST(AccelerometerModel, PinkNoiseSdPerSampleAndStationaryFromTheFirstSample) {
  AccelerometerParams p = quiet();
  p.pink_sd_g = 1.5e-3;
  p.pink_min_hz = 1.0;
  const double fs = 1000.0;
  const auto ms = test::over_seeds(16, [&](std::uint64_t seed) { return test::mean_square(noise_only(p, fs, seed, 100000)); });
  const double target = p.pink_sd_g * p.pink_sd_g;
  EXPECT_NEAR(ms.mean, target, 4 * ms.se);
  EXPECT_LT(ms.se, 0.02 * target);
  // Sample 0 over many seeds: a filter started from rest would give a much smaller variance.
  AccelerometerParams slow = p;
  slow.pink_min_hz = 0.01;   // time constants of minutes
  const auto first = test::over_seeds(400, [&](std::uint64_t seed) {
    const double y0 = noise_only(slow, 10000.0, seed, 1)[0];
    return y0 * y0;
  });
  EXPECT_NEAR(first.mean, target, 4 * first.se);
}

TEST(AccelerometerModel, PinkNoisePsdFallsOneDecadePerDecade) {
  AccelerometerParams p = quiet();
  p.pink_sd_g = 1.5e-3;
  p.pink_min_hz = 0.1;
  const double fs = 1000.0;
  const std::vector<double> y = noise_only(p, fs, 42, 1 << 21);
  const test::Psd psd = test::welch(y, 1 << 13, fs);
  // 1 Hz .. 250 Hz: 2.4 decades, ten pink_min_hz above the flat part, half Nyquist below the top.
  const test::SlopeFit fit = test::loglog_slope(psd, 1.0, 250.0, 10);
  // The pole-zero approximation of 1/f ripples by about +-0.1 dB (slope error ~0.02 at most over
  // two decades); the rest of the tolerance is the statistical error of the fit.
  EXPECT_NEAR(fit.slope, -1.0, 0.02 + 4 * fit.slope_se) << "se " << fit.slope_se;
  EXPECT_LT(fit.slope_se, 0.01);
}

TEST(AccelerometerModel, BrownNoiseIsARandomWalkWithSdAfterOneSecond) {
  AccelerometerParams p = quiet();
  p.brown_sd_g = 2e-3;
  const double fs = 1000.0;
  // One-second increments of independent seeds: sd must be brown_sd_g.
  const auto ms = test::over_seeds(400, [&](std::uint64_t seed) {
    const std::vector<double> y = noise_only(p, fs, seed, 1001);
    const double d = y[1000] - y[0];
    return d * d;
  });
  EXPECT_NEAR(ms.mean, p.brown_sd_g * p.brown_sd_g, 4 * ms.se);
  // Per-sample increments are white with variance brown_sd^2 / fs (tight check of the scaling).
  const std::vector<double> y = noise_only(p, fs, 9, 1 << 21);
  std::vector<double> d(y.size() - 1);
  for (std::size_t i = 1; i < y.size(); ++i) d[i - 1] = y[i] - y[i - 1];
  const double target = p.brown_sd_g * p.brown_sd_g / fs;
  EXPECT_NEAR(test::mean_square(d), target, 4 * target * std::sqrt(2.0 / static_cast<double>(d.size())));
  EXPECT_NEAR(test::autocorrelation(d, 1), 0.0, 4.0 / std::sqrt(static_cast<double>(d.size())));
  const test::SlopeFit fit = test::loglog_slope(test::welch(y, 1 << 13, fs), 0.5, 100.0, 10);
  // The discrete walk's PSD is sigma^2 / (4 sin^2(pi f / fs)), steeper than f^-2 by < 0.04 in
  // slope terms below fs/10; the rest is the fit's statistical error.
  EXPECT_NEAR(fit.slope, -2.0, 0.04 + 4 * fit.slope_se) << "se " << fit.slope_se;
  EXPECT_LT(fit.slope_se, 0.01);
}

TEST(AccelerometerModel, SameSeedSameOutputDifferentSeedDifferentOutput) {
  AccelerometerParams p;   // table 1, all noises on
  p.brown_sd_g = 1e-4;
  auto run = [&](std::uint64_t seed) {
    AccelerometerModel m(p, 10000.0, seed);
    std::vector<double> y;
    for (int k = 0; k < 5000; ++k) y.push_back(m.step({0.1 * k, g0, -0.2 * g0}, 0.01 * k));
    return y;
  };
  const auto a = run(17), b = run(17), c = run(18);
  EXPECT_EQ(a, b);
  int differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i];
  EXPECT_EQ(differ, static_cast<int>(a.size()));
}

TEST(AccelerometerModel, RejectsParametersOutOfRange) {
  const AccelerometerParams good;
  EXPECT_NO_THROW(AccelerometerModel(good, 10000.0, 1));
  EXPECT_THROW(AccelerometerModel(good, 0.0, 1), std::invalid_argument);
  auto with = [&](auto change) { AccelerometerParams p = good; change(p); return p; };
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.b_ii_rad_s = 0.0; }), 10000.0, 1), std::invalid_argument);
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.b_pp_rad_s = 4e4; }), 10000.0, 1), std::invalid_argument);
  EXPECT_NO_THROW(AccelerometerModel(with([](auto& p) { p.k_oo = 0.0; p.b_oo_rad_s = 0.0; }), 10000.0, 1));
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.white_sd_g = -1e-4; }), 10000.0, 1), std::invalid_argument);
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.brown_sd_g = -1e-4; }), 10000.0, 1), std::invalid_argument);
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.pink_min_hz = 6000.0; }), 10000.0, 1), std::invalid_argument);
  EXPECT_THROW(AccelerometerModel(with([](auto& p) { p.pink_min_hz = 0.0; }), 10000.0, 1), std::invalid_argument);
  try {
    AccelerometerModel(with([](auto& p) { p.b_pp_rad_s = -1.0; }), 10000.0, 1);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("b_pp_rad_s"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace inertia::sim
