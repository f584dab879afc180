// The noise terms' fit (analyzer/noise/noise_fit.hpp) against simulated static records of known
// white, flicker and random-walk noise (the simulator's generators, hal/sim/sensors): over seeds,
// every term inside its 95 % interval in at least 90 % of the records, and the intervals as wide
// as the estimates' spread.
#include "analyzer/noise/noise_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "hal/sim/sensors/gaussian_source.hpp"
#include "hal/sim/sensors/pink_noise.hpp"

namespace inertia::noise {
namespace {

struct Truth {
  double n, b, k;
};

/// A static record at fs: white (sd per sample), pink 1/f from f_min, random walk; the truth of N,
/// B, K in the fit's units.
std::vector<AllanPoint> record(std::uint64_t seed, double fs, std::int64_t samples, double white_sd, double pink_sd,
                               double brown_sd, Truth* truth) {
  const double f_min = 1e-5;
  sim::GaussianSource white(seed, 1), steps(seed, 2);
  sim::PinkNoise pink(pink_sd, f_min, fs, seed, 3);
  AllanAccumulator acc(1.0 / fs);
  double walk = 0.0;
  const double step_sd = brown_sd / std::sqrt(fs);
  for (std::int64_t k = 0; k < samples; ++k) {
    walk += step_sd * steps.next();
    acc.push(white_sd * white.next() + pink.next() + walk);
  }
  // White: N^2 = sd^2 tau0. Flicker: one-sided S = h / f with h = sd^2 / (1 + ln(f_N / f_min))
  // (the generator's variance holds the flat part below f_min), B^2 = pi h. Random walk: K = brown_sd.
  const double h = pink_sd * pink_sd / (1.0 + std::log(0.5 * fs / f_min));
  *truth = {white_sd / std::sqrt(fs), std::sqrt(std::numbers::pi * h), brown_sd};
  return acc.points();
}

TEST(NoiseFit, TermsLieInTheirIntervalsAndTheIntervalsMatchTheSpread) {
  constexpr int kSeeds = 20;
  std::array<std::vector<double>, 3> estimates;
  std::array<std::vector<double>, 3> half_widths;
  std::array<int, 3> inside{};
  Truth truth{};
  for (int s = 0; s < kSeeds; ++s) {
    const std::vector<AllanPoint> points = record(100 + static_cast<std::uint64_t>(s), 100.0, 1 << 20, 0.02, 0.004, 2e-4, &truth);
    NoiseFitOptions o;
    o.terms = {false, true, true, true, false};   // the record holds no quantization and no ramp
    const NoiseFit fit = fit_noise(points, o);
    const double want[3] = {truth.n, truth.b, truth.k};
    for (int t = 0; t < 3; ++t) {
      const NoiseCoefficient& c = fit.terms[static_cast<std::size_t>(t + 1)];
      estimates[static_cast<std::size_t>(t)].push_back(c.value);
      half_widths[static_cast<std::size_t>(t)].push_back(0.5 * (c.upper - c.lower));
      if (want[t] >= c.lower && want[t] <= c.upper) ++inside[static_cast<std::size_t>(t)];
    }
  }
  const char* names[3] = {"N", "B", "K"};
  const double want[3] = {truth.n, truth.b, truth.k};
  for (int t = 0; t < 3; ++t) {
    const auto& e = estimates[static_cast<std::size_t>(t)];
    double mean = 0.0, var = 0.0, width = 0.0;
    for (double x : e) mean += x / kSeeds;
    for (double x : e) var += (x - mean) * (x - mean) / (kSeeds - 1);
    for (double w : half_widths[static_cast<std::size_t>(t)]) width += w / kSeeds;
    const double spread = 1.96 * std::sqrt(var);
    std::printf("%s: truth %.4g mean %.4g (%+.1f%%) inside %d/%d, mean half-width %.3g vs 1.96 sd over seeds %.3g (ratio %.2f)\n",
                names[t], want[t], mean, 100.0 * (mean / want[t] - 1.0), inside[static_cast<std::size_t>(t)], kSeeds, width,
                spread, width / spread);
    EXPECT_GE(inside[static_cast<std::size_t>(t)], 18) << names[t];
    EXPECT_GT(width / spread, 1.0 / 1.5) << names[t];
    EXPECT_LT(width / spread, 1.5) << names[t];
  }
}

}  // namespace
}  // namespace inertia::noise
