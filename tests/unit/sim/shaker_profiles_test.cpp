// Shaker profiles against independent computations: a Welch PSD written here (own radix-2 FFT,
// not the Eigen FFT the generator uses), a single-bin DFT for the sine, finite differences for
// the consistency of displacement and acceleration.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <vector>

#include "common/units.hpp"
#include "hal/sim/shaker_profiles.hpp"

namespace {

using inertia::kPi;
using namespace inertia::sim;

// Iterative radix-2 Cooley-Tukey, size a power of two.
void fft(std::vector<std::complex<double>>& x) {
  const std::size_t n = x.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(x[i], x[j]);
  }
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const std::complex<double> w = std::polar(1.0, -2.0 * kPi / static_cast<double>(len));
    for (std::size_t i = 0; i < n; i += len) {
      std::complex<double> wk = 1.0;
      for (std::size_t k = 0; k < len / 2; ++k) {
        const auto u = x[i + k], v = x[i + k + len / 2] * wk;
        x[i + k] = u + v;
        x[i + k + len / 2] = u - v;
        wk *= w;
      }
    }
  }
}

// One-sided Welch PSD (Hann window, 50 % overlap), units^2/Hz; also returns the segment count.
std::vector<double> welch(const Eigen::VectorXd& x, std::size_t seg, double fs, std::size_t* segments) {
  std::vector<double> win(seg), psd(seg / 2 + 1, 0.0);
  double wss = 0.0;
  for (std::size_t i = 0; i < seg; ++i) {
    win[i] = 0.5 - 0.5 * std::cos(2.0 * kPi * static_cast<double>(i) / static_cast<double>(seg));
    wss += win[i] * win[i];
  }
  std::size_t count = 0;
  for (std::size_t start = 0; start + seg <= static_cast<std::size_t>(x.size()); start += seg / 2) {
    std::vector<std::complex<double>> buf(seg);
    for (std::size_t i = 0; i < seg; ++i) buf[i] = win[i] * x[static_cast<Eigen::Index>(start + i)];
    fft(buf);
    for (std::size_t k = 0; k <= seg / 2; ++k) {
      const double one_sided = (k == 0 || k == seg / 2) ? 1.0 : 2.0;
      psd[k] += one_sided * std::norm(buf[k]) / (fs * wss);
    }
    ++count;
  }
  for (double& p : psd) p /= static_cast<double>(count);
  *segments = count;
  return psd;
}

TEST(RandomSegment, RmsAndFlatPsdMatchTheRequest) {
  const double fs = 10000.0, f1 = 20.0, f2 = 2000.0, rms = 17.0 * inertia::kStandardGravity, ramp = 0.05;
  const std::size_t n = 100000;   // 10 s: enough segments for a tight PSD estimate
  const ShakerSegment s = random_segment(f1, f2, rms, ramp, n, fs, 42);
  // Plateau: where the taper is 1.
  const auto skip = static_cast<Eigen::Index>(ramp * fs) + 1;
  const Eigen::VectorXd plateau = s.a.segment(skip, static_cast<Eigen::Index>(n) - 2 * skip);
  const double realized = std::sqrt(plateau.squaredNorm() / static_cast<double>(plateau.size()));
  // Equal bin amplitudes with random phases: the mean square over a window shorter than the
  // synthesis period scatters by well under 1 %; 3 % is the request's tolerance.
  EXPECT_NEAR(realized / rms, 1.0, 0.03);

  const std::size_t seg = 2048;
  std::size_t segments = 0;
  const std::vector<double> psd = welch(plateau, seg, fs, &segments);
  const double df = fs / static_cast<double>(seg);
  const double level = rms * rms / (f2 - f1);
  // In-band: ten bands, each an average of B bins over K segments. The relative standard error of
  // a Welch average is about 1/sqrt(K B) (Hann with 50 % overlap keeps segments nearly
  // independent); the bound is 5 of those, plus 1 % for the band edges' leakage.
  const double lo = f1 + 5 * df, hi = f2 - 5 * df;
  const int bands = 10;
  for (int b = 0; b < bands; ++b) {
    const double fa = lo + (hi - lo) * b / bands, fb = lo + (hi - lo) * (b + 1) / bands;
    double sum = 0.0;
    int bins = 0;
    for (std::size_t k = 0; k < psd.size(); ++k) {
      const double f = static_cast<double>(k) * df;
      if (f >= fa && f < fb) {
        sum += psd[k];
        ++bins;
      }
    }
    const double tol = 5.0 / std::sqrt(static_cast<double>(segments) * bins) + 0.01;
    EXPECT_NEAR(sum / bins / level, 1.0, tol) << "band " << fa << "-" << fb << " Hz";
  }
  // Out of band: leakage of the Hann window only, far below the level.
  for (std::size_t k = 0; k < psd.size(); ++k) {
    const double f = static_cast<double>(k) * df;
    if ((f > 2.0 && f < f1 / 2) || f > 1.2 * f2) {
      EXPECT_LT(psd[k], 1e-3 * level) << f << " Hz";
    }
  }
}

