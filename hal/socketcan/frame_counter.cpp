#include "hal/socketcan/frame_counter.hpp"

#include <algorithm>
#include <cmath>

namespace inertia::hal::socketcan {

FrameCounter::FrameCounter(int bits, double period_ns) noexcept : bits_(std::clamp(bits, 1, 64)), period_ns_(period_ns) {}

FrameCounter::Result FrameCounter::take(std::uint64_t raw, std::int64_t t_ns) noexcept {
  constexpr std::uint64_t kIndexMask = ~std::uint64_t{0} >> 1;   // sample numbers are int64 >= 0
  if (!seen_) {
    seen_ = true;
    raw_ = raw;
    index_ = static_cast<std::int64_t>(raw & kIndexMask);
    t_ns_ = t_ns;
    received_ = 1;
    return {Verdict::First, index_};
  }
  auto accept = [&](Verdict verdict, std::int64_t index) {
    const std::int64_t step = index - index_;
    received_ = (verdict == Verdict::Reset || step >= 64 ? 0 : received_ << step) | 1;
    raw_ = raw;
    index_ = index;
    t_ns_ = t_ns;
    return Result{verdict, index};
  };
  // A frame `behind` the newest: received already, or overtaken by the ones after it.
  auto refused = [&](std::uint64_t behind) {
    const bool again = behind < 64 && ((received_ >> behind) & 1) != 0;
    return Result{again ? Verdict::Duplicate : Verdict::OutOfOrder, index_};
  };
  // The counter's range; a 63- or 64-bit counter never rolls over in a bench's lifetime.
  const bool rolls = bits_ < 63;
  const std::uint64_t modulus = rolls ? std::uint64_t{1} << bits_ : 0;
  const std::uint64_t mask = rolls ? modulus - 1 : ~std::uint64_t{0};
  const std::uint64_t forward = (raw - raw_) & mask;
  const std::uint64_t backward = (raw_ - raw) & mask;
  // Out of order is only ever a few frames; on a small counter less than a quarter of its range.
  const auto reorder = static_cast<std::uint64_t>(
      rolls ? std::min<std::uint64_t>(kReorderFrames, std::max<std::uint64_t>(1, modulus / 4)) : kReorderFrames);
  const double range = rolls ? static_cast<double>(modulus) : 0.0;
  const double elapsed = period_ns_ > 0.0 ? std::max(0.0, static_cast<double>(t_ns - t_ns_) / period_ns_) : 0.0;
  const double tolerance = period_ns_ > 0.0 ? kStampTolerance_s * 1e9 / period_ns_ + kDriftTolerance * elapsed : 0.0;
  // Time decides only where the stamps' scatter is well inside half the counter's range.
  const bool timed = period_ns_ > 0.0 && (!rolls || 4.0 * tolerance < range);
  if (!timed) {
    // By value: the shortest step; a counter a few behind is out of order, the same a duplicate.
    if (forward == 0) return refused(0);
    if (backward <= reorder) return refused(backward);
    if (rolls || forward <= (mask >> 1)) return accept(Verdict::Next, index_ + static_cast<std::int64_t>(forward));
    return accept(Verdict::Reset, index_ + 1);   // a wide counter went back: restarted, gap unknown
  }
  // The step the counter and the elapsed time agree on: its difference plus whole roll-overs.
  double step = static_cast<double>(forward);
  if (rolls && elapsed > step) step += range * std::round((elapsed - step) / range);
  const bool behind = rolls ? raw < raw_ : backward < forward;   // the counter's value went down
  if (!rolls && behind) step = -static_cast<double>(backward);
  if (std::abs(step - elapsed) <= tolerance) {
    if (step == 0.0) return refused(0);
    if (step > 0.0) return accept(Verdict::Next, index_ + static_cast<std::int64_t>(step));
  }
  if (forward != 0 && backward <= reorder && elapsed <= tolerance) return refused(backward);
  // A counter that went up by other than the time says was stamped late or early (a delayed
  // transfer, a stalled host): its own step counts. One that went down where the time says no
  // roll-over happened restarted: numbered on from the time, a new segment.
  if (!behind && step > 0.0) return accept(Verdict::Next, index_ + static_cast<std::int64_t>(step));
  return accept(Verdict::Reset, index_ + std::max<std::int64_t>(1, std::llround(elapsed)));
}

}  // namespace inertia::hal::socketcan
