#include "daq/clock_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace inertia::daq {

ClockFit::ClockFit(double nominal_period_s, double window_s, double span_s)
    : nominal_ns_(nominal_period_s * 1e9),
      window_samples_(std::max<std::int64_t>(1, std::llround(window_s / nominal_period_s))),
      capacity_(static_cast<std::size_t>(std::clamp(std::ceil(span_s / window_s), 4.0, 512.0))),
      index_(capacity_),
      stamp_(capacity_),
      period_ns_(nominal_period_s * 1e9) {}

void ClockFit::add(std::int64_t index, std::int64_t host_ns) noexcept {
  if (!started_) {
    started_ = true;
    anchor_index_ = index;
    anchor_stamp_ = host_ns;
  }
  if (window_open_ && index >= window_first_ + window_samples_) close_window();
  // Excess of the stamp over a line of the current period through the anchor: the sample with the
  // least is the one that waited least. Not over the fitted line itself: before the first window
  // closes its offset follows the earliest floor, and excesses taken against a line that moved
  // within the window would rank a sample of a late start-up burst above the prompt ones after
  // it and put the first fits milliseconds off (ClockFit.AStartUpBurstIsNotTheWindowsLeastDelayedSample).
  const double excess = static_cast<double>(host_ns) - static_cast<double>(anchor_stamp_) -
                        period_ns_ * static_cast<double>(index - anchor_index_);
  if (!window_open_) {
    window_open_ = true;
    window_first_ = index - ((index - anchor_index_) % window_samples_ + window_samples_) % window_samples_;
    best_excess_ = excess;
    best_index_ = index;
    best_stamp_ = host_ns;
  } else if (excess < best_excess_) {
    best_excess_ = excess;
    best_index_ = index;
    best_stamp_ = host_ns;
  }
  // Before any window closed, follow the earliest floor seen at the nominal period.
  if (count_ == 0 && excess < offset_ns_) offset_ns_ = excess;
}

void ClockFit::close_window() noexcept {
  window_open_ = false;
  index_[head_] = best_index_;
  stamp_[head_] = best_stamp_;
  head_ = (head_ + 1) % capacity_;
  count_ = std::min(count_ + 1, capacity_);
  refit();
}