TEST(RandomSegment, DisplacementIsTheDoubleIntegralWithoutDrift) {
  // Low band so that a second difference approximates the second derivative to (w dt)^2/12.
  const double fs = 10000.0, f2 = 100.0;
  const std::size_t n = 20000;
  const ShakerSegment s = random_segment(10.0, f2, 10.0, 0.1, n, fs, 7);
  const double dt = 1.0 / fs, wmax = 2.0 * kPi * f2;
  const double a_rms = std::sqrt(s.a.squaredNorm() / static_cast<double>(n));
  double worst = 0.0;
  for (Eigen::Index k = 1; k + 1 < static_cast<Eigen::Index>(n); ++k) {
    const double dd = (s.x[k + 1] - 2.0 * s.x[k] + s.x[k - 1]) / (dt * dt);
    worst = std::max(worst, std::abs(dd - s.a[k]));
  }
  // Truncation error of the central difference: a * (w dt)^2 / 12 at the band's top, with a
  // crest factor of 5 on a_rms.
  EXPECT_LT(worst, 5.0 * a_rms * (wmax * dt) * (wmax * dt) / 12.0);
  // Starts and ends at rest: the taper brings x and v to zero (the last sample is dt from the end).
  const double x_rms = std::sqrt(s.x.squaredNorm() / static_cast<double>(n));
  EXPECT_EQ(s.x[0], 0.0);
  EXPECT_EQ(s.v[0], 0.0);
  EXPECT_LT(std::abs(s.x[static_cast<Eigen::Index>(n) - 1]), 1e-3 * x_rms);
}

TEST(RandomSegment, SeedChangesTheRealization) {
  const ShakerSegment a = random_segment(20.0, 200.0, 1.0, 0.05, 4000, 1000.0, 1);
  const ShakerSegment b = random_segment(20.0, 200.0, 1.0, 0.05, 4000, 1000.0, 1);
  const ShakerSegment c = random_segment(20.0, 200.0, 1.0, 0.05, 4000, 1000.0, 2);
  EXPECT_EQ(a.a, b.a);
  EXPECT_GT((a.a - c.a).norm(), 0.5 * a.a.norm());
}

TEST(SineSegment, AmplitudeAndFrequencyOnThePlateau) {
  const double fs = 10000.0, f = 10.0, amp = 30.0 * inertia::kStandardGravity;
  const std::size_t n = 10000;   // 1 s, ramps of one cycle at each end
  const ShakerSegment s = sine_segment(f, amp, 1.0, n, fs);
  // Plateau [0.1 s, 0.9 s): exactly 8 cycles, so the DFT bin at f holds the whole sine.
  const Eigen::Index k0 = 1000, len = 8000;
  auto bin = [&](double fq) {
    std::complex<double> acc = 0.0;
    for (Eigen::Index k = 0; k < len; ++k) {
      const double t = static_cast<double>(k0 + k) / fs;
      acc += s.a[k0 + k] * std::polar(1.0, -2.0 * kPi * fq * t);
    }
    return 2.0 * acc / static_cast<double>(len);
  };
  const std::complex<double> c = bin(f);
  EXPECT_NEAR(std::abs(c) / amp, 1.0, 1e-9);
  EXPECT_NEAR(std::arg(c), -kPi / 2, 1e-9);   // a = A sin(w t) from the phase start
  // Neighbouring bins (integer cycles) hold nothing: the frequency is f, not near it.
  EXPECT_LT(std::abs(bin(f - fs / len)) / amp, 1e-9);
  EXPECT_LT(std::abs(bin(f + fs / len)) / amp, 1e-9);
  // Displacement and velocity vanish at both ends (no drift for the encoder).
  EXPECT_EQ(s.x[0], 0.0);
  EXPECT_EQ(s.v[0], 0.0);
  const double x_amp = amp / std::pow(2.0 * kPi * f, 2);
  EXPECT_LT(std::abs(s.x[static_cast<Eigen::Index>(n) - 1]), 1e-6 * x_amp);
  // x'' = a everywhere, ramps included. The central difference's truncation error is
  // |x''''| dt^2 / 12. On a one-cycle ramp, x = (A/w^2) win sin and the window's derivatives are
  // bounded by |win'| <= w/pi and |win''|, |win'''|, |win''''| <= w^2, w^3, w^4 over 2 pi, so
  // Leibniz gives |x''''| <= A w^2 (1 + 4/pi + 6/(2 pi) + 4/(2 pi) + 1/(2 pi)) = A w^2 (1 + 9.5/pi).
  const double dt = 1.0 / fs;
  const double bound = (1.0 + 9.5 / kPi) * amp * std::pow(2.0 * kPi * f * dt, 2) / 12.0;
  for (Eigen::Index k = 1; k + 1 < static_cast<Eigen::Index>(n); ++k) {
    const double dd = (s.x[k + 1] - 2.0 * s.x[k] + s.x[k - 1]) / (dt * dt);
    ASSERT_NEAR(dd, s.a[k], bound + 1e-9 * amp) << k;
  }
}

