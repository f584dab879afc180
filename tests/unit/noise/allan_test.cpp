// The streaming Allan estimator (analyzer/noise/allan.hpp) against the sums written out, and its
// values against the theory of white and random-walk rate noise.
#include "analyzer/noise/allan.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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
    // Every second difference of the (averaged) series, every sum of m of them at stride 1.
    const std::int64_t n = y.size() / p.stride, m = p.m / p.stride;
    EXPECT_EQ(p.terms, n - 2 * m + 1) << "m " << p.m;
    if (p.stride == 1) {
      EXPECT_EQ(p.mod_terms, n - 3 * m + 2) << "m " << p.m;
    }
    EXPECT_EQ(p.phase_points, std::vector<double>{static_cast<double>(n + 1)});
  }
  EXPECT_EQ(exact, 5);
  EXPECT_GE(decimated, 3);
}

TEST(Allan, AnOffsetDoesNotCostPrecision) {
  // Against the sums written out on the raw samples: the tolerance is theirs (sums near 1e3 m
  // differenced lose the offset's digits), the streaming estimator loses none (below).
  const Eigen::VectorXd y = (white(5000, 1.0, 4).array() + 1.0e3).matrix();
  AllanAccumulator acc(1e-3, 4);
  acc.push(y);
  for (const AllanPoint& p : acc.points()) {
    if (p.stride != 1) continue;
    const double want = allan_variance_direct(y, p.m);
    EXPECT_NEAR(p.avar, want, 1e-9 * want) << "m " << p.m;
  }
}

TEST(Allan, ALongRecordWithAnOffsetKeepsItsDigits) {
  // 2^20 samples at 1e3 with unit noise, against the sums written out on y - 1e3 (exact: Sterbenz),
  // which round at the noise's scale, not the offset's. The estimator's own rounding is that of a
  // phase integrated over one buffer (7 * 2^10 samples) about its mean, some 1e2 noise sd: a few
  // 1e-14 of the variance at every m and stride. 1e-12 catches rounding that grows with the record
  // or with the offset (running sums of the raw samples erred by 1e-9 at stride 512).
  const Eigen::VectorXd y = (white(Eigen::Index{1} << 20, 1.0, 5).array() + 1.0e3).matrix();
  const Eigen::VectorXd noise = (y.array() - 1.0e3).matrix();
  AllanAccumulator acc(1e-3);
  acc.push(y);
  int checked = 0;
  for (const AllanPoint& p : acc.points()) {
    if (p.stride == 1) {
      if (p.m != 1 && p.m != 16 && p.m != 256 && p.m != 1024) continue;
      const double want = allan_variance_direct(noise, p.m);
      EXPECT_NEAR(p.avar, want, 1e-12 * want) << "m " << p.m;
      if (p.m <= 16) {   // the modified variance written out costs 3 m N
        const double want_mod = modified_allan_variance_direct(noise, p.m);
        EXPECT_NEAR(p.mvar, want_mod, 1e-12 * want_mod) << "m " << p.m;
      }
    } else {
      if (p.stride != 8 && p.stride != 64 && p.stride != 512) continue;
      const Eigen::Index n = noise.size() / p.stride;
      Eigen::VectorXd averaged(n);
      for (Eigen::Index i = 0; i < n; ++i) averaged(i) = noise.segment(i * p.stride, p.stride).mean();
      const double want = allan_variance_direct(averaged, p.m / p.stride);
      EXPECT_NEAR(p.avar, want, 1e-12 * want) << "m " << p.m << " stride " << p.stride;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 7);
}

TEST(Allan, HowTheSamplesArriveChangesNothing) {
  // Blocks of any length, one sample at a time, and points() asked midway (which sums a part-filled
  // block on a copy) all give the same bits.
  const Eigen::VectorXd y = (white(20000, 1.0, 6).array() + 3.0).matrix();
  AllanAccumulator one_by_one(1e-3, 4), in_pieces(1e-3, 4);
  for (Eigen::Index k = 0; k < y.size(); ++k) {
    one_by_one.push(y(k));
    if (k == 4321) {
      EXPECT_FALSE(one_by_one.points().empty());
    }
  }
  for (Eigen::Index begin = 0, length = 1; begin < y.size(); begin += length, length = 3 * length + 1) {
    in_pieces.push(y.segment(begin, std::min(length, y.size() - begin)));
    (void)in_pieces.points();
  }
  const std::vector<AllanPoint> a = one_by_one.points(), b = in_pieces.points();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].m, b[i].m);
    EXPECT_EQ(a[i].avar, b[i].avar) << "m " << a[i].m;
    EXPECT_EQ(a[i].terms, b[i].terms);
    EXPECT_EQ(a[i].mod_terms, b[i].mod_terms);
    if (a[i].mod_terms > 0) {
      EXPECT_EQ(a[i].mvar, b[i].mvar) << "m " << a[i].m;
    }
    EXPECT_EQ(a[i].phase_points, b[i].phase_points);
  }
  EXPECT_EQ(one_by_one.samples(), y.size());
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

// The record pushed whole or in pieces of any size: the same points to the bit (each level's
// blocks are the same, and a sum over a block adds in the same order wherever the heap put it).
TEST(AllanAccumulator, ThePointsDoNotDependOnHowTheSamplesArePushed) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 0.01);
  Eigen::VectorXd y(40000);
  for (double& v : y) v = 3.0 + g(rng);
  AllanAccumulator whole(1e-3), pieces(1e-3);
  whole.push(y);
  pieces.push(y.head(12345));
  pieces.push(y(12345));
  pieces.push(y.tail(y.size() - 12346));
  const std::vector<AllanPoint> a = whole.points(), b = pieces.points();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].avar, b[i].avar) << "tau " << a[i].tau;
    EXPECT_EQ(std::isnan(a[i].mvar), std::isnan(b[i].mvar)) << "tau " << a[i].tau;
    if (!std::isnan(a[i].mvar)) {
      EXPECT_EQ(a[i].mvar, b[i].mvar) << "tau " << a[i].tau;
    }
  }
}

}  // namespace
}  // namespace inertia::noise