void ClockFit::refit() noexcept {
  // The floor of the kept points: the line below every point that lies closest to them in sum
  // (a linear programme whose optimum is the edge of their lower convex hull over the points'
  // mean index). A latency is never negative, so a point above the floor is only later, whatever
  // made it so: a stretch of windows whose every sample waited (a loaded PC, a stalled reader)
  // lies above the line and does not tilt it, where a least-squares line would follow it.
  if (count_ == 0) return;
  const std::size_t first = count_ < capacity_ ? 0 : head_;   // the oldest point, indices increasing
  std::array<double, 512> xs{}, ys{};
  double mean_x = 0.0;
  for (std::size_t k = 0; k < count_; ++k) {
    const std::size_t at = (first + k) % capacity_;
    xs[k] = static_cast<double>(index_[at] - anchor_index_);
    ys[k] = static_cast<double>(stamp_[at] - anchor_stamp_);
    mean_x += xs[k];
  }
  mean_x /= static_cast<double>(count_);
  // Andrew's monotone chain, lower half (x increasing; equal x keeps the lower point).
  std::array<std::size_t, 512> hull{};
  std::size_t h = 0;
  for (std::size_t k = 0; k < count_; ++k) {
    if (h > 0 && xs[hull[h - 1]] == xs[k]) {
      if (ys[k] >= ys[hull[h - 1]]) continue;
      --h;
    }
    while (h >= 2) {
      const std::size_t o = hull[h - 2], m = hull[h - 1];
      const double cross = (xs[m] - xs[o]) * (ys[k] - ys[o]) - (ys[m] - ys[o]) * (xs[k] - xs[o]);
      if (cross > 0.0) break;   // a left turn: m stays on the lower hull
      --h;
    }
    hull[h++] = k;
  }
  if (h >= 2) {
    // The hull edge over the mean index (the last one when the mean lies at or past its end).
    std::size_t e = 0;
    while (e + 2 < h && xs[hull[e + 1]] < mean_x) ++e;
    const std::size_t p = hull[e], q = hull[e + 1];
    period_ns_ = (ys[q] - ys[p]) / (xs[q] - xs[p]);
    offset_ns_ = ys[p] - period_ns_ * xs[p];
  } else {
    offset_ns_ = ys[hull[0]] - period_ns_ * xs[hull[0]];   // one point fixes the offset only
  }
  // The residual reported: the rms excess over the floor of the points that are not late
  // outright (within 5 robust sd of the median excess, at least 20 us): the fit's own scatter,
  // not how long a loaded stretch waited.
  std::array<double, 512> excess{};
  for (std::size_t k = 0; k < count_; ++k) excess[k] = ys[k] - (offset_ns_ + period_ns_ * xs[k]);
  std::array<double, 512> sorted = excess;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(count_ / 2),
                   sorted.begin() + static_cast<std::ptrdiff_t>(count_));
  const double cut = std::max(5.0 * 1.4826 * sorted[count_ / 2], 20e3);
  std::array<double, 512> kept_x{}, kept_excess{};
  std::size_t n = 0;
  double ss = 0.0, se = 0.0, sx = 0.0;
  for (std::size_t k = 0; k < count_; ++k) {
    if (excess[k] > cut) continue;
    kept_x[n] = xs[k];
    kept_excess[n] = excess[k];
    ss += excess[k] * excess[k];
    se += excess[k];
    sx += xs[k];
    ++n;
  }
  residual_ns_ = n > 0 ? std::sqrt(ss / static_cast<double>(n)) : 0.0;
  drift_sd_ppm_ = 0.0;
  if (n < 2) return;
  // The period's uncertainty as a line through points that scatter by the residual would have
  // it, with their autocorrelation: a host's load comes and goes over seconds, so windows up to
  // a few seconds apart wait alike. The slope's variance is w' Gamma w (w_k = (x_k - mean x) / Sxx) with the excess's
  // autocorrelations up to sqrt(n) windows apart, Bartlett-tapered (Newey-West), scaled by the
  // residual about the floor; never below the white-noise value.
  const double kept_mean_x = sx / static_cast<double>(n), mean_excess = se / static_cast<double>(n);
  std::array<double, 512> w{}, centred{};
  double spread = 0.0, gamma0 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    w[k] = kept_x[k] - kept_mean_x;
    spread += w[k] * w[k];
    centred[k] = kept_excess[k] - mean_excess;
    gamma0 += centred[k] * centred[k];
  }
  if (spread <= 0.0) return;
  for (std::size_t k = 0; k < n; ++k) w[k] /= spread;
  const double white = 1.0 / spread;   // sum of w_k^2
  double weighted = white;
  if (gamma0 > 0.0) {
    const auto lags = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
    for (std::size_t lag = 1; lag <= lags && lag < n; ++lag) {
      double gamma = 0.0, ww = 0.0;
      for (std::size_t k = lag; k < n; ++k) {
        gamma += centred[k] * centred[k - lag];
        ww += w[k] * w[k - lag];
      }
      const double taper = 1.0 - static_cast<double>(lag) / static_cast<double>(lags + 1);
      weighted += 2.0 * taper * (gamma / gamma0) * ww;
    }
  }
  drift_sd_ppm_ = residual_ns_ * std::sqrt(std::max(weighted, white)) / nominal_ns_ * 1e6;
}

double ClockFit::time_ns(std::int64_t index) const noexcept {
  return static_cast<double>(anchor_stamp_) + offset_ns_ + period_ns_ * static_cast<double>(index - anchor_index_);
}

SlewedTimeBase::BlockTime SlewedTimeBase::block(const ClockFit& fit, std::int64_t first, std::int32_t n) noexcept {
  const double fit_period_ns = fit.period_s() * 1e9;
  BlockTime out;
  if (!started_ || first != next_index_ || n < 1) {
    out.t0_ns = std::llround(fit.time_ns(first));
    out.period_s = fit.period_s();
  } else {
    // The integer start the block carries, so that downstream's end of this block (t0 + n *
    // period, from what it receives) is where the next one starts.
    out.t0_ns = std::llround(next_ns_);
    const double t0 = static_cast<double>(out.t0_ns);
    largest_correction_ns_ = std::max(largest_correction_ns_, std::abs(fit.time_ns(first) - t0));
    const double period_ns = (fit.time_ns(first + n) - t0) / static_cast<double>(n);
    out.period_s = 1e-9 * std::clamp(period_ns, fit_period_ns * (1.0 - max_slew_), fit_period_ns * (1.0 + max_slew_));
  }
  started_ = true;
  next_index_ = first + n;
  next_ns_ = static_cast<double>(out.t0_ns) + static_cast<double>(n) * out.period_s * 1e9;
  return out;
}

}  // namespace inertia::daq
