#include "analyzer/diagnose/location.hpp"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <fmt/format.h>
#include <Spectra/SymEigsSolver.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <map>
#include <numbers>

#include "analyzer/ident/statistics.hpp"
#include "analyzer/noise/fourier.hpp"
#include "common/units.hpp"

namespace inertia::diagnose {
namespace {

using Eigen::Index;
using Complex = std::complex<double>;

/// P(F(d1, d2) > ratio).
double f_upper(double d1, double d2, double ratio) {
  if (!(d1 > 0.0) || !(d2 > 0.0)) return 1.0;
  return boost::math::cdf(boost::math::complement(boost::math::fisher_f(d1, d2), std::max(ratio, 0.0)));
}

double chi2_upper(double dof, double stat) {
  if (!(dof > 0.0) || !std::isfinite(stat)) return 1.0;
  return boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), std::max(stat, 0.0)));
}

/// Periodic Hann window: its squared DFT is nonzero at 0 and +-1, +-2 bins only, so the
/// periodogram's bin correlations below are short.
Eigen::VectorXd hann(Index n) {
  Eigen::VectorXd w(n);
  for (Index k = 0; k < n; ++k) w(k) = 0.5 * (1.0 - std::cos(2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n)));
  return w;
}

/// Correlations of the windowed DFT of white noise, relative to E|X_k|^2, for bin offsets
/// d = -D..D: within one segment (gap 0) and between segments half a window apart (gap 1):
///   rho_g(d) = |sum_n w(n) w(n + g L/2) exp(-i 2 pi d n / L)| / sum_n w(n)^2.
/// Cov(|X_k|^2, |X'_m|^2) = E^2 (rho(k - m)^2 + rho(k + m)^2) for Gaussian data (the second,
/// the pseudo-covariance, matters only near 0 and Nyquist).
struct WindowCorrelation {
  static constexpr int kSpan = 8;   // beyond it |rho| < 1e-3 for gap 1 and exactly 0 for gap 0
  Index length = 0;
  std::array<std::array<double, 2 * kSpan + 1>, 2> rho{};

  explicit WindowCorrelation(const Eigen::VectorXd& w) : length(w.size()) {
    const Index n = w.size();
    const double energy = w.squaredNorm();
    for (int gap = 0; gap < 2; ++gap) {
      const Index shift = gap * n / 2;
      for (int d = -kSpan; d <= kSpan; ++d) {
        Complex acc = 0.0;
        for (Index k = 0; k + shift < n; ++k) {
          const double phase = -2.0 * std::numbers::pi * d * static_cast<double>(k) / static_cast<double>(n);
          acc += w(k) * w(k + shift) * Complex(std::cos(phase), std::sin(phase));
        }
        rho[static_cast<std::size_t>(gap)][static_cast<std::size_t>(d + kSpan)] = std::abs(acc) / energy;
      }
    }
  }
  /// rho_gap(d) with d taken modulo the window length.
  [[nodiscard]] double at(int gap, Index d) const {
    d %= length;
    if (d > length / 2) d -= length;
    if (d < -length / 2) d += length;
    if (std::abs(d) > kSpan) return 0.0;
    return rho[static_cast<std::size_t>(gap)][static_cast<std::size_t>(d + kSpan)];
  }
  /// Sum over bin pairs k, m in [lo, hi) of rho_gap(k - m)^2 + rho_gap(k + m)^2.
  [[nodiscard]] double pair_sum(int gap, Index lo, Index hi) const {
    double s = 0.0;
    for (Index k = lo; k < hi; ++k) {
      for (Index m = std::max(lo, k - kSpan); m < std::min(hi, k + kSpan + 1); ++m) s += std::pow(at(gap, k - m), 2);
      for (int e = -kSpan; e <= kSpan; ++e) {
        for (Index m : {e - k, length + e - k}) {
          if (m >= lo && m < hi) s += std::pow(at(gap, k + m), 2);
        }
      }
    }
    return s;
  }
};

/// The Welch segment length for n samples: at least ~7 half-overlapping segments (dof), at most
/// 2^15 points (resolution far below any band we report).
Index welch_length(Index n) {
  Index length = 16;
  while (length * 2 <= n / 4 && length < (Index{1} << 15)) length *= 2;
  return length;
}

