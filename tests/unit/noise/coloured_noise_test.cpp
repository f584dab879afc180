// The coloured noise of a residual and its sandwich (analyzer/noise/coloured_noise.hpp): the
// frequency-domain quadratic form against the Toeplitz one written out, and the coefficients' sd
// of a least-squares fit under white plus 1/f noise against their spread over seeds.
#include "analyzer/noise/coloured_noise.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "hal/sim/sensors/gaussian_source.hpp"
#include "hal/sim/sensors/pink_noise.hpp"

namespace inertia::noise {
namespace {

/// AR(1) e_k = phi e_{k-1} + w_k, var(w) = s2: two-sided S(f) = s2 / |1 - phi e^{-2 pi i f}|^2,
/// r(tau) = s2 phi^|tau| / (1 - phi^2).
double ar1_density(double f, double phi, double s2) {
  return s2 / (1.0 - 2.0 * phi * std::cos(2.0 * std::numbers::pi * f) + phi * phi);
}

/// A seed's z-scores of coefficients 1 and 2 of a least-squares fit, under the sandwich and the
/// classical covariance, appended per coefficient.
void add_z(const Eigen::Vector3d& estimate, const Eigen::Vector3d& theta, const Eigen::Matrix3d& sandwich,
           const Eigen::Matrix3d& classical, std::vector<double> (&z_sandwich)[2], std::vector<double> (&z_classical)[2]) {
  for (int j = 1; j <= 2; ++j) {
    z_sandwich[j - 1].push_back((estimate(j) - theta(j)) / std::sqrt(sandwich(j, j)));
    z_classical[j - 1].push_back((estimate(j) - theta(j)) / std::sqrt(classical(j, j)));
  }
}

/// The sample standard deviation of z.
double sd_of(const std::vector<double>& z) {
  double m = 0.0, v = 0.0;
  for (double e : z) m += e / double(z.size());
  for (double e : z) v += (e - m) * (e - m) / double(z.size() - 1);
  return std::sqrt(v);
}

TEST(ColouredNoise, QuadraticFormEqualsTheToeplitzForm) {
  const double phi = 0.9, s2 = 0.3;
  const Eigen::Index n = 300;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd x(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) x.row(k) << 1.0, std::sin(0.05 * double(k)), normal(rng);
  const SegmentSpectrum spectrum = spectrum_of(n, [&](double f) { return ar1_density(f, phi, s2); });
  Eigen::MatrixXd r(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) r(a, b) = s2 * std::pow(phi, double(std::abs(a - b))) / (1.0 - phi * phi);
  const Eigen::MatrixXd direct = x.transpose() * r * x;
  const Eigen::MatrixXd by_fft = quadratic_form(spectrum, x);
  // The circulant of length L >= 2n differs from the Toeplitz by phi^(L-n), nothing at double precision.
  EXPECT_LT((by_fft - direct).norm(), 1e-10 * direct.norm()) << by_fft << "\n" << direct;
  for (Eigen::Index tau : {0, 1, 10, 100})
    EXPECT_NEAR(spectrum.autocovariance(tau), r(0, tau), 1e-10 * r(0, 0)) << tau;
}

TEST(ColouredNoise, CovarianceTimesEqualsTheToeplitzProduct) {
  // As above: the circulant's wrap-around, phi^(L-n) = 0.9^724, is nothing at double precision.
  const double phi = 0.9, s2 = 0.7;
  const Eigen::Index n = 300;
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 3);
  const SegmentSpectrum spectrum = spectrum_of(n, [&](double f) { return ar1_density(f, phi, s2); });
  Eigen::MatrixXd r(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) r(a, b) = s2 * std::pow(phi, double(std::abs(a - b))) / (1.0 - phi * phi);
  const Eigen::MatrixXd direct = r * x;
  EXPECT_LT((covariance_times(spectrum, x) - direct).norm(), 1e-10 * direct.norm());
  EXPECT_LT((x.transpose() * covariance_times(spectrum, x) - quadratic_form(spectrum, x)).norm(), 1e-10 * direct.norm());
}

// R x is taken through a circulant shorter than the density's transform that embeds R, the
// Toeplitz matrix of the lags the spectrum states, exactly: under a long memory (r falls by e in
// 1000 lags, longer than the record) a circulant of the density sampled on the shorter length
// would differ from R by r's wrap-around, of R's own size.
TEST(ColouredNoise, ProductsThroughTheShortCirculantAreTheToeplitzOfTheStatedLags) {
  const double phi = 0.999, s2 = 0.4;
  const Eigen::Index n = 300;
  const SegmentSpectrum spectrum = spectrum_of(n, [&](double f) { return ar1_density(f, phi, s2); });
  ASSERT_GE(spectrum.circulant_length, 2 * n - 1);
  ASSERT_LT(spectrum.circulant_length, spectrum.length);
  ASSERT_EQ(spectrum.circulant.size(), spectrum.circulant_length / 2 + 1);
  Eigen::MatrixXd r(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) r(a, b) = spectrum.autocovariance(std::abs(a - b));
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 4);
  const Eigen::MatrixXd direct = r * x;
  EXPECT_LT((covariance_times(spectrum, x) - direct).norm(), 1e-12 * direct.norm());
  const Eigen::MatrixXd form = x.transpose() * direct;
  EXPECT_LT((quadratic_form(spectrum, x) - form).norm(), 1e-12 * form.norm());
}

