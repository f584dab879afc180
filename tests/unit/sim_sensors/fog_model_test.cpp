// Paper eq. 5 (FOG truth model) checked against hand evaluation, independent DC-gain and
// autocorrelation formulas, and measured statistics.
#include "hal/sim/sensors/fog_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/unit/sim_sensors/spectral_tools.hpp"

namespace inertia::sim {
namespace {

FogParams quiet() {
  FogParams p;
  p.noise_sd_rad_s = 0.0;
  return p;
}

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

TEST(FogModel, StaticRateWithTemperatureAndScaleNonlinearityByHand) {
  FogParams p = quiet();
  p.s0 = 0.5;
  p.eps_t_ppm_per_degc = 120.0;
  p.c_f1 = 2e-3;
  p.c_i = 1.01;
  p.c_t1 = 3e-6;
  p.c_t2 = -1e-6;
  p.drift_rad_s = 4e-6;
  for (const double w : {0.5, -1.2, 0.0}) {
    for (const double t : {0.0, 12.0, -20.0}) {
      FogModel m(p, 1000.0, 1);
      const double expected = (1.01 * w + 3e-6 * t - 1e-6 * t + 4e-6) / (0.5 * (1 + 1e-6 * 120.0 * t + 2e-3 * w));
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.step({w, 0, 0}, {0, 0, 0}, t), expected, 1e-15) << w << " " << t;
    }
  }
}

TEST(FogModel, TemperatureTermsUseCurrentAndPreviousSample) {
  FogParams p = quiet();
  p.c_t1 = 3e-6;
  p.c_t2 = -1e-6;
  FogModel m(p, 1000.0, 1);
  m.step({0, 0, 0}, {0, 0, 0}, 10.0);
  EXPECT_NEAR(m.step({0, 0, 0}, {0, 0, 0}, 14.0), 3e-6 * 14.0 - 1e-6 * 10.0, 1e-18);
  EXPECT_NEAR(m.step({0, 0, 0}, {0, 0, 0}, 9.0), 3e-6 * 9.0 - 1e-6 * 14.0, 1e-18);
}

TEST(FogModel, CrossAxisRatesEnterThroughMisalignment) {
  FogParams p = quiet();
  p.c_i = 0.98;
  p.c_f1 = 1e-3;
  p.alpha_p_rad = 0.01;
  p.alpha_o_rad = -0.02;
  const Eigen::Matrix3d m_cs = r_about_third(-0.02) * r_about_second(0.01);
  for (const Eigen::Vector3d& w : {Eigen::Vector3d(0, 1.0, 0), Eigen::Vector3d(0, 0, -2.0), Eigen::Vector3d(0.3, -0.4, 0.5)}) {
    FogModel m(p, 1000.0, 1);
    EXPECT_LT((m.m_cs() - m_cs).cwiseAbs().maxCoeff(), 1e-15);
    const double w_i = (m_cs * w)(0);
    const double expected = 0.98 * w_i / (1.0 + 1e-3 * w_i);
    EXPECT_NEAR(m.step(w, {0, 0, 0}, 0.0), expected, 1e-15) << w.transpose();
  }
  // alpha_o alone couples the second case axis with sin(alpha_o): c_y = c_i sin(alpha_o).
  p.alpha_p_rad = 0.0;
  p.c_f1 = 0.0;
  FogModel m(p, 1000.0, 1);
  EXPECT_NEAR(m.step({0, 1.0, 0}, {0, 0, 0}, 0.0), 0.98 * std::sin(-0.02), 1e-15);
}

TEST(FogModel, GSensitivityDcGainIsSumNumOverSumDen) {
  FogParams p = quiet();
  p.g_sens_i = {{2e-4, -1e-4, 5e-5}, {1.0, -0.5, 0.2}};
  p.g_sens_p = {{1e-4, 1e-4, 0.0}, {1.0, -1.2, 0.5}};
  p.g_sens_o = {{-3e-4, 0.0, 0.0}, {1.0, 0.3, 0.0}};
  const double dc_i = (2e-4 - 1e-4 + 5e-5) / (1.0 - 0.5 + 0.2);
  const double dc_p = (1e-4 + 1e-4) / (1.0 - 1.2 + 0.5);
  const double dc_o = -3e-4 / 1.3;
  const Eigen::Vector3d a(3.0, -2.0, 9.0);   // alpha = 0: case = sensor frame
  const double expected = dc_i * 3.0 + dc_p * -2.0 + dc_o * 9.0;
  FogModel settled(p, 1000.0, 1);             // static from the start: no transient
  EXPECT_NEAR(settled.step({0, 0, 0}, a, 0.0), expected, 1e-15);
  FogModel stepped(p, 1000.0, 1);             // from rest, then a step: converges to the same
  stepped.step({0, 0, 0}, {0, 0, 0}, 0.0);
  double first = 0.0, last = 0.0;
  for (int k = 0; k < 500; ++k) {
    last = stepped.step({0, 0, 0}, a, 0.0);
    if (k == 0) first = last;
  }
  EXPECT_NEAR(first, 2e-4 * 3.0 + 1e-4 * -2.0 - 3e-4 * 9.0, 1e-15);   // y(0) = num[0] u(0)
  EXPECT_NEAR(last, expected, 1e-12);
}

std::vector<double> noise_record(const FogParams& p, std::uint64_t seed, std::size_t n) {
  FogModel m(p, 1000.0, seed);
  std::vector<double> y(n);
  for (auto& v : y) v = m.step({0, 0, 0}, {0, 0, 0}, 0.0);
  return y;
}

TEST(FogModel, Ar1NoiseHasItsLag1AutocorrelationAndVariance) {
  FogParams p;
  p.s0 = 2.0;
  p.noise_sd_rad_s = 1e-5;
  p.noise = {{1.0, 0.0, 0.0, 0.0}, {1.0, -0.9, 0.0, 0.0}};
  const auto r1 = test::over_seeds(20, [&](std::uint64_t s) { return test::autocorrelation(noise_record(p, s, 20000), 1); });
  EXPECT_NEAR(r1.mean, 0.9, 4 * r1.se);
  EXPECT_LT(r1.se, 0.005);
  const auto var = test::over_seeds(20, [&](std::uint64_t s) { return test::mean_square(noise_record(p, s, 20000)); });
  const double target = 1e-10 / (1 - 0.81) / 4.0;   // sigma^2 / (1 - phi^2) / S0^2
  EXPECT_NEAR(var.mean, target, 4 * var.se);
  EXPECT_LT(var.se, 0.02 * target);
}

TEST(FogModel, ArmaAndAr2NoiseMatchTheirAutocorrelationFormulas) {
  FogParams p;
  p.noise_sd_rad_s = 1e-5;
  const double phi = 0.6, theta = 0.5;
  p.noise = {{1.0, theta, 0.0, 0.0}, {1.0, -phi, 0.0, 0.0}};   // ARMA(1,1)
  const double rho1 = (1 + phi * theta) * (phi + theta) / (1 + 2 * phi * theta + theta * theta);
  auto r = test::over_seeds(20, [&](std::uint64_t s) { return test::autocorrelation(noise_record(p, s, 20000), 1); });
  EXPECT_NEAR(r.mean, rho1, 4 * r.se);
  const double p1 = 0.5, p2 = 0.3;
  p.noise = {{1.0, 0.0, 0.0, 0.0}, {1.0, -p1, -p2, 0.0}};   // AR(2): Yule-Walker
  const double r1 = p1 / (1 - p2), r2 = p1 * r1 + p2;
  r = test::over_seeds(20, [&](std::uint64_t s) { return test::autocorrelation(noise_record(p, s, 20000), 1); });
  EXPECT_NEAR(r.mean, r1, 4 * r.se);
  r = test::over_seeds(20, [&](std::uint64_t s) { return test::autocorrelation(noise_record(p, s, 20000), 2); });
  EXPECT_NEAR(r.mean, r2, 4 * r.se);
}

TEST(FogModel, ColouredNoiseIsStationaryFromTheFirstSample) {
  FogParams p;
  p.noise_sd_rad_s = 1e-5;
  p.noise = {{1.0, 0.0, 0.0, 0.0}, {1.0, -0.999, 0.0, 0.0}};   // time constant 1000 samples
  const auto first = test::over_seeds(400, [&](std::uint64_t s) {
    const double y0 = noise_record(p, s, 1)[0];
    return y0 * y0;
  });
  // Started from rest the variance of sample 0 would be sigma^2, 500 times less.
  EXPECT_NEAR(first.mean, 1e-10 / (1 - 0.999 * 0.999), 4 * first.se);
}

TEST(FogModel, SameSeedSameOutputDifferentSeedDifferentOutput) {
  FogParams p;
  p.noise = {{1.0, 0.2, 0.0, 0.0}, {1.0, -0.7, 0.1, 0.0}};
  auto run = [&](std::uint64_t seed) {
    FogModel m(p, 1000.0, seed);
    std::vector<double> y;
    for (int k = 0; k < 2000; ++k) y.push_back(m.step({0.01 * k, 0, 0}, {0, 0, 9.8}, 0.0));
    return y;
  };
  const auto a = run(3), b = run(3), c = run(4);
  EXPECT_EQ(a, b);
  int differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i];
  EXPECT_EQ(differ, static_cast<int>(a.size()));
}