/// Octave bands of the bins of an L-point grid: [0, 2), [2, 4), ..., [L/4, L/2 + 1).
std::vector<std::pair<Index, Index>> octave_bands(Index length) {
  std::vector<std::pair<Index, Index>> b;
  for (Index lo = 0, hi = 2; lo < length / 2; lo = hi, hi *= 2) b.emplace_back(lo, hi >= length / 2 ? length / 2 + 1 : hi);
  return b;
}

/// Variance of a band's statistic sum_{s,k} |X_sk|^2 / E_k for the lowest bins under a model with
/// slow noise: the white formula (WindowCorrelation) takes segments more than half a window apart
/// as independent, which 1/f noise is not at the lowest bins, and so understates the lowest band's
/// spread (docs/validation.md, 'Evidence behind choices in the code'). For Gaussian noise,
///   Var = sum_d (K - |d|) sum_{k,m} (|E X_{s,k} X*_{s+d,m}|^2 + |E X_{s,k} X_{s+d,m}|^2) / (E_k E_m),
/// each expectation the integral of the whole model's two-sided PSD against the bins' kernels C_k,
/// shifted by d hops: on the fine grid, one inverse DFT per pair of bins gives every shift. The
/// grid's period (8 windows) bounds the shifts taken: segments further apart count as independent.
double low_band_variance(const std::vector<std::vector<Complex>>& responses, Index lo, Index hi,
                         const Eigen::VectorXd& expected, Index segments, Index hop, double fs, const NoiseModel& noise) {
  const auto grid = static_cast<Index>(responses.front().size());
  const Index length = grid / 8;
  const double bin_hz = fs / static_cast<double>(length);
  const double sigma2 = noise.white_sd * noise.white_sd;
  std::vector<double> psd(static_cast<std::size_t>(grid), 0.0);
  for (Index j = 1; j < grid; ++j) {   // f = 0 carries nothing: the detrended kernels vanish there
    const double f = std::abs(bin_hz * static_cast<double>(j <= grid / 2 ? j : j - grid) / 8.0);
    psd[static_cast<std::size_t>(j)] = sigma2 * noise.gain2(f, fs) / fs + 0.5 * noise.power_law_psd(f, fs);
  }
  const double scale = fs / static_cast<double>(grid);
  noise::ComplexFourier cov_fourier(grid), pseudo_fourier(grid);
  double variance = 0.0;
  for (Index k = lo; k < hi; ++k) {
    for (Index m = lo; m < hi; ++m) {
      const auto& ck = responses[static_cast<std::size_t>(k)];
      const auto& cm = responses[static_cast<std::size_t>(m)];
      auto product = cov_fourier.values();
      auto pseudo_product = pseudo_fourier.values();
      for (Index j = 0; j < grid; ++j) {
        const auto at = static_cast<std::size_t>(j);
        product(j) = psd[at] * ck[at] * std::conj(cm[at]);
        pseudo_product(j) = psd[at] * ck[at] * cm[static_cast<std::size_t>((grid - j) % grid)];
      }
      cov_fourier.inverse();   // sum_j P_j e^{i 2 pi j D / grid} / grid
      pseudo_fourier.inverse();
      const auto cov = cov_fourier.values();
      const auto pseudo = pseudo_fourier.values();
      for (Index d = -(segments - 1); d < segments; ++d) {
        const Index shift = d * hop;
        if (std::abs(shift) >= grid / 2) continue;
        const Index at = (shift + grid) % grid;
        const double g = static_cast<double>(grid) * scale;
        variance += static_cast<double>(segments - std::abs(d)) *
                    (std::norm(cov(at) * g) + std::norm(pseudo(at) * g)) / (expected(k) * expected(m));
      }
    }
  }
  return variance;
}