// Some columns of x, in any order, without a copy: the rows and columns of the whole form.
TEST(ColouredNoise, QuadraticFormOfSomeColumnsIsThatPartOfTheWholeForm) {
  const Eigen::Index n = 500;
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 7);
  const SegmentSpectrum spectrum = spectrum_of(n, [&](double f) { return ar1_density(f, 0.8, 0.5); });
  const Eigen::MatrixXd whole = quadratic_form(spectrum, x);
  const std::vector<Eigen::Index> some{5, 0, 3, 6, 1};
  const Eigen::MatrixXd part = quadratic_form(spectrum, x, some);
  ASSERT_EQ(part.rows(), 5);
  for (std::size_t a = 0; a < some.size(); ++a)
    for (std::size_t b = 0; b < some.size(); ++b)
      EXPECT_NEAR(part(Eigen::Index(a), Eigen::Index(b)), whole(some[a], some[b]), 1e-12 * whole.norm()) << a << " " << b;
  const std::vector<Eigen::Index> beyond{1, 7};
  EXPECT_THROW((void)quadratic_form(spectrum, x, beyond), std::invalid_argument);
}

TEST(ColouredNoise, GroupSumsEqualTheToeplitzFormOfTheIndicators) {
  // A long memory (phi 0.999: r falls by e in 1000 lags) makes every block's sum large against
  // its neighbours', where the running sums' differences lose most digits. Groups split into
  // several runs and a one-row group exercise the runs.
  const double phi = 0.999, s2 = 0.7;
  const Eigen::Index n = 1500;
  const SegmentSpectrum spectrum = spectrum_of(n, [&](double f) { return ar1_density(f, phi, s2); });
  RowGroups rows;
  rows.groups = 4;
  rows.group.resize(std::size_t(n));
  for (Eigen::Index k = 0; k < n; ++k) rows.group[std::size_t(k)] = k < 400 || k >= 1300 ? 0 : k < 700 ? 1 : 2;
  rows.group[900] = 3;
  Eigen::MatrixXd z = Eigen::MatrixXd::Zero(n, rows.groups);
  for (Eigen::Index k = 0; k < n; ++k) z(k, rows.group[std::size_t(k)]) = 1.0;
  Eigen::MatrixXd r(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) r(a, b) = spectrum.autocovariance(std::abs(a - b));
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 3);
  const Eigen::MatrixXd zrz = z.transpose() * r * z, xrz = x.transpose() * r * z;
  const Eigen::MatrixXd by_sums = group_covariance(spectrum, rows), cross_by_sums = group_cross_covariance(spectrum, rows, x);
  for (Eigen::Index g = 0; g < rows.groups; ++g) {
    for (Eigen::Index h = 0; h < rows.groups; ++h)
      EXPECT_NEAR(by_sums(g, h), zrz(g, h), 1e-12 * std::sqrt(zrz(g, g) * zrz(h, h))) << g << " " << h;
    for (Eigen::Index j = 0; j < x.cols(); ++j)
      EXPECT_NEAR(cross_by_sums(j, g), xrz(j, g), 1e-12 * std::sqrt((x.col(j).transpose() * r * x.col(j)).value() * zrz(g, g)))
          << j << " " << g;
  }
  // Columns held apart, [X W]'RZ in one pass: the rows of each.
  const Eigen::MatrixXd w = Eigen::MatrixXd::Random(n, 2);
  const Eigen::MatrixXd both = group_cross_covariance(spectrum, rows, x, w);
  ASSERT_EQ(both.rows(), 5);
  EXPECT_EQ(Eigen::MatrixXd(both.topRows(3)), cross_by_sums);
  EXPECT_EQ(Eigen::MatrixXd(both.bottomRows(2)), group_cross_covariance(spectrum, rows, w));
  // A row's group out of range is refused.
  rows.group[3] = 4;
  EXPECT_THROW((void)group_covariance(spectrum, rows), std::invalid_argument);
}

