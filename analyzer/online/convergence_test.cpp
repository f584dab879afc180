// The online estimator's convergence test (convergence_test.hpp).
#include "analyzer/online/convergence_test.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

#include <fmt/format.h>

namespace inertia::online {

using Eigen::Index;

namespace {

/// The Bonferroni bound of a two-sided normal test: |z| above it has probability alpha / tests.
double bonferroni_z(double alpha, double tests) {
  // Inverse of the normal tail by bisection on erfc (tests are few; called once per snapshot).
  const double target = alpha / std::max(tests, 1.0);
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (std::erfc(mid / std::numbers::sqrt2) > target) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

/// Leave-one-out: the estimate without case c against the estimate with it. Under the model,
/// theta_without - theta has variance var_without - var (nested estimators), so
/// z = |difference| / sqrt(var_without - var) is standard normal; a case whose z exceeds the
/// Bonferroni bound disagrees with the others, and one more such case would move the estimate.
/// A case without which a term is not determined (a plan with no case to spare: a rotation
/// table's rate series alone gives the centripetal terms, a thermal bench's two poses the bias)
/// is checked by leaving out each of its phases instead; a term that rests on one phase alone
/// is never called converged.
void ConvergenceTest::update(const LiveEstimate& s, const OnlineSnapshot& out, const LiveModel& live,
                             CaseAccumulator& statistics, EstimateSolver& estimates) {
  const auto rate_rows = statistics.nominal_period > 0.0 ? live.options.convergence_interval_s / statistics.nominal_period : 1e4;
  const std::size_t with_data = statistics.cases_with_data();
  // A segment ended since the last test (CaseAccumulator::segment_closed): it runs afresh.
  if (!statistics.segment_closed && last_convergence_rows >= 0 && with_data == last_convergence_cases &&
      static_cast<double>(statistics.rows_total - last_convergence_rows) < rate_rows)
    return;
  statistics.segment_closed = false;
  last_convergence_rows = statistics.rows_total;
  last_convergence_cases = with_data;
  converged = false;
  // Terms the plan cannot determine (no mounting aligned) do not hold the flag back; the
  // verdict says which they are.
  std::string beyond_plan =
      out.plan_undetermined.empty()
          ? std::string()
          : fmt::format("; not determined by this plan ({}): {}",
                        s.aligned ? "every case is in" : "no mounting is aligned", fmt::join(out.plan_undetermined, ", "));
  if (!out.confounded.empty())
    beyond_plan += fmt::format("; left out, constant within each phase with no phase to spare for the offsets between "
                               "them (placement, drift): {}",
                               fmt::join(out.confounded, ", "));
  if (!out.insignificant.empty())
    beyond_plan += fmt::format("; left out, not significant: {}", fmt::join(out.insignificant, ", "));
  const std::size_t beyond = out.plan_undetermined.size() + out.confounded.size() + out.insignificant.size();
  if (out.undetermined.size() > beyond) {
    convergence = fmt::format("{} term(s) not determined yet{}", out.undetermined.size() - beyond, beyond_plan);
    return;
  }
  // A plan of one case is checked by its phases (below), once it is in.
  if (with_data < 2 && !statistics.every_plan_case_in()) {
    convergence = "one case so far: nothing to check it against" + beyond_plan;
    return;
  }
  // Each case left out in turn; a case the model cannot do without (a minimal plan) is checked
  // by its phases instead: with no case to spare, the case's own runs are the replicates.
  double worst = 0.0;
  std::string worst_at;
  std::size_t units = 0;
  // The estimate without `left_out`: the first model term it does not determine, or none (then
  // its moves are in worst).
  const auto compare = [&](const LeftOut& left_out, const std::string& where) -> std::optional<std::string> {
    // The batch again without it, each mounting keeping its M_C^S and its uncertainty
    // (re-running algorithm 1 without a case would break the procedure's own structure: a
    // shaker fixture left without the mounting that gives it the bias, an orientation missing
    // that separated a tilt from the cross-couplings).
    const LiveEstimate without = estimates.solve(false, left_out, &s.m_cs, &s.angle_covariances, &s.held_angles, &s);
    if (!without.batch.ok) return std::string("the model");
    for (std::size_t j = 0; j < live.model.size(); ++j) {
      const std::string name = live.model_terms[j].to_string();
      if (std::find(out.plan_undetermined.begin(), out.plan_undetermined.end(), name) != out.plan_undetermined.end() ||
          std::find(out.confounded.begin(), out.confounded.end(), name) != out.confounded.end() ||
          std::find(out.insignificant.begin(), out.insignificant.end(), name) != out.insignificant.end())
        continue;
      std::optional<Index> a, b;
      for (std::size_t k = 0; k < s.batch.terms.size(); ++k)
        if (s.batch.terms[k] == live.model[j]) a = static_cast<Index>(k);
      for (std::size_t k = 0; k < without.batch.terms.size(); ++k)
        if (without.batch.terms[k] == live.model[j]) b = static_cast<Index>(k);
      if (!a || !b) return "term " + name;
      // Nested estimators: theta - theta_without has variance var_without - var <= var_without,
      // so measuring the move in sd_without is conservative (and needs no difference of
      // variances, which the misalignment's share makes fragile). Fewer rows never know more:
      // where the rows left read less case scatter than all of them (the sd without below the
      // sd with), the scale is the sd with.
      const double z = std::abs(without.batch.theta(*b) - s.batch.theta(*a)) /
                       std::max(without.batch.sd(*b), s.batch.sd(*a));
      if (z > worst) {
        worst = z;
        worst_at = fmt::format("{} without {}", name, where);
      }
    }
    ++units;
    return std::nullopt;
  };
  for (std::size_t c = 0; c < statistics.cases.size(); ++c) {
    if (!statistics.has_data(c)) continue;
    const std::optional<std::string> missing = compare({c, std::nullopt}, "case " + statistics.cases[c].name);
    if (!missing) continue;
    const std::vector<const RunStatistics::Run*> runs = statistics.runs_of(c);
    std::size_t with_rows = 0;
    for (const RunStatistics::Run* r : runs) with_rows += r->info.samples() > 0 ? 1 : 0;
    if (with_rows < 2) {
      convergence = fmt::format("without case {} {} is not determined, and the case has one phase to check it "
                                "by{}",
                                statistics.cases[c].name, *missing, beyond_plan);
      return;
    }
    const std::size_t groups = std::min(runs.size(), kMaxPhaseGroups);
    for (std::size_t g = 0; g < groups; ++g) {
      const std::size_t first = g * runs.size() / groups, last = (g + 1) * runs.size() / groups;
      std::int64_t rows = 0;
      for (std::size_t r = first; r < last; ++r) rows += runs[r]->info.samples();
      if (rows == 0) continue;
      const auto name = [&](std::size_t r) {
        const auto label = static_cast<std::size_t>(runs[r]->label);
        return fmt::format("{} ({})", runs[r]->phase,
                           label < statistics.cases[c].phase_names.size() ? statistics.cases[c].phase_names[label] : "unlabelled");
      };
      const std::string where = last - first == 1
                                    ? fmt::format("phase {} of case {}", name(first), statistics.cases[c].name)
                                    : fmt::format("phases {} to {} of case {}", name(first), name(last - 1), statistics.cases[c].name);
      if (const std::optional<std::string> rests = compare({c, std::pair{first, last}}, where)) {
        convergence = fmt::format("without case {} {} is not determined, nor without its {}: it rests on {}{}",
                                  statistics.cases[c].name, *missing, where, last - first == 1 ? "one phase" : "those phases",
                                  beyond_plan);
        return;
      }
    }
  }
  const double z_bound = bonferroni_z(live.options.convergence_alpha, static_cast<double>(units * s.batch.terms.size()));
  converged = worst <= z_bound;
  convergence = fmt::format("largest leave-one-out z {:.2f} ({}), bound {:.2f}{}", worst, worst_at, z_bound, beyond_plan);
}

}  // namespace inertia::online