CaseBands case_bands(const CaseResidual& cr, double fs, const NoiseModel& noise) {
  CaseBands out;
  out.case_index = cr.case_index;
  out.sample_rate_hz = fs;
  const Index n = cr.residual.size();
  if (n < 4 * Index{16}) return out;   // too short a case gets no spectrum
  const Index length = welch_length(n);
  const Index hop = length / 2;
  const Index segments = (n - length) / hop + 1;
  out.segment_length = static_cast<int>(length);
  out.segments = static_cast<int>(segments);
  const Eigen::VectorXd w = hann(length);
  const double w_energy = w.squaredNorm();
  const Index half = length / 2;
  Eigen::VectorXd power = Eigen::VectorXd::Zero(half + 1);   // sum over segments of |X_k|^2
  noise::RealFourier fourier(length);
  // With power-law noise (flicker, random walk) in the model each segment's mean is taken off
  // first (Welch's constant detrend): a segment's mean then carries the noise slower than the
  // whole record, whose expectation 1/f noise leaves undefined (it diverges without a lower
  // edge), while after the detrend every bin's expectation converges. A white model keeps the
  // means: there an offset is excess the model must answer for.
  const bool detrend = noise.has_slow_noise();
  for (Index s = 0; s < segments; ++s) {
    const double mean = detrend ? cr.residual.segment(s * hop, length).mean() : 0.0;
    fourier.samples() = w.array() * (cr.residual.segment(s * hop, length).array() - mean);
    fourier.forward();
    power += fourier.spectrum().cwiseAbs2();
  }
  // Expected |X_k|^2 under the model: sigma^2 |H|^2 sum w^2; one-sided PSD factor 2 / (fs sum w^2).
  // The detrended bin k is sum_n c_n x_n with c_n = w_n e^{-i 2 pi k n / L} - W_k / L (W_k the
  // window's DFT, nonzero at k = 0 and 1 only): white noise gives sigma^2 (sum w^2 - |W_k|^2 / L).
  const double sigma2 = noise.white_sd * noise.white_sd;
  const double window_sum = w.sum();   // W_0; |W_1| = W_0 / 2 for the periodic Hann window
  Eigen::VectorXd expected(half + 1), psd_factor(half + 1);
  for (Index k = 0; k <= half; ++k) {
    const double f = fs * static_cast<double>(k) / static_cast<double>(length);
    const double w_k = k == 0 ? window_sum : k == 1 ? 0.5 * window_sum : 0.0;
    const double energy = detrend ? w_energy - w_k * w_k / static_cast<double>(length) : w_energy;
    expected(k) = sigma2 * noise.gain2(f, fs) * energy;
    psd_factor(k) = (k == 0 || k == half ? 1.0 : 2.0) / (fs * w_energy);
  }
  const WindowCorrelation corr(w);
  constexpr Index kFine = 8, kLobe = 2 * kFine, kFullBins = 8;
  std::vector<std::vector<Complex>> low_responses;   // C_k on the fine grid, the lowest bins
  Index grid = 0;
  if (noise.has_power_law()) {
    // E|sum c_n x_n|^2 = integral of S(f) |C(f)|^2 (S two-sided): on a grid 8 times finer than
    // the bins, from the zero-padded DFT of c (sum |C_m|^2 = 8 L sum |c_n|^2). In full over the
    // band for the lowest bins, where 1/f varies across the kernel and its sidelobes reach DC;
    // from the main lobe (+-2 bins, 99.9 % of the window's energy) above.
    grid = kFine * length;
    const double bin_hz = fs / static_cast<double>(length);
    const auto two_sided = [&](double f) { return 0.5 * noise.power_law_psd(std::abs(f), fs); };
    noise::ComplexFourier fourier_fine(grid);
    auto kernel = fourier_fine.values();   // zero-padded c, then its transform C
    std::vector<Complex> response;
    low_responses.clear();
    for (Index k = 0; k <= half; ++k) {
      if (k < kFullBins) {
        kernel.setZero();
        Complex w_k = 0.0;   // W_k
        for (Index m = 0; m < length; ++m) {
          const double phase = -2.0 * std::numbers::pi * static_cast<double>(k * m) / static_cast<double>(length);
          kernel(m) = w(m) * std::polar(1.0, phase);
          w_k += kernel(m);
        }
        if (detrend) kernel.head(length).array() -= w_k / static_cast<double>(length);
        fourier_fine.forward();
        response.assign(kernel.data(), kernel.data() + grid);
        low_responses.push_back(response);
        double e = 0.0;
        for (Index m = 1; m < grid; ++m) {   // m = 0 is f = 0: the detrended kernel is 0 there
          const double f = bin_hz * static_cast<double>(m <= grid / 2 ? m : m - grid) / static_cast<double>(kFine);
          e += two_sided(f) * std::norm(response[static_cast<std::size_t>(m)]);
        }
        expected(k) += fs * e / static_cast<double>(grid);
      } else {
        if (k == kFullBins) {
          // The window's own spectral main lobe, once.
          kernel.setZero();
          kernel.head(length) = w.cast<Complex>();
          fourier_fine.forward();
          response.assign(kernel.data(), kernel.data() + grid);
        }
        double e = 0.0, lobe = 0.0;
        for (Index m = -kLobe; m <= kLobe; ++m) {
          const double weight = std::norm(response[static_cast<std::size_t>((m + grid) % grid)]);
          e += weight * two_sided(bin_hz * (static_cast<double>(k) + static_cast<double>(m) / kFine));
          lobe += weight;
        }
        expected(k) += fs * w_energy * e / lobe;
      }
    }
  }
  const double kd = static_cast<double>(segments);
  for (const auto& [lo, hi] : octave_bands(length)) {
    BandTest b;
    b.f_lo_hz = fs * static_cast<double>(lo) / static_cast<double>(length);
    b.f_hi_hz = fs * static_cast<double>(std::min(hi, half)) / static_cast<double>(length);
    b.bins = static_cast<int>(hi - lo);
    double q = 0.0, psd = 0.0, model = 0.0;
    for (Index k = lo; k < hi; ++k) {
      q += power(k) / expected(k);
      psd += power(k) / kd * psd_factor(k);
      model += expected(k) * psd_factor(k);
    }
    const double mean = kd * static_cast<double>(hi - lo);
    const double variance = hi <= static_cast<Index>(low_responses.size())
                                ? low_band_variance(low_responses, lo, hi, expected, segments, hop, fs, noise)
                                : kd * corr.pair_sum(0, lo, hi) + 2.0 * (kd - 1.0) * corr.pair_sum(1, lo, hi);
    b.residual_psd = psd / static_cast<double>(hi - lo);
    b.model_psd = model / static_cast<double>(hi - lo);
    b.ratio = q / mean;
    b.dof = 2.0 * mean * mean / variance;
    // The expected power is itself an estimate where the law's terms carry their sd: the ratio is
    // then F-like, the band's scaled chi-square over the reference's (its dof 2 / relative
    // variance). Taken as exact, a law's small misfit on many dof reads as excess (sim-thermal's
    // top octave; docs/validation.md, 'Evidence behind choices in the code').
    const double reference = noise.band_relative_variance(b.f_lo_hz, std::max(b.f_hi_hz, b.f_lo_hz * 1.0001), fs);
    b.reference_dof = reference > 0.0 ? 2.0 / reference : 0.0;
    b.p_value = b.reference_dof > 0.0 ? f_upper(b.dof, b.reference_dof, b.ratio) : chi2_upper(b.dof, b.dof * b.ratio);
    out.bands.push_back(b);
  }
  // Plot points: bins averaged over log-spaced groups (~8 per octave).
  std::vector<double> pf, pp, pm;
  for (Index lo = 1; lo <= half;) {
    const Index hi = std::min(half + 1, std::max(lo + 1, static_cast<Index>(std::ceil(static_cast<double>(lo) * 1.09))));
    double p = 0.0, m = 0.0;
    for (Index k = lo; k < hi; ++k) {
      p += power(k) / kd * psd_factor(k);
      m += expected(k) * psd_factor(k);
    }
    const double cnt = static_cast<double>(hi - lo);
    pf.push_back(fs * 0.5 * static_cast<double>(lo + hi - 1) / static_cast<double>(length));
    pp.push_back(p / cnt);
    pm.push_back(m / cnt);
    lo = hi;
  }
  out.plot_f = Eigen::Map<Eigen::VectorXd>(pf.data(), static_cast<Index>(pf.size()));
  out.plot_psd = Eigen::Map<Eigen::VectorXd>(pp.data(), static_cast<Index>(pp.size()));
  out.plot_model = Eigen::Map<Eigen::VectorXd>(pm.data(), static_cast<Index>(pm.size()));
  return out;
}

