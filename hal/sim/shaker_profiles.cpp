#include "hal/sim/shaker_profiles.hpp"

#include <unsupported/Eigen/FFT>
#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "common/units.hpp"
#include "hal/sim/random_streams.hpp"

namespace inertia::sim {

WindowValue ramp_window(double t, double length, double ramp) {
  if (ramp <= 0.0) return {1.0, 0.0, 0.0};
  // w(u) = u - sin(2 pi u) / (2 pi) on u = (time into the ramp) / ramp: w' and w'' vanish at
  // both ends, so the window is C2 and the acceleration a = (w s)'' has no step at the ramp
  // edges (a raised cosine would leave a step of w'' there).
  const double k = 2.0 * kPi / ramp;
  auto up = [&](double u_s) -> WindowValue {
    const double u = std::clamp(u_s, 0.0, ramp);
    return {u / ramp - std::sin(k * u) / (2.0 * kPi), (1.0 - std::cos(k * u)) / ramp, k * std::sin(k * u) / ramp};
  };
  if (t < ramp) return up(t);
  if (t > length - ramp) {
    const WindowValue w = up(length - t);   // time to the end; d/dt = -d/du
    return {w.w, -w.dw, w.ddw};
  }
  return {1.0, 0.0, 0.0};
}

ShakerSegment sine_segment(double frequency_hz, double amplitude_mps2, double ramp_cycles,
                           std::size_t samples, double sample_rate_hz) {
  ShakerSegment s{Eigen::VectorXd(samples), Eigen::VectorXd(samples), Eigen::VectorXd(samples)};
  const double w = 2.0 * kPi * frequency_hz;
  const double length = static_cast<double>(samples) / sample_rate_hz;
  const double ramp = ramp_cycles / frequency_hz;
  const double k = amplitude_mps2 / (w * w);
  for (std::size_t i = 0; i < samples; ++i) {
    const double t = static_cast<double>(i) / sample_rate_hz;
    const double sn = std::sin(w * t), cs = std::cos(w * t);
    const WindowValue win = ramp_window(t, length, ramp);
    const auto n = static_cast<Eigen::Index>(i);
    s.x[n] = -k * win.w * sn;
    s.v[n] = -k * (win.dw * sn + win.w * w * cs);
    s.a[n] = amplitude_mps2 * win.w * sn - k * (win.ddw * sn + 2.0 * w * win.dw * cs);
  }
  return s;
}

ShakerSegment random_segment(double f1_hz, double f2_hz, double rms_mps2, double ramp_s,
                             std::size_t samples, double sample_rate_hz, std::uint64_t seed) {
  std::size_t n_fft = 2;
  while (n_fft < samples) n_fft *= 2;
  const double df = sample_rate_hz / static_cast<double>(n_fft);
  const auto k1 = static_cast<std::size_t>(std::ceil(f1_hz / df));
  const auto k2 = std::min(static_cast<std::size_t>(std::floor(f2_hz / df)), n_fft / 2 - 1);
  const std::size_t bins = k2 >= k1 ? k2 - k1 + 1 : 0;
  ShakerSegment s{Eigen::VectorXd::Zero(samples), Eigen::VectorXd::Zero(samples),
                  Eigen::VectorXd::Zero(samples)};
  if (bins == 0) return s;
  // Equal amplitude c on every bin: sum of K cosines of amplitude c has mean square K c^2 / 2.
  const double c = rms_mps2 * std::sqrt(2.0 / static_cast<double>(bins));
  using Complex = std::complex<double>;
  std::vector<Complex> acc(n_fft), vel(n_fft), disp(n_fft);
  RandomSource rng(seed);
  const double scale = static_cast<double>(n_fft);   // Eigen's inverse FFT divides by n_fft
  for (std::size_t k = k1; k <= k2; ++k) {
    const double w = 2.0 * kPi * df * static_cast<double>(k);
    const Complex e = std::polar(c * scale, 2.0 * kPi * rng.uniform());
    acc[k] = e;                      // c cos(w t + phi)
    vel[k] = e / Complex(0.0, w);    // its integral, (c/w) sin(w t + phi)
    disp[k] = -e / (w * w);          // double integral, -(c/w^2) cos(w t + phi)
  }
  Eigen::FFT<double> fft;
  std::vector<Complex> ta, tv, tx;
  fft.inv(ta, acc);
  fft.inv(tv, vel);
  fft.inv(tx, disp);
  // Only positive-frequency bins were filled: the real part is the real signal.
  const double length = static_cast<double>(samples) / sample_rate_hz;
  for (std::size_t i = 0; i < samples; ++i) {
    const double t = static_cast<double>(i) / sample_rate_hz;
    const WindowValue win = ramp_window(t, length, ramp_s);
    const double x0 = tx[i].real(), v0 = tv[i].real(), a0 = ta[i].real();
    const auto n = static_cast<Eigen::Index>(i);
    s.x[n] = win.w * x0;
    s.v[n] = win.dw * x0 + win.w * v0;
    s.a[n] = win.ddw * x0 + 2.0 * win.dw * v0 + win.w * a0;
  }
  return s;
}

namespace {

// One half-sine pulse of peak p over [ts, ts + d] and its exact integrals (zero before ts).
void add_half_sine(double t, double ts, double d, double p, double& a, double& v, double& x) {
  if (t <= ts) return;
  const double k = kPi / d;
  if (t < ts + d) {
    const double u = t - ts;
    a += p * std::sin(k * u);
    v += p / k * (1.0 - std::cos(k * u));
    x += p / k * (u - std::sin(k * u) / k);
    return;
  }
  const double dv = 2.0 * p / k;   // velocity change of the whole pulse
  v += dv;
  x += p / k * d + dv * (t - ts - d);
}

}  // namespace

ShakerSegment shock_segment(double peak_mps2, double pulse_s, double compensation,
                            std::size_t samples, double sample_rate_hz) {
  ShakerSegment s{Eigen::VectorXd(samples), Eigen::VectorXd(samples), Eigen::VectorXd(samples)};
  const double length = static_cast<double>(samples) / sample_rate_hz;
  const double centre = 0.5 * length;
  const double dc = compensation * pulse_s;
  const double pc = -peak_mps2 / (2.0 * compensation);   // each carries half the main area
  for (std::size_t i = 0; i < samples; ++i) {
    const double t = static_cast<double>(i) / sample_rate_hz;
    double a = 0.0, v = 0.0, x = 0.0;
    add_half_sine(t, centre - 0.5 * pulse_s - dc, dc, pc, a, v, x);
    add_half_sine(t, centre - 0.5 * pulse_s, pulse_s, peak_mps2, a, v, x);
    add_half_sine(t, centre + 0.5 * pulse_s, dc, pc, a, v, x);
    const auto n = static_cast<Eigen::Index>(i);
    s.a[n] = a;
    s.v[n] = v;
    s.x[n] = x;
  }
  return s;
}

}  // namespace inertia::sim
