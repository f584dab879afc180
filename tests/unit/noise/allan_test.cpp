// The streaming Allan estimator (analyzer/noise/allan.hpp) against the sums written out, and its
// values against the theory of white and random-walk rate noise.
#include "analyzer/noise/allan.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace inertia::noise {
namespace {

Eigen::VectorXd white(Eigen::Index n, double sd, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sd);
  Eigen::VectorXd y(n);
  for (Eigen::Index k = 0; k < n; ++k) y(k) = g(rng);
  return y;
}

TEST(Allan, StreamingEqualsTheSumsWrittenOut) {
  const Eigen::VectorXd y = (white(5000, 1.0, 1).array() + 3.0).matrix();
  AllanAccumulator acc(1e-3, 4);   // exact up to m = 16, then octave decimation
  acc.push(y);
  const std::vector<AllanPoint> points = acc.points();
  ASSERT_FALSE(points.empty());
  int exact = 0, decimated = 0;
  for (const AllanPoint& p : points) {
    double want = 0.0;
    if (p.stride == 1) {
      want = allan_variance_direct(y, p.m);
      ++exact;
      const double want_mod = modified_allan_variance_direct(y, p.m);
      EXPECT_NEAR(p.mvar, want_mod, 1e-12 * want_mod) << "m " << p.m;
    } else {
      // The overlapping estimator on the series of stride-sample averages.
      const Eigen::Index n = y.size() / p.stride;
      Eigen::VectorXd averaged(n);
      for (Eigen::Index i = 0; i < n; ++i) averaged(i) = y.segment(i * p.stride, p.stride).mean();
      want = allan_variance_direct(averaged, p.m / p.stride);
      ++decimated;
    }
    EXPECT_NEAR(p.avar, want, 1e-12 * want) << "m " << p.m << " stride " << p.stride;
    EXPECT_NEAR(p.tau, 1e-3 * static_cast<double>(p.m), 1e-15);
  }
  EXPECT_EQ(exact, 5);
  EXPECT_GE(decimated, 3);
}

TEST(Allan, AnOffsetDoesNotCostPrecision) {
  // The running sums are re-summed from the ring, so a level 1e3 times the noise costs only the
  // digits it must (the differences of sums near 1e3 m).
  const Eigen::VectorXd y = (white(5000, 1.0, 4).array() + 1.0e3).matrix();
  AllanAccumulator acc(1e-3, 4);
  acc.push(y);
  for (const AllanPoint& p : acc.points()) {
    if (p.stride != 1) continue;
    const double want = allan_variance_direct(y, p.m);
    EXPECT_NEAR(p.avar, want, 1e-9 * want) << "m " << p.m;
  }
}

TEST(Allan, WhiteRateNoiseFallsAsOneOverTauWithinItsInterval) {
  // Per-sample sd s at tau0: sigma^2(tau) = s^2 tau0 / tau (N^2 / tau with N^2 = s^2 tau0). Every
  // octave's 99.9 % interval (white-FM edf) holds it, over several records.
  const double s = 2.0, tau0 = 1e-2;
  int points = 0, outside = 0;
  for (std::uint64_t seed = 10; seed < 16; ++seed) {
    AllanAccumulator acc(tau0);
    acc.push(white(200000, s, seed));
    for (const AllanPoint& p : acc.points()) {
      const double edf = point_edf(p, 0);
      if (edf < 10.0) continue;
      const double want = s * s * tau0 / p.tau;
      const auto [lo, hi] = variance_interval(p.avar, edf, 0.999);
      ++points;
      if (want < lo || want > hi) ++outside;
    }
  }
  EXPECT_GT(points, 60);
  EXPECT_LE(outside, 1) << "of " << points;
}

TEST(Allan, MemoryDoesNotGrowWithTheRecord) {
  AllanAccumulator a(1e-4), b(1e-4);
  a.push(white(1 << 16, 1.0, 3));
  b.push(white(1 << 20, 1.0, 3));
  // One more level per doubling beyond the exact octaves, each a ring of 4 * 2^10 doubles.
  EXPECT_LE(b.memory_bytes(), a.memory_bytes() + 4 * 4 * 1024 * sizeof(double));
}

TEST(Allan, EdfFollowsTheTableForWhiteNoise) {
  // NIST SP 1065 table 5, white FM: [3(N-1)/(2m) - 2(N-2)/N] 4m^2/(4m^2+5).
  EXPECT_NEAR(overlapping_edf(1025.0, 1.0, 0), (3.0 * 1024 / 2.0 - 2.0 * 1023 / 1025) * 4.0 / 9.0, 1e-9);
  EXPECT_GT(overlapping_edf(10000.0, 4.0, -1), 100.0);
  EXPECT_GT(overlapping_edf(10000.0, 4.0, -2), 100.0);
}

}  // namespace
}  // namespace inertia::noise
