#include "hal/gpiod/quadrature_decoder.hpp"

namespace inertia::hal::gpiod {

void QuadratureDecoder::reset(bool a, bool b, std::int64_t count) noexcept {
  level_[0] = a;
  level_[1] = b;
  count_ = count;
  have_last_ = false;
  other_moved_[0] = other_moved_[1] = false;
}

QuadratureDecoder::Outcome QuadratureDecoder::on_edge(EdgeLine line, bool rising, std::int64_t t_ns) noexcept {
  ++counters_.edges;
  const int i = line == EdgeLine::B ? 1 : 0;
  if (level_[i] == rising) {
    // No level change: the opposite edge never reached us. Harmless while the other line stood
    // still (the two cancel); after it moved, edges were lost and the count with them.
    if (other_moved_[i]) {
      other_moved_[i] = false;
      have_last_ = false;
      ++counters_.lost;
      return Outcome::Lost;
    }
    ++counters_.glitches;
    return Outcome::Glitch;
  }
  if (have_last_ && last_step_ != 0) {
    const std::int64_t dt = t_ns - last_t_ns_;
    if (last_line_ == i && dt < min_edge_interval_ns_) {
      // A pulse shorter than the minimum interval: undo its first edge, keep the level it had.
      count_ -= last_step_;
      --counters_.steps;
      level_[i] = rising;
      ++counters_.glitches;
      have_last_ = false;
      return Outcome::Glitch;
    }
    if (last_line_ != i && dt <= simultaneous_ns_) {
      // Both lines moved at once: the state in between was skipped, direction unknown.
      count_ -= last_step_;
      --counters_.steps;
      level_[i] = rising;
      ++counters_.illegal_transitions;
      have_last_ = false;
      return Outcome::Illegal;
    }
  }
  const int before = state(level_[0], level_[1]);
  level_[i] = rising;
  const int after = state(level_[0], level_[1]);
  const int step = ((after - before) & 3) == 1 ? 1 : -1;  // one line changed: +-1 only
  count_ += step;
  ++counters_.steps;
  other_moved_[i] = false;
  other_moved_[1 - i] = true;
  have_last_ = true;
  last_line_ = i;
  last_step_ = step;
  last_t_ns_ = t_ns;
  return Outcome::Step;
}

}  // namespace inertia::hal::gpiod