/// What is known of the noise below one cycle per record from elsewhere (the plan's static
/// stretches) replaces the white part there, and only there; where it is lower the white part stays.
TEST(ColouredNoise, BelowTheRecordsLowestFrequencyTheKnownLawHolds) {
  const Eigen::Index n = 4096;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  Eigen::VectorXd residual(n);
  for (Eigen::Index k = 0; k < n; ++k) residual(k) = 2.0 * normal(rng);
  const SegmentSpectrum white = fitted_spectrum(residual);
  const SegmentSpectrum held = fitted_spectrum(residual, [](double) { return 40.0; });
  const SegmentSpectrum lower = fitted_spectrum(residual, [](double) { return 1e-3; });
  const Eigen::Index below = held.length / n;   // bins k / L < 1 / n
  for (Eigen::Index k = 0; k <= held.length / 2; ++k) {
    if (k < below) {
      EXPECT_DOUBLE_EQ(held.density(k), 40.0) << k;
    } else {
      EXPECT_DOUBLE_EQ(held.density(k), white.density(k)) << k;
    }
    EXPECT_DOUBLE_EQ(lower.density(k), white.density(k)) << k;
  }
  EXPECT_NEAR(white.density(0), 4.0, 0.5);   // the white part: the mean square, two-sided per sample
}

TEST(ColouredNoise, WhiteSpectrumGivesTheClassicalForm) {
  const Eigen::Index n = 257;
  const Eigen::MatrixXd x = Eigen::MatrixXd::Random(n, 4);
  const SegmentSpectrum spectrum = spectrum_of(n, [](double) { return 2.5; });
  EXPECT_LT((quadratic_form(spectrum, x) - 2.5 * x.transpose() * x).norm(), 1e-10 * (x.transpose() * x).norm());
}

/// A least-squares fit of a slow and a fast sine (and a mean) under white plus 1/f noise: the
/// classical sd takes the 1/f power at the slow sine's frequency as white and is optimistic; the
/// sandwich with the residual's fitted spectrum matches the spread over seeds (the target:
/// z-scores with an sd within [0.8, 1.25]). The mean is not scored: what lies below the record's
/// lowest frequency is the offsets between cases (cluster_offsets), not one record's business.
TEST(ColouredNoise, SandwichSdMatchesTheSpreadUnderFlickerNoise) {
  constexpr int kSeeds = 60;
  const double fs = 100.0;
  const Eigen::Index n = 1 << 14;
  Eigen::MatrixXd x(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = double(k) / fs;
    x.row(k) << 1.0, std::sin(2.0 * std::numbers::pi * 0.05 * t), std::sin(2.0 * std::numbers::pi * 11.0 * t);
  }
  const Eigen::Vector3d theta(0.2, 1.0, -0.5);
  const Eigen::MatrixXd xx_inverse = (x.transpose() * x).inverse();
  std::vector<double> z_sandwich[2], z_classical[2];
  for (int seed = 0; seed < kSeeds; ++seed) {
    sim::GaussianSource white(900 + std::uint64_t(seed), 1);
    sim::PinkNoise pink(0.05, 1e-3, fs, 900 + std::uint64_t(seed), 2);
    Eigen::VectorXd y = x * theta;
    for (Eigen::Index k = 0; k < n; ++k) y(k) += 0.01 * white.next() + pink.next();
    const Eigen::Vector3d estimate = xx_inverse * (x.transpose() * y);
    const Eigen::VectorXd residual = y - x * estimate;
    const double s2 = residual.squaredNorm() / double(n - 3);
    const Eigen::Matrix3d sandwich = xx_inverse * quadratic_form(fitted_spectrum(residual), x) * xx_inverse;
    add_z(estimate, theta, sandwich, s2 * xx_inverse, z_sandwich, z_classical);
  }
  const auto sd = sd_of;
  const char* names[2] = {"slow sine (0.05 Hz)", "fast sine (11 Hz)"};
  for (int j = 0; j < 2; ++j) {
    std::printf("%s: z sd over %d seeds: sandwich %.2f, classical %.2f\n", names[j], kSeeds, sd(z_sandwich[j]), sd(z_classical[j]));
    // 60 seeds: the sd of z's sd is about 1/sqrt(2 * 59) = 0.09, so [0.8, 1.25] is 2.2 to 2.7 of it.
    EXPECT_GT(sd(z_sandwich[j]), 0.8) << names[j];
    EXPECT_LT(sd(z_sandwich[j]), 1.25) << names[j];
  }
  // The slow sine is where the 1/f power is: the classical sd is optimistic there.
  EXPECT_GT(sd(z_classical[0]), 1.5);
}

