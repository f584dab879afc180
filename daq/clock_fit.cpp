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
  // Excess of the stamp over the current line: the sample with the least is the one that waited
  // least.
  const double excess = static_cast<double>(host_ns) - time_ns(index);
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
  if (count_ == 0 && excess < 0.0) offset_ns_ += excess;
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
  // Least squares of (stamp - anchor_stamp) on (index - anchor_index), centred; then once more
  // without the points far above the line: a window whose every sample came late (a stalled
  // reader) is not the floor. Its excess over the line, not below: a latency is never negative.
  double cut = std::numeric_limits<double>::infinity();
  for (int pass = 0; pass < 2; ++pass) {
    double mx = 0.0, my = 0.0, n = 0.0;
    for (std::size_t k = 0; k < count_; ++k) {
      const double x = static_cast<double>(index_[k] - anchor_index_);
      const double y = static_cast<double>(stamp_[k] - anchor_stamp_);
      if (pass > 0 && y - (offset_ns_ + period_ns_ * x) > cut) continue;
      mx += x;
      my += y;
      n += 1.0;
    }
    if (n == 0.0) return;
    mx /= n;
    my /= n;
    double sxx = 0.0, sxy = 0.0;
    for (std::size_t k = 0; k < count_; ++k) {
      const double x = static_cast<double>(index_[k] - anchor_index_);
      const double y = static_cast<double>(stamp_[k] - anchor_stamp_);
      if (pass > 0 && y - (offset_ns_ + period_ns_ * x) > cut) continue;
      sxx += (x - mx) * (x - mx);
      sxy += (x - mx) * (y - my);
    }
    // One point (or points at one index) fixes the offset only: keep the period.
    if (n >= 2.0 && sxx > 0.0) period_ns_ = sxy / sxx;
    offset_ns_ = my - period_ns_ * mx;
    // Residuals about this line; the cut for the second pass from their median absolute value.
    std::array<double, 512> r{};
    const std::size_t m = std::min(count_, r.size());
    double ss = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      const double x = static_cast<double>(index_[k] - anchor_index_);
      r[k] = static_cast<double>(stamp_[k] - anchor_stamp_) - (offset_ns_ + period_ns_ * x);
      ss += r[k] * r[k];
    }
    residual_ns_ = std::sqrt(ss / static_cast<double>(std::max<std::size_t>(1, m)));
    if (pass > 0) break;
    std::array<double, 512> a{};
    for (std::size_t k = 0; k < m; ++k) a[k] = std::abs(r[k]);
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(m / 2), a.begin() + static_cast<std::ptrdiff_t>(m));
    cut = std::max(5.0 * 1.4826 * a[m / 2], 20e3);   // 5 robust sd, at least 20 us
  }
  // The residual reported is of the kept points.
  double ss = 0.0, n = 0.0;
  for (std::size_t k = 0; k < count_; ++k) {
    const double x = static_cast<double>(index_[k] - anchor_index_);
    const double r = static_cast<double>(stamp_[k] - anchor_stamp_) - (offset_ns_ + period_ns_ * x);
    if (r > cut) continue;
    ss += r * r;
    n += 1.0;
  }
  if (n > 0.0) residual_ns_ = std::sqrt(ss / n);
}

double ClockFit::time_ns(std::int64_t index) const noexcept {
  return static_cast<double>(anchor_stamp_) + offset_ns_ + period_ns_ * static_cast<double>(index - anchor_index_);
}

}  // namespace inertia::daq