TEST(ShockSegment, PeakDurationAndNoResidualMotion) {
  const double fs = 10000.0, peak = 50.0 * inertia::kStandardGravity, d = 0.011, comp = 8.0;
  const std::size_t n = 5000;
  const ShakerSegment s = shock_segment(peak, d, comp, n, fs);
  EXPECT_NEAR(s.a.maxCoeff(), peak, peak * (1.0 - std::cos(kPi / (d * fs))));   // within half a sample of the crest
  // Duration: samples of the main pulse (above the compensating pulses' level) times dt.
  Eigen::Index first = -1, last = -1;
  for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(n); ++k) {
    if (s.a[k] > 0.0) {
      if (first < 0) first = k;
      last = k;
    }
  }
  EXPECT_NEAR(static_cast<double>(last - first + 1) / fs, d, 1.5 / fs);
  // The compensating pulses: opposite sign, peak / (2 comp).
  EXPECT_NEAR(s.a.minCoeff(), -peak / (2.0 * comp), 1e-3 * peak / comp);
  // Main pulse area (trapezoid) = 2 P D / pi.
  double area = 0.0;
  for (Eigen::Index k = first; k <= last; ++k) area += s.a[k] / fs;
  EXPECT_NEAR(area, 2.0 * peak * d / kPi, 2e-3 * 2.0 * peak * d / kPi);
  // At rest after the shock: the symmetric, zero-area profile returns v and x to zero.
  const Eigen::Index end = static_cast<Eigen::Index>(n) - 1;
  EXPECT_NEAR(s.v[end], 0.0, 1e-12 * peak * d);
  EXPECT_NEAR(s.x[end], 0.0, 1e-12 * peak * d * d * comp);
  // x'' = a, checked away from the pulse corners (where a' jumps and the difference smears).
  const double dt = 1.0 / fs;
  const double w = kPi / d;
  for (Eigen::Index k = 1; k < end; ++k) {
    const double dd = (s.x[k + 1] - 2.0 * s.x[k] + s.x[k - 1]) / (dt * dt);
    ASSERT_NEAR(dd, s.a[k], peak * (w * dt) * (w * dt) / 12.0 + peak * (w * dt) / 2.0) << k;
  }
}

TEST(RampWindow, ContinuousWithDerivatives) {
  const double length = 1.0, ramp = 0.1, h = 1e-6;
  for (double t : {0.03, 0.07, 0.5, 0.93, 0.97}) {
    const WindowValue a = ramp_window(t - h, length, ramp), b = ramp_window(t + h, length, ramp),
                      c = ramp_window(t, length, ramp);
    EXPECT_NEAR((b.w - a.w) / (2 * h), c.dw, 1e-6 * (1 + std::abs(c.dw)));
    EXPECT_NEAR((b.dw - a.dw) / (2 * h), c.ddw, 1e-4 * (1 + std::abs(c.ddw)));
  }
  EXPECT_EQ(ramp_window(0.0, length, ramp).w, 0.0);
  EXPECT_EQ(ramp_window(0.5, length, ramp).w, 1.0);
}

}  // namespace