/// Contiguous excess bands of a case, merged: "20-2500 Hz (power x12)".
std::string band_ranges(const CaseBands& cb) {
  std::string s;
  for (std::size_t i = 0; i < cb.bands.size();) {
    if (!cb.bands[i].excess) {
      ++i;
      continue;
    }
    std::size_t j = i;
    double worst = 0.0;
    while (j < cb.bands.size() && cb.bands[j].excess) worst = std::max(worst, cb.bands[j++].ratio);
    s += fmt::format("{}{:.3g}-{:.3g} Hz (power x{:.3g})", s.empty() ? "" : ", ", cb.bands[i].f_lo_hz,
                     cb.bands[j - 1].f_hi_hz, worst);
    i = j;
  }
  return s;
}

/// Bins of |a| in g: the rest, 1 g, and octaves of vibration level.
constexpr std::array<double, 10> kAccelEdgesG{0.0, 0.5, 1.5, 3.0, 6.0, 12.0, 24.0, 48.0, 96.0, 1e300};
constexpr double kTempBinC = 5.0;
constexpr Index kMinBinSamples = 20;
constexpr std::array<noise::NoiseTerm, 3> kSlowTerms{noise::NoiseTerm::B, noise::NoiseTerm::K, noise::NoiseTerm::R};

}  // namespace

