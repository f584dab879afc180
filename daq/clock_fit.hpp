#pragma once
// One time base for every device on a real bench: a device's samples are timed
// by its own sample clock (the frame counter it sends, or the count of its samples), mapped to
// CLOCK_MONOTONIC by an online fit of offset and drift to the host stamps of its samples.
//
// A host stamp is the sample's true time plus a latency that is never negative: the ADC's
// conversion and transfer, the bus, the driver, the receiving thread's scheduling. The latency's
// floor is nearly constant; its excess is one-sided jitter (tens of us to ms on a loaded PC).
// A least-squares line through all stamps would follow the mean latency, and a late burst would
// drag it. The fit follows the floor instead: per window of samples (window_s) the sample with
// the smallest stamp minus its nominal time is kept (the one that waited least), and the floor of
// the kept points of the last span_s (the line below all of them closest to them in sum: an edge
// of their lower convex hull, as in one-way-delay skew estimation) gives offset and period; a
// stretch of late windows lies above it and cannot tilt it. With 200 us rms exponential jitter
// at 1 kHz a window of 100 samples keeps a point ~2 us above the floor, and the floor of those
// points follows the clock where a stretch of extra load would tilt a least-squares line (tests
// ClockFit.SampleTimesWithinTwentyMicrosecondsAfterTenSeconds and
// ClockFit.ALoadedStretchDoesNotTiltTheDrift; figures in docs/validation.md, 'Evidence behind
// choices in the code'); its period carries the device clock's error against the host's
// (drift_ppm).
//
// The constant part of the floor is not observable from the stamps; it is the device's
// `latency_floor_ns` (config; default 0). Thread: the publisher's; not real-time (no allocation
// after construction, O(1) per sample, O(points) per window).
#include <cstdint>
#include <vector>

namespace inertia::daq {

/// The fit's default window: per this many seconds of samples, the one that waited least is kept.
inline constexpr double kClockFitWindowS = 0.1;

class ClockFit {
 public:
  ClockFit(double nominal_period_s, double window_s = kClockFitWindowS, double span_s = 20.0);

  /// One sample: its index on the device's clock (increasing; gaps allowed) and its host stamp.
  void add(std::int64_t index, std::int64_t host_ns) noexcept;

  /// Host time (ns, CLOCK_MONOTONIC) of sample `index`. Before the first window closes: the
  /// earliest stamp's line at the nominal period.
  [[nodiscard]] double time_ns(std::int64_t index) const noexcept;
  /// The device's sample period on the host clock (s).
  [[nodiscard]] double period_s() const noexcept { return period_ns_ * 1e-9; }
  /// (period / nominal - 1) in ppm: the device clock's error against the host's.
  [[nodiscard]] double drift_ppm() const noexcept { return (period_ns_ / nominal_ns_ - 1.0) * 1e6; }
  /// Standard deviation of drift_ppm(): a line through the kept points scattering by the
  /// residual, with the scatter's autocorrelation over up to sqrt(points) windows (0 before two
  /// points). A load that only eases (or only grows) over the whole span is a tilt of the floor
  /// that no stamp tells from drift; it is not in this sd.
  [[nodiscard]] double drift_sd_ppm() const noexcept { return drift_sd_ppm_; }
  /// RMS of the kept points about the line (us): the floor's wander, what the fit cannot follow.
  [[nodiscard]] double residual_us() const noexcept { return residual_ns_ * 1e-3; }
  /// Kept points in the current fit (0: nominal period, no drift estimate yet).
  [[nodiscard]] std::size_t points() const noexcept { return count_; }

 private:
  void close_window() noexcept;
  void refit() noexcept;

  double nominal_ns_;
  std::int64_t window_samples_;
  std::size_t capacity_;
  // Ring of kept points (index, stamp).
  std::vector<std::int64_t> index_, stamp_;
  std::size_t head_ = 0, count_ = 0;
  // Current window: its first index and the best point so far.
  bool window_open_ = false;
  std::int64_t window_first_ = 0;
  std::int64_t best_index_ = 0, best_stamp_ = 0;
  double best_excess_ = 0.0;
  // Fit: time = anchor_stamp_ + (index - anchor_index_) * period_ns_ + offset_ns_.
  bool started_ = false;
  std::int64_t anchor_index_ = 0, anchor_stamp_ = 0;
  double offset_ns_ = 0.0, period_ns_;
  double residual_ns_ = 0.0;
  double drift_sd_ppm_ = 0.0;
};

/// The times a device's blocks carry: sample k of a block at t0 + k * period (sample_block_t),
/// continuous from one block to the next while the sample numbers are. The fit's line moves when
/// it refits (a late first window tilts its first edges; an edge gives way to the next one); a
/// step between two blocks reads downstream as lost samples (forward) or overlapping blocks
/// (backward), and as a spike in every difference of an encoder read at those times. So a
/// correction is slewed in, as a clock discipline does: each block starts where the previous one
/// ended and ends on the fit's line, its period within max_slew of the fit's (2 %: a 2 ms
/// start-up correction is in after 0.1 s). A jump of the numbers (samples that never arrived)
/// starts on the fit again. Thread: the publisher's; O(1), no allocation.
class SlewedTimeBase {
 public:
  static constexpr double kDefaultMaxSlew = 0.02;
  explicit SlewedTimeBase(double max_slew = kDefaultMaxSlew) : max_slew_(max_slew) {}

  struct BlockTime {
    std::int64_t t0_ns = 0;
    double period_s = 0.0;
  };
  /// Times of the block of samples [first, first + n) of a device timed by `fit`.
  [[nodiscard]] BlockTime block(const ClockFit& fit, std::int64_t first, std::int32_t n) noexcept;
  /// The largest correction met between two blocks (us): what a step would have been.
  [[nodiscard]] double largest_correction_us() const noexcept { return largest_correction_ns_ * 1e-3; }

 private:
  double max_slew_;
  bool started_ = false;
  std::int64_t next_index_ = 0;   // the number after the last block's ...
  double next_ns_ = 0.0;          // ... and its time on the published line
  double largest_correction_ns_ = 0.0;
};

}  // namespace inertia::daq
