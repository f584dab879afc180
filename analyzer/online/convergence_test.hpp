#pragma once
// The online estimator's convergence verdict (docs/live-estimates.md, "Converged";
// OnlineSnapshot::converged): leave-one-out. The estimate without case c against the estimate
// with it; a case the model cannot do without is checked by leaving out groups of its phases
// instead. Run on a stream-time interval (convergence_interval_s) and after every segment's end;
// its verdict is kept in between.
#include <cstddef>
#include <cstdint>
#include <string>

#include "analyzer/online/case_accumulator.hpp"
#include "analyzer/online/live_estimate.hpp"
#include "analyzer/online/live_model.hpp"
#include "analyzer/online/online_estimator.hpp"

namespace inertia::online {

struct ConvergenceTest {
  std::int64_t last_convergence_rows = -1;
  std::size_t last_convergence_cases = 0;
  bool converged = false;
  std::string convergence = "not tested yet";   // the verdict: why not, or the largest leave-one-out z

  /// At most this many leave-outs per case checked by its phases: a long case (a plan repeated for
  /// hours) leaves out contiguous groups of its phases, so the test's cost stays bounded and one
  /// group's move is not lost among thousands of phases.
  static constexpr std::size_t kMaxPhaseGroups = 10;

  /// Tests estimate `s` (published as `out`) when it is due; `estimates` solves it again without
  /// each case or phase group of `statistics`.
  void update(const LiveEstimate& s, const OnlineSnapshot& out, const LiveModel& live, CaseAccumulator& statistics,
              EstimateSolver& estimates);
};

}  // namespace inertia::online