NoiseModel NoiseModel::of(const model::ModelFile& model, double white_sd) {
  NoiseModel n;
  for (std::size_t i = 0; i < model.noise.values.size(); ++i) {
    n.power_law[i] = model.noise.values[i].value_or(0.0);
    n.power_law_sd[i] = model.noise.values[i] ? model.noise.sd[i].value_or(0.0) : 0.0;
  }
  n.white_sd = n.power_law[static_cast<std::size_t>(noise::NoiseTerm::N)] > 0.0 ? 0.0 : white_sd;
  for (const model::ModelTerm& t : model.terms) {
    const auto& f = t.term.factors();
    if (f.size() != 1 || f[0].lag == 0 || f[0].power != 1 || f[0].function != ident::FactorFunction::Plain) continue;
    Eigen::VectorXd* target = f[0].variable == ident::Variable::E   ? &n.ma
                              : f[0].variable == ident::Variable::Y ? &n.ar
                                                                     : nullptr;
    if (target == nullptr) continue;
    if (target->size() < f[0].lag) target->conservativeResizeLike(Eigen::VectorXd::Zero(f[0].lag));
    (*target)(f[0].lag - 1) += t.coefficient;
  }
  return n;
}

double NoiseModel::power_law_psd(double f_hz, double fs_hz) const {
  return has_power_law() ? noise::model_psd(power_law, f_hz, 1.0 / fs_hz) : 0.0;
}

bool NoiseModel::has_power_law() const {
  return std::any_of(power_law.begin(), power_law.end(), [](double v) { return v > 0.0; });
}

bool NoiseModel::has_slow_noise() const {
  return std::any_of(std::begin(kSlowTerms), std::end(kSlowTerms),
                     [&](noise::NoiseTerm t) { return power_law[static_cast<std::size_t>(t)] > 0.0; });
}

bool NoiseModel::has_reference() const { return white_sd > 0.0 || has_power_law(); }

double NoiseModel::band_relative_variance(double f_lo_hz, double f_hi_hz, double fs_hz) const {
  // Each term's PSD is its coefficient squared times a shape: an error d in the coefficient moves
  // its share of the band's power by 2 d / value. The terms' errors are taken as independent
  // (N's and Q's are anticorrelated, so where both matter this is conservative).
  constexpr int kPoints = 32;
  std::array<double, noise::kNoiseTerms> share{};
  double total = 0.0;
  for (int k = 0; k < kPoints; ++k) {
    const double f = std::max(f_lo_hz, 1e-3 * f_hi_hz) * std::pow(f_hi_hz / std::max(f_lo_hz, 1e-3 * f_hi_hz), (k + 0.5) / kPoints);
    total += white_sd * white_sd * gain2(f, fs_hz) * 2.0 / fs_hz;
    for (int t = 0; t < noise::kNoiseTerms; ++t) {
      std::array<double, noise::kNoiseTerms> one{};
      one[static_cast<std::size_t>(t)] = power_law[static_cast<std::size_t>(t)];
      const double psd = noise::model_psd(one, f, 1.0 / fs_hz);
      share[static_cast<std::size_t>(t)] += psd;
      total += psd;
    }
  }
  double variance = 0.0;
  for (std::size_t t = 0; t < share.size(); ++t) {
    if (!(power_law[t] > 0.0) || !(power_law_sd[t] > 0.0) || !(total > 0.0)) continue;
    variance += std::pow(2.0 * share[t] / total * power_law_sd[t] / power_law[t], 2);
  }
  return variance;
}

