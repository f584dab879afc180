#pragma once
// x4 quadrature decoding of both-edge line events (docs/design.md: shaker armature and rotation-table
// encoders through libgpiod v1 both-edge events with kernel timestamps).
//
// State s = gray index of (A, B): 0 = (0,0), 1 = (1,0), 2 = (1,1), 3 = (0,1); forward motion
// (A leads B) walks 0 -> 1 -> 2 -> 3 -> 0 and counts +1 per edge. One event changes one line,
// so every accepted edge is a legal +-1 step. What is not:
// * glitch: an edge that leaves its line's level unchanged (the opposite edge was lost) while
//   the other line stood still, so the lost edge and this one cancel; or an edge less than
//   min_edge_interval_ns after the previous edge on the same line with no other line's edge in
//   between: that pair is a pulse too short to be motion, so the first edge's step is withdrawn
//   and one glitch counted (bounce settles to the right level either way);
// * lost: an edge that leaves its line's level unchanged after the other line moved: edges of
//   this line were lost in between (libgpiod v1's per-line kernel FIFO of 16 events overflows
//   silently), so the other line's edges were decoded against a wrong level and the count is
//   off by steps nobody saw. The line takes the edge's level; the caller resynchronizes from the
//   line levels and marks what it sampled meanwhile invalid;
// * illegal transition: an edge on one line at (within simultaneous_ns of) the time of the
//   immediately preceding edge on the other line: both lines changed at once, so the state was
//   skipped and the direction is unknown; the first edge's step is withdrawn (net 0 for the pair).
#include <cstdint>

namespace inertia::hal::gpiod {

enum class EdgeLine : std::uint8_t { A = 0, B = 1, Marker = 2, Trigger = 3 };
inline constexpr std::size_t kEdgeLineCount = 4;

struct EdgeEvent {
  EdgeLine line = EdgeLine::A;
  bool rising = false;
  std::int64_t t_ns = 0;  // CLOCK_MONOTONIC (gpio uAPI v1 since Linux 5.7)
};

struct QuadratureCounters {
  std::uint64_t edges = 0;                 // A/B events seen
  std::uint64_t steps = 0;                 // accepted +-1 steps (withdrawn ones excluded)
  std::uint64_t glitches = 0;
  std::uint64_t illegal_transitions = 0;
  std::uint64_t lost = 0;                  // edges found missing (Outcome::Lost)
};

class QuadratureDecoder {
 public:
  enum class Outcome : std::uint8_t { Step, Glitch, Illegal, Lost };

  explicit QuadratureDecoder(std::int64_t min_edge_interval_ns = 0, std::int64_t simultaneous_ns = 0) noexcept
      : min_edge_interval_ns_(min_edge_interval_ns), simultaneous_ns_(simultaneous_ns) {}

  /// Starts from known line levels (read once when the lines are requested) and a count.
  void reset(bool a, bool b, std::int64_t count = 0) noexcept;
  /// The lines are at these levels (read from the chip after edges were lost): the state is
  /// theirs from here on; the count keeps what it has (the steps lost are not known).
  void resync(bool a, bool b) noexcept { reset(a, b, count_); }

  /// One A or B edge. Real-time safe. Returns what the edge was.
  Outcome on_edge(EdgeLine line, bool rising, std::int64_t t_ns) noexcept;

  [[nodiscard]] std::int64_t count() const noexcept { return count_; }
  [[nodiscard]] bool level(EdgeLine line) const noexcept { return level_[line == EdgeLine::B ? 1 : 0]; }
  [[nodiscard]] const QuadratureCounters& counters() const noexcept { return counters_; }

 private:
  static int state(bool a, bool b) noexcept { return a ? (b ? 2 : 1) : (b ? 3 : 0); }

  std::int64_t min_edge_interval_ns_;
  std::int64_t simultaneous_ns_;
  bool level_[2] = {false, false};
  // Per line: the other line has moved since this line's last edge.
  bool other_moved_[2] = {false, false};
  std::int64_t count_ = 0;
  // The last accepted edge, so that a glitch pulse or a skipped state can withdraw its step.
  bool have_last_ = false;
  int last_line_ = 0;
  int last_step_ = 0;
  std::int64_t last_t_ns_ = 0;
  QuadratureCounters counters_;
};

}  // namespace inertia::hal::gpiod
