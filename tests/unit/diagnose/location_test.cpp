// The location statistics of diagnose (analyzer/diagnose/location.hpp) against noise of known
// law: under the model's own noise every band and condition-bin test must hold its nominal size,
// a band's mean ratio must be 1 within its chi-square spread, and an excess put in one band or one
// |a| bin must be found there and nowhere else.
#include <gtest/gtest.h>

#include <unsupported/Eigen/FFT>

#include <cmath>
#include <complex>
#include <iostream>
#include <numbers>
#include <random>
#include <vector>

#include "analyzer/diagnose/location.hpp"

namespace inertia::diagnose {
namespace {

constexpr double kFs = 1000.0;
constexpr Eigen::Index kSamples = 20000;
constexpr double kSd = 0.01;

/// One case at rest (|a| = 1 g) for the first half, on a 5 g vibration for the second half.
dataset::Dataset one_case() {
  dataset::Dataset d;
  dataset::CaseData c;
  c.name = "case";
  c.sample_period_s = 1.0 / kFs;
  c.t = Eigen::VectorXd::LinSpaced(kSamples, 0.0, double(kSamples - 1) / kFs);
  c.a_e = Eigen::MatrixXd::Zero(kSamples, 3);
  for (Eigen::Index k = 0; k < kSamples; ++k) c.a_e(k, 2) = (k < kSamples / 2 ? 1.0 : 5.0) * 9.80665;
  c.y = Eigen::VectorXd::Zero(kSamples);
  d.cases.push_back(std::move(c));
  return d;
}

Eigen::VectorXd white(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, kSd);
  Eigen::VectorXd e(kSamples);
  for (Eigen::Index k = 0; k < kSamples; ++k) e(k) = g(rng);
  return e;
}

NoiseModel white_model() {
  NoiseModel n;
  n.white_sd = kSd;
  return n;
}

TEST(Location, WhiteNoiseHoldsTheBandTestsSizeAndRatioOne) {
  const dataset::Dataset d = one_case();
  std::mt19937_64 rng(11);
  const int seeds = 200;
  int tests = 0, rejections = 0, family_alarms = 0;
  double worst_z = 0.0;
  for (int s = 0; s < seeds; ++s) {
    const Location loc = locate(d, {{0, 0, white(rng)}}, white_model(), 0.05);
    ASSERT_EQ(loc.bands.size(), 1U);
    bool alarm = false;
    for (const BandTest& b : loc.bands[0].bands) {
      ++tests;
      rejections += b.p_value < 0.05;
      alarm = alarm || b.excess;
      // The ratio is a scaled chi-square / dof: mean 1, sd sqrt(2 / dof).
      worst_z = std::max(worst_z, std::abs(b.ratio - 1.0) / std::sqrt(2.0 / b.dof));
    }
    family_alarms += alarm;
  }
  // Per-band size 0.05: binomial sd sqrt(n p (1-p)); 4 sd either way.
  const double expected = 0.05 * tests, sd = std::sqrt(tests * 0.05 * 0.95);
  EXPECT_NEAR(rejections, expected, 4.0 * sd) << rejections << " of " << tests;
  // Bonferroni keeps the family's false-alarm rate at most alpha.
  EXPECT_LE(family_alarms, 0.05 * seeds + 4.0 * std::sqrt(seeds * 0.05 * 0.95)) << family_alarms;
  // Over ~2000 band statistics the largest deviation of a true chi-square stays below ~4.5 sd.
  EXPECT_LT(worst_z, 5.0);
  std::cout << "[ location ] white noise: " << rejections << " of " << tests << " band tests below p 0.05, " << family_alarms
            << " of " << seeds << " seeds with a Bonferroni excess, largest |ratio - 1| " << worst_z << " sd\n";
}

TEST(Location, ArNoiseIsExplainedByItsModelAndNotByWhiteNoise) {
  const dataset::Dataset d = one_case();
  std::mt19937_64 rng(12);
  // e filtered by 1 / (1 - 0.8 q^-1): a free-run residual of a model with y[k-1] = 0.8.
  const Eigen::VectorXd e = white(rng);
  Eigen::VectorXd r(kSamples);
  r(0) = e(0) / std::sqrt(1.0 - 0.64);   // started stationary
  for (Eigen::Index k = 1; k < kSamples; ++k) r(k) = 0.8 * r(k - 1) + e(k);
  NoiseModel ar = white_model();
  ar.ar = Eigen::VectorXd::Constant(1, 0.8);
  const Location explained = locate(d, {{0, 0, r}}, ar, 0.05);
  for (const BandTest& b : explained.bands[0].bands) EXPECT_FALSE(b.excess) << b.f_lo_hz << ".." << b.f_hi_hz << " ratio " << b.ratio;
  // The AR(1) spectrum is 1 / |1 - 0.8 e^{-jw}|^2: 25 at DC, 1/3.24 at Nyquist. Against a white
  // model with the same innovation sd the low bands are in excess and the top band is not.
  const Location against_white = locate(d, {{0, 0, r}}, white_model(), 0.05);
  const auto& bands = against_white.bands[0].bands;
  EXPECT_TRUE(bands.front().excess);
  EXPECT_GT(bands.front().ratio, 10.0);
  EXPECT_FALSE(bands.back().excess);
  EXPECT_LT(bands.back().ratio, 0.5);
}

/// A record of n samples at kFs of the model's noise, synthesized in the frequency domain: each
/// DFT bin a complex Gaussian of variance S(f) fs n (the white part through C/A, the law beside it).
std::vector<double> synthesize(const NoiseModel& model, Eigen::Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<std::complex<double>> spectrum(static_cast<std::size_t>(n));
  for (Eigen::Index j = 1; j <= n / 2; ++j) {
    const double f = kFs * static_cast<double>(j) / static_cast<double>(n);
    const double two_sided = model.white_sd * model.white_sd * model.gain2(f, kFs) / kFs + 0.5 * model.power_law_psd(f, kFs);
    const double sd = std::sqrt(two_sided * kFs * static_cast<double>(n) / (j == n / 2 ? 1.0 : 2.0));
    const std::complex<double> z = j == n / 2 ? std::complex<double>(sd * g(rng), 0.0) : std::complex<double>(sd * g(rng), sd * g(rng));
    spectrum[static_cast<std::size_t>(j)] = z;
    if (j < n / 2) spectrum[static_cast<std::size_t>(n - j)] = std::conj(z);
  }
  Eigen::FFT<double> fft;
  std::vector<double> series;
  fft.inv(series, spectrum);
  return series;
}

/// White plus flicker plus random walk: flicker above white below ~60 Hz.
NoiseModel power_law_model() {
  NoiseModel model = white_model();
  model.power_law[static_cast<std::size_t>(noise::NoiseTerm::B)] = 3.0 * kSd / std::sqrt(kFs);
  model.power_law[static_cast<std::size_t>(noise::NoiseTerm::K)] = 0.3 * kSd;
  return model;
}

/// White plus flicker plus random walk of known law (synthesize, 2^20 samples) cut into cases of
/// kSamples: against a model with those [noise] terms every band's ratio has mean 1 within its
/// spread and the band and condition-bin tests hold their size; against white noise alone the low
/// bands are excess.
TEST(Location, PowerLawNoiseIsExplainedByItsTermsAndNotByWhiteNoise) {
  const dataset::Dataset d = one_case();
  const NoiseModel model = power_law_model();
  const Eigen::Index n = Eigen::Index{1} << 20;
  const std::vector<double> series = synthesize(model, n, 13);
  const int cases = static_cast<int>(n / kSamples);
  int tests = 0, rejections = 0, white_excess_low = 0, bins = 0, bin_rejections = 0;
  std::vector<double> sum(16, 0.0), sum2(16, 0.0), dof(16, 0.0);
  for (int c = 0; c < cases; ++c) {
    const Eigen::VectorXd r = Eigen::Map<const Eigen::VectorXd>(series.data() + c * kSamples, kSamples);
    const Location loc = locate(d, {{0, 0, r}}, model, 0.05);
    const auto& bands = loc.bands[0].bands;
    for (std::size_t b = 0; b < bands.size(); ++b) {
      ++tests;
      rejections += bands[b].p_value < 0.05;
      sum[b] += bands[b].ratio;
      sum2[b] += bands[b].ratio * bands[b].ratio;
      dof[b] = bands[b].dof;
    }
    // The two |a| bins are the case's contiguous halves: each carries its offset from the case's mean.
    for (const ConditionBin& b : loc.conditions) {
      ++bins;
      bin_rejections += b.p_value < 0.05;
    }
    white_excess_low += locate(d, {{0, 0, r}}, white_model(), 0.05).bands[0].bands.front().excess;
  }
  for (std::size_t b = 0; b < 3; ++b) {
    const double mean = sum[b] / cases, spread = std::sqrt(sum2[b] / cases - mean * mean);
    std::cout << "[ location ] power-law noise, band " << b << ": mean ratio " << mean << ", spread " << spread
              << " (model " << std::sqrt(2.0 / dof[b]) << ") over " << cases << " cases\n";
    // The mean of `cases` ratios, each of sd sqrt(2 / dof): 4 of its sd.
    EXPECT_NEAR(mean, 1.0, 4.0 * std::sqrt(2.0 / dof[b] / cases)) << "band " << b;
  }
  const double expected = 0.05 * tests, sd = std::sqrt(tests * 0.05 * 0.95);
  EXPECT_NEAR(rejections, expected, 4.0 * sd) << rejections << " of " << tests;
  std::cout << "[ location ] power-law noise: condition bins below p 0.05: " << bin_rejections << " of " << bins << '\n';
  EXPECT_NEAR(bin_rejections, 0.05 * bins, 4.0 * std::sqrt(bins * 0.05 * 0.95)) << bin_rejections << " of " << bins;
  EXPECT_EQ(white_excess_low, cases) << "against white noise alone the lowest band must be excess";
}

/// NoiseModel::stretch: the mean and dof of a stretch's sum of squares. Under white noise through
/// an AR(1) the exact Toeplitz forms from its autocovariance sigma^2 a^|d| / (1 - a^2); under the
/// power law (about the stretch's mean) the mean and spread of the sums of squares of 1024
/// stretches of synthesized noise.
TEST(Location, StretchMomentsAreTheToeplitzFormsOfTheModelsNoise) {
  NoiseModel ar = white_model();
  ar.ar = Eigen::VectorXd::Constant(1, 0.8);
  constexpr Eigen::Index kRows = 300;
  Eigen::MatrixXd r(kRows, kRows);
  for (Eigen::Index i = 0; i < kRows; ++i)
    for (Eigen::Index j = 0; j < kRows; ++j) r(i, j) = kSd * kSd * std::pow(0.8, std::abs(i - j)) / (1.0 - 0.64);
  const NoiseModel::StretchMoments m = ar.stretch(kRows, kFs);
  EXPECT_FALSE(m.about_mean);
  EXPECT_NEAR(m.mean_square * kRows, r.trace(), 1e-9 * r.trace());
  const double toeplitz_dof = r.trace() * r.trace() / (r * r).trace();
  EXPECT_NEAR(m.dof, toeplitz_dof, 1e-6 * toeplitz_dof);
  const NoiseModel::StretchMoments white = white_model().stretch(kRows, kFs);
  EXPECT_NEAR(white.mean_square, kSd * kSd, 1e-12);
  EXPECT_NEAR(white.dof, static_cast<double>(kRows), 1e-6);

  // Flicker ten times the power_law_model's: it dominates up to ~1/4 of Nyquist, so the stretch's
  // sum of squares has few dof and the mean taken off matters.
  NoiseModel law = power_law_model();
  law.power_law[static_cast<std::size_t>(noise::NoiseTerm::B)] *= 10.0;
  constexpr Eigen::Index kStretch = 1024, kStretches = 1024;
  const std::vector<double> series = synthesize(law, kStretch * kStretches, 14);
  const NoiseModel::StretchMoments lm = law.stretch(kStretch, kFs);
  ASSERT_TRUE(lm.about_mean);
  double sum = 0.0, sum2 = 0.0;
  for (Eigen::Index s = 0; s < kStretches; ++s) {
    const Eigen::Map<const Eigen::VectorXd> x(series.data() + s * kStretch, kStretch);
    const double ratio = (x.array() - x.mean()).square().sum() / (lm.mean_square * kStretch);
    sum += ratio;
    sum2 += ratio * ratio;
  }
  const double mean = sum / kStretches, spread = std::sqrt(sum2 / kStretches - mean * mean), predicted = std::sqrt(2.0 / lm.dof);
  std::cout << "[ location ] stretch of " << kStretch << " under the law: mean ratio " << mean << ", spread " << spread
            << " (predicted " << predicted << ", dof " << lm.dof << ")\n";
  EXPECT_NEAR(mean, 1.0, 4.0 * predicted / std::sqrt(static_cast<double>(kStretches)));
  // The sample sd of n draws of a scaled chi-square of nu dof (kurtosis 3 + 12 / nu) has a
  // relative sd of sqrt((2 + 12 / nu) / 4n): 4 of those.
  EXPECT_NEAR(spread / predicted, 1.0, 4.0 * std::sqrt((2.0 + 12.0 / lm.dof) / (4.0 * kStretches)));
}

/// A law whose N is 3 % low (the power 6 %) against white noise of 2^20 samples: its top bands
/// have ~10^5 dof, and taken as exact they read as excess. With the law's sd for N stating that
/// uncertainty (3 %), the band test is F-like and holds.
TEST(Location, TheLawsOwnSdKeepsItsEstimationErrorFromReadingAsExcess) {
  constexpr Eigen::Index kLong = Eigen::Index{1} << 20;
  dataset::Dataset d = one_case();
  dataset::CaseData& c = d.cases.front();
  c.t = Eigen::VectorXd::LinSpaced(kLong, 0.0, double(kLong - 1) / kFs);
  c.a_e = Eigen::MatrixXd::Zero(kLong, 3);
  c.a_e.col(2).setConstant(9.80665);
  c.y = Eigen::VectorXd::Zero(kLong);
  std::mt19937_64 rng(15);
  std::normal_distribution<double> g(0.0, kSd);
  Eigen::VectorXd r(kLong);
  for (Eigen::Index k = 0; k < kLong; ++k) r(k) = g(rng);
  NoiseModel law;
  // White noise of sd kSd is N = kSd / sqrt(fs) (one-sided PSD 2 N^2); 3 % below.
  law.power_law[static_cast<std::size_t>(noise::NoiseTerm::N)] = 0.97 * kSd / std::sqrt(kFs);
  const Location exact = locate(d, {{0, 0, r}}, law, 0.05);
  EXPECT_TRUE(exact.bands[0].bands.back().excess) << "ratio " << exact.bands[0].bands.back().ratio;
  law.power_law_sd[static_cast<std::size_t>(noise::NoiseTerm::N)] = 0.03 * kSd / std::sqrt(kFs);
  const Location stated = locate(d, {{0, 0, r}}, law, 0.05);
  for (const BandTest& b : stated.bands[0].bands) {
    EXPECT_FALSE(b.excess) << b.f_lo_hz << ".." << b.f_hi_hz << " ratio " << b.ratio << " p " << b.p_value;
    EXPECT_NEAR(b.reference_dof, 2.0 / std::pow(2.0 * 0.03 / 0.97, 2), 1.0);
  }
}

TEST(Location, ASineIsLocatedInItsBandAndItsCondition) {
  const dataset::Dataset d = one_case();
  std::mt19937_64 rng(13);
  Eigen::VectorXd r = white(rng);
  // 2 sd of sine at 100 Hz, only while the case vibrates at 5 g.
  const double f0 = 100.0;
  for (Eigen::Index k = kSamples / 2; k < kSamples; ++k) r(k) += 2.0 * kSd * std::sin(2.0 * std::numbers::pi * f0 * double(k) / kFs);
  const Location loc = locate(d, {{0, 0, r}}, white_model(), 0.05);
  int flagged = 0;
  for (const BandTest& b : loc.bands[0].bands) {
    const bool holds = b.f_lo_hz <= f0 && f0 < b.f_hi_hz;
    EXPECT_EQ(b.excess, holds) << b.f_lo_hz << ".." << b.f_hi_hz << " ratio " << b.ratio << " p " << b.p_value;
    flagged += b.excess;
  }
  EXPECT_EQ(flagged, 1);
  int bins = 0;
  for (const ConditionBin& c : loc.conditions) {
    if (c.quantity != "|a|") continue;
    ++bins;
    const bool vibrating = c.lo <= 5.0 && 5.0 < c.hi;
    EXPECT_EQ(c.excess, vibrating) << c.lo << ".." << c.hi << " g, ratio " << c.ratio;
    // Where the sine acts the mean square is (1 + 2^2 / 2) sd^2 = 3 sd^2; per sample r^2 has
    // variance 2 sd^4 + 4 sd^2 (2^2 sd^2 / 2) = 10 sd^4, so the RMS ratio sqrt(3) has sd
    // sqrt(10 / n) / (2 sqrt(3)) over the bin's n samples. 4 sd.
    if (vibrating) {
      const double n = double(c.samples);
      EXPECT_NEAR(c.ratio, std::sqrt(3.0), 4.0 * std::sqrt(10.0 / n) / (2.0 * std::sqrt(3.0)));
    }
  }
  EXPECT_EQ(bins, 2);
}

}  // namespace
}  // namespace inertia::diagnose

