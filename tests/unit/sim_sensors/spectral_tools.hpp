#pragma once
// Independent measuring tools for the sensor-model tests: Welch PSD, log-log slope fit, sinusoid
// fit, statistics over independent seeds. They use only Eigen (FFT from Eigen's unsupported
// module, i.e. kissfft) and never the code under test.
#include <Eigen/Dense>
#include <cmath>
#include <complex>
#include <cstddef>
#include <functional>
#include <numbers>
#include <unsupported/Eigen/FFT>
#include <vector>

namespace inertia::sim::test {

struct Psd {
  std::vector<double> freq_hz;
  std::vector<double> density;   // one-sided, unit^2/Hz
};

/// Welch: non-overlapping Hann-windowed segments, each with its least-squares line removed (a
/// random walk is not stationary; the line keeps its huge lowest-frequency content from leaking),
/// periodograms averaged.
inline Psd welch(const std::vector<double>& x, std::size_t segment, double fs) {
  Eigen::FFT<double> fft;
  std::vector<double> window(segment), buf(segment);
  double wsum2 = 0.0;
  for (std::size_t i = 0; i < segment; ++i) {
    window[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(segment));
    wsum2 += window[i] * window[i];
  }
  Psd psd;
  psd.density.assign(segment / 2 + 1, 0.0);
  std::vector<std::complex<double>> spectrum;
  const std::size_t count = x.size() / segment;
  const double n = static_cast<double>(segment);
  for (std::size_t s = 0; s < count; ++s) {
    const double* seg = x.data() + s * segment;
    // Line fit y = c0 + c1 t with t centred (closed form).
    double mean = 0.0, tm = (n - 1.0) / 2.0, sty = 0.0, stt = 0.0;
    for (std::size_t i = 0; i < segment; ++i) mean += seg[i];
    mean /= n;
    for (std::size_t i = 0; i < segment; ++i) {
      const double t = static_cast<double>(i) - tm;
      sty += t * (seg[i] - mean);
      stt += t * t;
    }
    const double slope = sty / stt;
    for (std::size_t i = 0; i < segment; ++i)
      buf[i] = (seg[i] - mean - slope * (static_cast<double>(i) - tm)) * window[i];
    fft.fwd(spectrum, buf);
    for (std::size_t k = 0; k <= segment / 2; ++k) psd.density[k] += std::norm(spectrum[k]);
  }
  psd.freq_hz.resize(segment / 2 + 1);
  for (std::size_t k = 0; k <= segment / 2; ++k) {
    psd.freq_hz[k] = static_cast<double>(k) * fs / n;
    const double one_sided = (k == 0 || k == segment / 2) ? 1.0 : 2.0;
    psd.density[k] *= one_sided / (fs * wsum2 * static_cast<double>(count));
  }
  return psd;
}

struct SlopeFit {
  double slope = 0.0;
  double slope_se = 0.0;   // from the scatter of the band averages about the line
  int bands = 0;
};

/// Slope of log10(PSD) against log10(f) over [f_lo, f_hi]: the bins are first averaged in bands
/// of equal width in log frequency (bands_per_decade), then a straight line is fitted.
inline SlopeFit loglog_slope(const Psd& psd, double f_lo, double f_hi, int bands_per_decade) {
  const double decades = std::log10(f_hi / f_lo);
  const int bands = static_cast<int>(std::round(decades * bands_per_decade));
  std::vector<double> lx, ly;
  for (int b = 0; b < bands; ++b) {
    const double lo = f_lo * std::pow(10.0, static_cast<double>(b) / bands_per_decade);
    const double hi = f_lo * std::pow(10.0, static_cast<double>(b + 1) / bands_per_decade);
    double sum_p = 0.0, sum_lf = 0.0;
    int n = 0;
    for (std::size_t k = 1; k < psd.freq_hz.size(); ++k) {
      if (psd.freq_hz[k] >= lo && psd.freq_hz[k] < hi) {
        sum_p += psd.density[k];
        sum_lf += std::log10(psd.freq_hz[k]);
        ++n;
      }
    }
    if (n == 0) continue;
    lx.push_back(sum_lf / n);
    ly.push_back(std::log10(sum_p / n));
  }
  const std::size_t m = lx.size();
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < m; ++i) { mx += lx[i]; my += ly[i]; }
  mx /= static_cast<double>(m);
  my /= static_cast<double>(m);
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < m; ++i) { sxx += (lx[i] - mx) * (lx[i] - mx); sxy += (lx[i] - mx) * (ly[i] - my); }
  SlopeFit fit;
  fit.slope = sxy / sxx;
  double rss = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const double r = ly[i] - my - fit.slope * (lx[i] - mx);
    rss += r * r;
  }
  fit.slope_se = std::sqrt(rss / static_cast<double>(m - 2) / sxx);
  fit.bands = static_cast<int>(m);
  return fit;
}

/// Amplitude of the component at omega (rad/s) of x(t_k), t_k = k / fs, by least squares on
/// [sin, cos, 1].
inline double sine_amplitude(const std::vector<double>& x, double omega, double fs) {
  Eigen::MatrixXd phi(static_cast<Eigen::Index>(x.size()), 3);
  Eigen::VectorXd y(static_cast<Eigen::Index>(x.size()));
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double t = static_cast<double>(k) / fs;
    const auto r = static_cast<Eigen::Index>(k);
    phi(r, 0) = std::sin(omega * t);
    phi(r, 1) = std::cos(omega * t);
    phi(r, 2) = 1.0;
    y(r) = x[k];
  }
  const Eigen::Vector3d c = phi.colPivHouseholderQr().solve(y);
  return std::hypot(c(0), c(1));
}

struct MeanSe {
  double mean = 0.0;
  double se = 0.0;
};

/// Mean and standard error of a statistic computed once per independent seed 1..seeds.
inline MeanSe over_seeds(int seeds, const std::function<double(std::uint64_t)>& statistic) {
  std::vector<double> v;
  for (int s = 1; s <= seeds; ++s) v.push_back(statistic(static_cast<std::uint64_t>(s) * 7919u));
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double var = 0.0;
  for (double x : v) var += (x - mean) * (x - mean);
  var /= static_cast<double>(v.size() - 1);
  return {mean, std::sqrt(var / static_cast<double>(v.size()))};
}

/// Sample autocorrelation at `lag` about the known mean 0.
inline double autocorrelation(const std::vector<double>& x, std::size_t lag) {
  double c0 = 0.0, cl = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) c0 += x[i] * x[i];
  for (std::size_t i = lag; i < x.size(); ++i) cl += x[i] * x[i - lag];
  return cl / c0;
}

inline double mean_square(const std::vector<double>& x) {
  double s = 0.0;
  for (double v : x) s += v * v;
  return s / static_cast<double>(x.size());
}

}  // namespace inertia::sim::test
