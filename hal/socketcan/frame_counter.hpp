#pragma once
// A frame counter (CanSignal::counter) unwrapped into the device's sample number by value and by
// receive time together. By value alone a counter cannot tell a roll-over from an adapter reset,
// nor one roll-over from several: a 16-bit counter at 10 kHz that restarts at 0 from above 32768
// reads as a forward jump of up to 3.3 s, and a silence of 6.5 to 9.8 s as a jump 65536 short.
// The receive stamps say how many samples the adapter's clock took between two frames (the
// nominal period, within the stamps' jitter and the clocks' drift), so:
//   * the step is the counter's difference plus the number of whole roll-overs closest to the
//     elapsed receive time (a long silence keeps its length);
//   * a counter that went down in value where the elapsed time says it did not roll over (its
//     step disagrees with the time by more than the tolerance) restarted: the adapter rebooted,
//     its numbers and its clock are a new segment, numbered on from the elapsed time, whose start
//     the device marks (hal::kSegmentStart). A counter that went up by other than the time says
//     keeps its own step: a frame stamped late (a delayed transfer, a stalled host) is no reset.
//     A restart whose counter lands within the tolerance of where the old one would have been is
//     not seen (a chance of 2 x tolerance / range: 0.15 % for 16 bits at 10 kHz), and its
//     samples are then numbered within the tolerance of their place;
//   * a counter received already (the newest, or one of the kReorderFrames before it) is a
//     duplicate, one a few frames behind the newest that never came is out of order (overtaken):
//     both are refused, so a sample number is never given twice (nothing is overwritten).
// Without a nominal rate only the value is there: the shortest step forward, resets unseen.
// Thread: the sampling thread. Real-time: O(1), no allocation.
#include <cstdint>

namespace inertia::hal::socketcan {

class FrameCounter {
 public:
  /// Receive stamps of one adapter's frames scatter by the adapter's transfer (a USB adapter
  /// hands over frames a millisecond's batch at a time) and the host's interrupt handling; a
  /// jump disagreeing with the elapsed time by more than this (plus kDriftTolerance of it) is a reset.
  static constexpr double kStampTolerance_s = 0.005;
  /// Clock error allowed between the adapter and the host over a long silence (1000 ppm).
  static constexpr double kDriftTolerance = 1e-3;
  /// A counter at most this many behind the newest, within the stamp tolerance, is a duplicate or
  /// a frame out of order (refused); further behind, or later, it is a reset.
  static constexpr std::int64_t kReorderFrames = 64;

  enum class Verdict : std::uint8_t {
    First,        // the first frame: the counter's value is its number
    Next,         // the number after the newest, by the step the counter and the time agree on
    Reset,        // a new segment starts at this number (the counter restarted)
    Duplicate,    // the newest counter again: refused
    OutOfOrder,   // behind the newest: refused
  };
  struct Result {
    Verdict verdict = Verdict::First;
    std::int64_t index = 0;   // the frame's sample number (the newest's for a refused frame)
  };

  /// bits: the counter's width (1..64); period_ns: the adapter's nominal frame period (<= 0:
  /// unknown, value only).
  FrameCounter(int bits, double period_ns) noexcept;

  /// One frame's counter and receive stamp (CLOCK_MONOTONIC). Real-time safe.
  Result take(std::uint64_t raw, std::int64_t t_ns) noexcept;

  [[nodiscard]] std::int64_t newest() const noexcept { return index_; }

 private:
  int bits_;
  double period_ns_;
  bool seen_ = false;
  std::uint64_t raw_ = 0;      // the newest accepted counter ...
  std::int64_t index_ = 0;     // ... its sample number ...
  std::int64_t t_ns_ = 0;      // ... and its receive stamp
  // Bit k set: number index_ - k came (k < 64), so that a frame behind the newest is told a
  // duplicate from one overtaken.
  std::uint64_t received_ = 0;
};

}  // namespace inertia::hal::socketcan