/// The density through the AR model on every bin is the innovation's over |A(e^{2 pi i f})|^2 of
/// the polynomial itself, also for a model longer than the padded transform (its coefficients fold).
TEST(ColouredNoise, SpectrumThroughTheArModelIsTheDensityOverThePolynomialsGainOnEveryBin) {
  sim::GaussianSource white(77, 1);
  for (const Eigen::Index rows : {Eigen::Index{3}, Eigen::Index{50}}) {
    Eigen::VectorXd innovation(rows);
    for (Eigen::Index k = 0; k < rows; ++k) innovation(k) = white.next();
    const Eigen::VectorXd ar = (Eigen::VectorXd(9) << 0.5, -0.2, 0.1, 0.05, -0.03, 0.02, 0.01, -0.01, 0.005).finished();
    const SegmentSpectrum through = fitted_spectrum_through_ar(innovation, ar, rows);
    const FittedDensity fitted = fitted_density(innovation);
    ASSERT_EQ(through.density.size(), through.length / 2 + 1);
    for (Eigen::Index k = 0; k <= through.length / 2; ++k) {
      const double f = static_cast<double>(k) / static_cast<double>(through.length);
      std::complex<double> a = 1.0;
      for (Eigen::Index j = 1; j <= ar.size(); ++j) a -= ar(j - 1) * std::polar(1.0, -2.0 * std::numbers::pi * f * static_cast<double>(j));
      const double direct = fitted.density(f) / std::norm(a);
      EXPECT_NEAR(through.density(k), direct, 1e-12 * direct) << "rows " << rows << ", bin " << k << " of " << through.length;
    }
  }
}

/// Rows kept unfiltered under AR(1) noise (phi 0.9): the innovation's fitted spectrum through the
/// AR model is the noise's own, and the sandwich with it gives the least-squares fit's sd, where
/// the classical form is optimistic by the noise's long-run factor (1 + phi) / (1 - phi) = 19 at
/// the slow sine.
TEST(ColouredNoise, SpectrumThroughTheArModelGivesTheSdOfUnfilteredRows) {
  constexpr int kSeeds = 60;
  const double phi = 0.9;
  const Eigen::Index n = 1 << 13;
  Eigen::MatrixXd x(n, 3);
  for (Eigen::Index k = 0; k < n; ++k)
    x.row(k) << 1.0, std::sin(2.0 * std::numbers::pi * 2e-3 * double(k)), std::sin(2.0 * std::numbers::pi * 0.21 * double(k));
  const Eigen::Vector3d theta(0.2, 1.0, -0.5);
  const Eigen::MatrixXd xx_inverse = (x.transpose() * x).inverse();
  std::vector<double> z_sandwich[2], z_classical[2];
  for (int seed = 0; seed < kSeeds; ++seed) {
    sim::GaussianSource white(500 + std::uint64_t(seed), 1);
    Eigen::VectorXd y = x * theta;
    double e = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) y(k) += (e = phi * e + 0.1 * white.next());
    const Eigen::Vector3d estimate = xx_inverse * (x.transpose() * y);
    const Eigen::VectorXd residual = y - x * estimate;
    // The AR(1) model from the residual's lag-1 autocorrelation, and the residual through it.
    const Eigen::VectorXd ar = Eigen::VectorXd::Constant(1, residual.head(n - 1).dot(residual.tail(n - 1)) / residual.squaredNorm());
    const Eigen::VectorXd innovation = residual.tail(n - 1) - ar(0) * residual.head(n - 1);
    const SegmentSpectrum spectrum = fitted_spectrum_through_ar(innovation, ar, n);
    if (seed == 0) {
      // Its autocovariance is the AR(1)'s, 0.01 phi^tau / (1 - phi^2), within the fit's scatter.
      for (Eigen::Index tau : {0, 1, 10, 40})
        EXPECT_NEAR(spectrum.autocovariance(tau), 0.01 * std::pow(phi, double(tau)) / (1.0 - phi * phi), 0.1 * 0.01 / (1.0 - phi * phi)) << tau;
    }
    const Eigen::Matrix3d sandwich = xx_inverse * quadratic_form(spectrum, x) * xx_inverse;
    const double s2 = residual.squaredNorm() / double(n - 3);
    add_z(estimate, theta, sandwich, s2 * xx_inverse, z_sandwich, z_classical);
  }
  const auto sd = sd_of;
  const char* names[2] = {"slow sine", "fast sine"};
  for (int j = 0; j < 2; ++j) {
    std::printf("%s: z sd over %d seeds: through the AR model %.2f, classical %.2f\n", names[j], kSeeds, sd(z_sandwich[j]),
                sd(z_classical[j]));
    // As above: the sd of z's sd over 60 seeds is about 0.09.
    EXPECT_GT(sd(z_sandwich[j]), 0.8) << names[j];
    EXPECT_LT(sd(z_sandwich[j]), 1.25) << names[j];
  }
  EXPECT_GT(sd(z_classical[0]), 3.0);   // sqrt(19) = 4.4 where the noise's memory is short against the sine
}

}  // namespace
}  // namespace inertia::noise