std::string NoiseModel::describe() const {
  std::string law;
  for (int t = 0; t < noise::kNoiseTerms; ++t) {
    if (power_law[static_cast<std::size_t>(t)] > 0.0)
      law += fmt::format("{}{} {:.3g}", law.empty() ? "" : ", ", noise::noise_term_name(noise::NoiseTerm(t)),
                         power_law[static_cast<std::size_t>(t)]);
  }
  const bool shaped = ma.size() > 0 || ar.size() > 0;
  std::string white = white_sd > 0.0 ? fmt::format("white_sd {:.4g}{}", white_sd,
                                                   shaped ? " through the noise terms e[k-j] and output lags y[k-j]" : "")
                                     : std::string();
  if (law.empty()) return white.empty() ? std::string("none") : white;
  if (white.empty()) return "the [noise] law (" + law + "; white_sd not added: the law's N is the white part)";
  return white + ", with the [noise] law's " + law;
}

double NoiseModel::gain2(double f_hz, double fs_hz) const {
  const double omega = 2.0 * std::numbers::pi * f_hz / fs_hz;
  Complex c = 1.0, a = 1.0;
  for (Index j = 0; j < ma.size(); ++j) c += ma(j) * std::polar(1.0, -omega * static_cast<double>(j + 1));
  for (Index j = 0; j < ar.size(); ++j) a -= ar(j) * std::polar(1.0, -omega * static_cast<double>(j + 1));
  return std::norm(c) / std::norm(a);
}

double NoiseModel::StretchCovariance::operator()(Index i, Index j) const {
  const double r = spectrum.autocovariance(std::abs(i - j));
  if (!about_mean) return r;
  const auto n = static_cast<double>(rows());
  return r - (row_sums(i) + row_sums(j)) / n + total / (n * n);
}

Eigen::VectorXd NoiseModel::StretchCovariance::times(const Eigen::VectorXd& x) const {
  if (!about_mean) return noise::covariance_times(spectrum, x);
  Eigen::VectorXd y = noise::covariance_times(spectrum, x.array() - x.mean());
  y.array() -= y.mean();
  return y;
}

NoiseModel::StretchCovariance NoiseModel::stretch_covariance(Index n, double fs_hz) const {
  StretchCovariance c;
  c.about_mean = has_slow_noise();
  // Two-sided density per sample (the variance is its integral over -1/2 .. 1/2 cycles per sample).
  c.spectrum = noise::spectrum_of(std::max<Index>(n, 1), [&](double f) {
    return white_sd * white_sd * gain2(f * fs_hz, fs_hz) + 0.5 * fs_hz * power_law_psd(f * fs_hz, fs_hz);
  });
  if (c.about_mean) {
    c.row_sums = noise::covariance_times(c.spectrum, Eigen::VectorXd::Ones(c.rows()));
    c.total = c.row_sums.sum();
  }
  return c;
}

namespace {

/// The stretch covariance as Spectra's operator: y = C x.
struct StretchOperator {
  using Scalar = double;
  const NoiseModel::StretchCovariance& covariance;
  [[nodiscard]] Index rows() const { return covariance.rows(); }
  [[nodiscard]] Index cols() const { return covariance.rows(); }
  void perform_op(const double* x_in, double* y_out) const {
    Eigen::Map<Eigen::VectorXd>(y_out, rows()) = covariance.times(Eigen::Map<const Eigen::VectorXd>(x_in, rows()));
  }
};

/// C's largest eigenvalues: all of them below kDenseRows rows, else the kLeading largest by
/// Lanczos (Spectra); none when that does not converge (the law is then the scaled chi-square).
constexpr Index kDenseRows = 160, kLeading = 16, kLanczosBasis = 48;
Eigen::VectorXd leading_eigenvalues(const NoiseModel::StretchCovariance& c) {
  const Index n = c.rows();
  if (n <= kDenseRows) {
    Eigen::MatrixXd m(n, n);
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < n; ++j) m(i, j) = c(i, j);
    const Eigen::VectorXd all = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m, Eigen::EigenvaluesOnly).eigenvalues();
    return all.cwiseMax(0.0);
  }
  StretchOperator op{c};
  Spectra::SymEigsSolver<StretchOperator> eigs(op, kLeading, kLanczosBasis);
  eigs.init();
  eigs.compute(Spectra::SortRule::LargestAlge, 1000, 1e-8);
  if (eigs.info() != Spectra::CompInfo::Successful) return {};
  return eigs.eigenvalues().cwiseMax(0.0);
}

}  // namespace

