#pragma once
// The test plan's markers as the stream assembler has received them (stream_assembler.hpp): per
// case its start, its end (or abort) and its phases' starts and planned ends, from the
// INERTIA_EVENT messages. It answers which case a row at a given time belongs to, and whether
// the markers still to come could change that or the row's phase, so that a row waits for its
// markers and no longer.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "inertia/plan_event_t.hpp"

namespace inertia::fusion {

struct PhaseMark {
  double start_ns;
  double end_ns;           // planned end (0: open-ended)
  std::int32_t phase_index;
  std::string label;
};

struct CaseMarks {
  std::size_t case_index = 0;
  std::string name;
  double start_ns = 0.0;
  double last_ns = 0.0;    // last sample (inclusive); valid when ended
  bool ended = false;
  bool aborted = false;
  std::vector<PhaseMark> phases;
};

struct PlanMarks {
  std::deque<CaseMarks> cases;   // in marker order; finished ones are removed (a deque: SegmentBuilder points into it)
  double newest_ns = -std::numeric_limits<double>::infinity();   // the newest marker's time
  bool saw_case_marker = false;

  /// One marker of the plan's case `index` (into the bench's cases). A case start ends the case
  /// still open one output sample (`period_ns`) before it; markers out of place are noted and ignored.
  void add(const plan_event_t& ev, std::size_t index, double period_ns, const std::string& where,
           std::vector<std::string>& notes);

  /// The case a row at t belongs to; nullptr when none. `ready` false when markers still to come
  /// could change the answer (`given_up`: they are no longer waited for at t).
  CaseMarks* case_of(double t, double half, bool given_up, bool& ready);

  /// Whether the phase of a row at t in case c is settled: a later marker arrived, the phase's
  /// planned end lies beyond t, or the markers are given up on.
  [[nodiscard]] bool phase_settled(const CaseMarks& c, double t, double half, bool given_up) const;
};

}  // namespace inertia::fusion