void expect_rejected(const FogParams& p, const std::string& field) {
  try {
    FogModel m(p, 1000.0, 1);
    ADD_FAILURE() << "accepted " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(FogModel, RejectsUnstableOrUnnormalisedFilters) {
  FogParams p = quiet();
  p.noise.den = {2.0, 0.0, 0.0, 0.0};
  expect_rejected(p, "noise");
  p = quiet();
  p.noise.den = {1.0, -1.0, 0.0, 0.0};           // random walk: pole on the unit circle
  expect_rejected(p, "noise");
  p = quiet();
  p.noise.den = {1.0, -2.5, 2.0, -0.5};          // (1 - q^-1)(1 - 1.5 q^-1 + 0.5 q^-2): poles 1, 1, 0.5
  expect_rejected(p, "noise");
  p = quiet();
  p.g_sens_i.den = {1.0, -2.1, 1.1};             // poles 1 and 1.1
  expect_rejected(p, "g_sens_i");
  p = quiet();
  p.g_sens_p.den = {1.0, 0.0, 1.2};              // complex poles of modulus sqrt(1.2)
  expect_rejected(p, "g_sens_p");
  p = quiet();
  p.g_sens_o.den = {0.5, 0.1, 0.0};
  expect_rejected(p, "g_sens_o");
  p = quiet();
  p.g_sens_o.num = {NAN, 0.0, 0.0};
  expect_rejected(p, "g_sens_o");
  p = quiet();
  p.s0 = 0.0;
  expect_rejected(p, "s0");
  p = quiet();
  p.g_sens_p.den = {1.0, -1.9, 0.95};            // stable (complex poles of modulus 0.975)
  EXPECT_NO_THROW(FogModel(p, 1000.0, 1));
}

}  // namespace
}  // namespace inertia::sim