NoiseModel::StretchMoments NoiseModel::moments(const StretchCovariance& c) {
  // tr(C) and tr(C^2), each in O(n) from the Toeplitz R.
  const Eigen::VectorXd& r = c.spectrum.autocovariance;
  const Index n = c.rows();
  const auto count = static_cast<double>(n);
  double trace_r2 = count * r(0) * r(0);
  for (Index d = 1; d < n; ++d) trace_r2 += 2.0 * (count - static_cast<double>(d)) * r(d) * r(d);
  double trace = count * r(0), trace_of_square = trace_r2;
  if (c.about_mean) {
    trace -= c.total / count;
    trace_of_square += -2.0 * c.row_sums.squaredNorm() / count + c.total * c.total / (count * count);
  }
  StretchMoments m;
  m.about_mean = c.about_mean;
  m.mean_square = trace / count;
  m.dof = trace_of_square > 0.0 ? trace * trace / trace_of_square : count;
  m.law = noise::QuadraticFormLaw::from(Eigen::VectorXd(), trace, trace_of_square);
  return m;
}

NoiseModel::StretchMoments NoiseModel::stretch(Index n, double fs_hz) const {
  if (n < 2 || !has_reference()) return {0.0, 0.0, has_slow_noise(), {}};
  const StretchCovariance c = stretch_covariance(n, fs_hz);
  StretchMoments m = moments(c);
  // White noise: every eigenvalue is sigma^2, and the scaled chi-square is the law.
  if (!has_power_law() && ma.size() == 0 && ar.size() == 0) return m;
  const double trace = m.mean_square * static_cast<double>(n);
  m.law = noise::QuadraticFormLaw::from(leading_eigenvalues(c), trace, trace * trace / m.dof);
  return m;
}

Location locate(const dataset::Dataset& data, const std::vector<CaseResidual>& residuals, const NoiseModel& noise,
                double alpha) {
  Location out;
  out.noise = noise.describe();
  out.about_means = noise.has_slow_noise();
  if (!noise.has_reference()) {
    out.verdict = "no noise reference: location by band and condition skipped";
    return out;
  }
  std::size_t tests = 0;
  for (const CaseResidual& cr : residuals) {
    const double fs = 1.0 / data.cases[cr.case_index].sample_period_s;
    out.bands.push_back(case_bands(cr, fs, noise));
    tests += out.bands.back().bands.size();
  }
  for (CaseBands& cb : out.bands) {
    for (BandTest& b : cb.bands) b.excess = b.p_value < ident::family_threshold(alpha, tests);
  }

  // Conditions. Each phase's run is a stretch whose covariance the model states (StretchCovariance,
  // about the run's mean when the model has slow noise, as the band test's segments are). A
  // sample's expected square is the covariance's diagonal there, exact: a contiguous part of a
  // run also carries its offset from the run's mean, which slow noise makes larger at the run's
  // ends. Each sample brings the run's variance in proportion to its expected square, so a bin
  // holding a share of a run gets that share of the run's dof: where its samples interleave
  // through the run (|a| under vibration) they share its slow noise and have more (conservative).
  // The scaled chi-square's tail is light where the noise is flicker across the whole band (few
  // dominant eigenvalues), so it rejects more such stretches than its level says
  // (docs/validation.md, 'Evidence behind choices in the code').
  struct Acc {
    double ss = 0.0, expected = 0.0, half_variance = 0.0;
    Index n = 0;
  };
  std::vector<Acc> accel(kAccelEdgesG.size() - 1);
  std::vector<Acc> temp;
  double t_min = std::numeric_limits<double>::infinity(), t_max = -t_min;
  bool have_temp = true;
  for (const CaseResidual& cr : residuals) {
    const dataset::CaseData& c = data.cases[cr.case_index];
    have_temp = have_temp && c.temp.has_value();
    for (Index r = 0; c.temp && r < cr.residual.size(); ++r) {
      t_min = std::min(t_min, (*c.temp)(cr.first_sample + r));
      t_max = std::max(t_max, (*c.temp)(cr.first_sample + r));
    }
  }
  const bool by_temp = have_temp && std::isfinite(t_min) && t_max - t_min > 1.0;
  const double t_base = by_temp ? std::floor(t_min / kTempBinC) * kTempBinC : 0.0;
  if (by_temp) temp.resize(static_cast<std::size_t>(std::floor((t_max - t_base) / kTempBinC)) + 1);
  std::map<std::pair<Index, double>, std::pair<NoiseModel::StretchCovariance, NoiseModel::StretchMoments>> runs;
  for (const CaseResidual& cr : residuals) {
    const dataset::CaseData& c = data.cases[cr.case_index];
    const double fs = 1.0 / c.sample_period_s;
    const auto phase = [&](Index r) { return c.phase.empty() ? 0 : c.phase[static_cast<std::size_t>(cr.first_sample + r)]; };
    for (Index begin = 0, end = 0; begin < cr.residual.size(); begin = end) {
      while (end < cr.residual.size() && phase(end) == phase(begin)) ++end;
      const Index m = end - begin;
      if (m < 2) continue;
      auto it = runs.find({m, fs});
      if (it == runs.end()) {
        NoiseModel::StretchCovariance cov = noise.stretch_covariance(m, fs);
        const NoiseModel::StretchMoments mom = NoiseModel::moments(cov);
        it = runs.emplace(std::make_pair(m, fs), std::make_pair(std::move(cov), mom)).first;
      }
      const NoiseModel::StretchCovariance& cov = it->second.first;
      const NoiseModel::StretchMoments& mom = it->second.second;
      const double mean = cov.about_mean ? cr.residual.segment(begin, m).mean() : 0.0;
      const double variance_per_expected = mom.mean_square * static_cast<double>(m) / mom.dof;
      const auto add_sample = [&](Acc& a, Index i) {
        const double r = cr.residual(begin + i) - mean, expected = cov(i, i);
        a.ss += r * r;
        a.expected += expected;
        a.half_variance += expected * variance_per_expected;
        ++a.n;
      };
      for (Index i = 0; i < m; ++i) {
        const Index k = cr.first_sample + begin + i;
        const double g = mps2_to_g(c.a_e.row(k).norm());
        const auto bin = static_cast<std::size_t>(std::upper_bound(kAccelEdgesG.begin(), kAccelEdgesG.end(), g) - kAccelEdgesG.begin()) - 1;
        add_sample(accel[std::min(bin, accel.size() - 1)], i);
        if (by_temp) {
          const auto t_bin = static_cast<std::size_t>(std::floor(((*c.temp)(k) - t_base) / kTempBinC));
          add_sample(temp[std::min(t_bin, temp.size() - 1)], i);
        }
      }
    }
  }
  auto add = [&](const char* quantity, double lo, double hi, const Acc& a) {
    if (a.n < kMinBinSamples) return;
    ConditionBin b;
    b.quantity = quantity;
    b.lo = lo;
    b.hi = hi;
    b.samples = a.n;
    b.rms = std::sqrt(a.ss / static_cast<double>(a.n));
    b.expected_rms = std::sqrt(a.expected / static_cast<double>(a.n));
    b.ratio = b.rms / b.expected_rms;
    b.dof = std::min(static_cast<double>(a.n), a.expected * a.expected / a.half_variance);
    b.p_value = chi2_upper(b.dof, b.dof * a.ss / a.expected);
    out.conditions.push_back(b);
  };
  for (std::size_t i = 0; i < accel.size(); ++i) add("|a|", kAccelEdgesG[i], kAccelEdgesG[i + 1], accel[i]);
  for (std::size_t i = 0; i < temp.size(); ++i)
    add("T", t_base + kTempBinC * static_cast<double>(i), t_base + kTempBinC * static_cast<double>(i + 1), temp[i]);
  for (ConditionBin& b : out.conditions) b.excess = b.p_value < ident::family_threshold(alpha, out.conditions.size());

  std::string where;
  for (const CaseBands& cb : out.bands) {
    const std::string r = band_ranges(cb);
    if (!r.empty()) where += fmt::format("{}{}: {}", where.empty() ? "" : "; ", data.cases[cb.case_index].name, r);
  }
  std::string cond;
  for (const ConditionBin& b : out.conditions) {
    if (!b.excess) continue;
    cond += fmt::format("{}{} {:.3g}-{:.3g} {} (RMS x{:.3g})", cond.empty() ? "" : ", ", b.quantity, b.lo,
                        b.hi > 1e299 ? std::numeric_limits<double>::infinity() : b.hi, b.quantity == "T" ? "degC" : "g",
                        b.ratio);
  }
  if (where.empty() && cond.empty()) {
    out.verdict = "within the model noise in every frequency band and condition bin";
  } else {
    out.verdict = "excess by frequency: " + (where.empty() ? std::string("none") : where) +
                  "; by condition: " + (cond.empty() ? std::string("none") : cond);
  }
  return out;
}

}  // namespace inertia::diagnose
