// The online estimator's noise model (live_noise_model.hpp): fitted once on the window's rows.
#include "analyzer/online/live_noise_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>

#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/online/case_accumulator.hpp"
#include "analyzer/online/live_estimate.hpp"
#include "analyzer/online/live_model.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::online {

using Eigen::Index;

std::vector<procedure::CaseRows> noise_pieces(Eigen::VectorXd& residuals, std::vector<procedure::CaseRows> pieces) {
  std::vector<double> power(pieces.size(), 0.0);
  double floor = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    auto e = residuals.segment(pieces[k].begin, pieces[k].rows);
    e.array() -= e.mean();
    power[k] = e.squaredNorm() / static_cast<double>(std::max<Index>(1, e.size()));
    if (e.size() >= kNoiseFloorRows) floor = std::min(floor, power[k]);
  }
  if (!std::isfinite(floor)) return pieces;
  std::vector<procedure::CaseRows> kept;
  for (std::size_t k = 0; k < pieces.size(); ++k)
    if (pieces[k].rows >= kNoiseFloorRows && power[k] <= kNoiseFloorPowerRatio * floor) kept.push_back(pieces[k]);
  return kept;
}

void LiveNoiseModel::fit(LiveModel& live, CaseAccumulator& statistics, EstimateSolver& estimates) {
  fitted = true;
  if (live.options.whitening_max_order <= 0) {
    buffer.clear();
    return;
  }
  // Residuals of the current (white-noise) fit over the kept rows. Every tilt is fitted: an angle
  // held at the nominal frame leaves a misfit that follows the input, which is no noise.
  estimates.hold_unexcited = false;
  LiveEstimate s = estimates.solve(false);
  estimates.hold_unexcited = true;
  if (!s.batch.ok) {
    buffer.clear();
    return;
  }
  std::vector<Index> fitted_terms = s.batch.terms;
  const Eigen::VectorXd coefficients = live.solver->signed_theta(s.batch);
  std::vector<procedure::CaseRows> layout;      // the rows by phase: the noise model's pieces are cut from them
  std::vector<procedure::CaseRows> case_runs;   // by case segment: one noise process each
  std::vector<std::size_t> run_states;           // each case run's case state
  Eigen::VectorXd residuals(buffered_rows);
  Index at = 0;
  std::vector<procedure::HighpassState> hp;
  std::pair<std::size_t, int> current{static_cast<std::size_t>(-1), -1};
  std::int32_t current_phase = 0;
  for (const BufferedRows& b : buffer) {
    Eigen::MatrixXd tb, tf;
    live.basis->transform(fitted_terms, s.m_cs[statistics.cases[b.state].mounting], s.batch.corner_rad_s.has_value(), tb, tf);
    Eigen::VectorXd fit = b.base * (tb.transpose() * coefficients);
    if (s.batch.corner_rad_s) {
      if (current != std::pair{b.state, b.segment}) hp.assign(live.basis->filtered_sources().size(), {});
      Eigen::MatrixXd f(b.base.rows(), live.basis->filtered_size());
      for (Index j = 0; j < f.cols(); ++j) {
        f.col(j) = b.base.col(live.basis->filtered_sources()[static_cast<std::size_t>(j)]);
        procedure::highpass_in_place(f.col(j), *s.batch.corner_rad_s, b.period,
                                     hp[static_cast<std::size_t>(j)]);
      }
      fit += f * (tf.transpose() * coefficients);
    }
    const bool new_run = current != std::pair{b.state, b.segment};
    current = {b.state, b.segment};
    residuals.segment(at, b.y.size()) = b.y - fit;
    if (new_run || case_runs.empty()) {
      case_runs.push_back({case_runs.size(), at, 0, 0});
      run_states.push_back(b.state);
    }
    case_runs.back().rows += b.y.size();
    for (Index i = 0; i < b.y.size(); ++i) {
      const std::int32_t phase = b.plan_phase.empty() ? 0 : b.plan_phase[static_cast<std::size_t>(i)];
      if (layout.empty() || (new_run && i == 0) || phase != current_phase) layout.push_back({layout.size(), at + i, 0, 0});
      current_phase = phase;
      ++layout.back().rows;
    }
    at += b.y.size();
  }
  // The noise model of the variances (a model kept unfiltered: its factor; a whitened one: each
  // case's own noise) reads the whole segments' residual, transitions included, as the batch's
  // inference reads its cases; noise_pieces demeans the pieces it keeps.
  const Eigen::VectorXd case_residuals = residuals;
  layout = noise_pieces(residuals, std::move(layout));
  Index noise_rows = 0;
  for (const procedure::CaseRows& piece : layout) noise_rows += piece.rows;
  // An AR(m) fit wants ten rows per order (ArWhitener::fit): a low-rate bench's window holds fewer.
  const int max_order = std::min<int>(live.options.whitening_max_order, static_cast<int>(noise_rows / 10));
  const procedure::ArWhitener noise = procedure::ArWhitener::fit(residuals, layout, max_order);
  if (!procedure::filters_rows(live.rational)) {
    // The noise model scales the variances instead, by what the batch's sandwich makes of a
    // column constant within each run.
    live.solver->set_long_run_variance_factor(
        procedure::unfiltered_long_run_ratio(case_residuals, case_runs, noise.coefficients()));
    buffer.clear();
    buffered_rows = 0;
    return;
  }
  ar = noise.coefficients();
  // Each case's whitened residual's own noise (its whole segments, transitions included, as the
  // batch's inference reads its cases), for the covariance of its phases' noise sums.
  case_density.assign(statistics.cases.size(), {});
  Index longest = 0;
  for (std::size_t r = 0; r < case_runs.size(); ++r) {
    const procedure::CaseRows& run = case_runs[r];
    if (run.rows <= ar.size()) continue;
    Eigen::VectorXd innovation(run.rows - ar.size());
    procedure::ar_filter(ar, case_residuals.segment(run.begin, run.rows), innovation);
    // Below one cycle per segment the segment's own flicker and random walk, held at their level
    // there: what a case's phases share beyond that is what the batch reads from the plan's
    // static stretches (procedure::StaticNoiseLaw::below_record), held at one cycle per plan.
    // Its level is the fit's residual variance at each solve: the density's shape only, per unit
    // variance (this residual is the white fit's of the rows so far, misfit and all).
    const double lowest = 1.0 / static_cast<double>(innovation.size());
    const std::function<double(double)> shape = [full = noise::fitted_density(innovation).density, lowest](double f) {
      return full(std::max(f, lowest));
    };
    const double variance = noise::spectrum_of(innovation.size(), shape).autocovariance(0);
    if (!(variance > 0.0) || !std::isfinite(variance)) continue;
    std::function<double(double)> fitted = [shape, variance](double f) { return shape(f) / variance; };
    if (run.rows > longest) {
      longest = run.rows;
      density = fitted;
    }
    std::function<double(double)>& own = case_density[run_states[r]];
    if (!own) own = std::move(fitted);   // a case's first segment stands for its others
  }
  // Every row so far again, through the noise model.
  for (CaseAccumulator::CaseState& c : statistics.cases) c.stats.clear();
  std::unique_ptr<SegmentPipeline> p;
  RunStatistics stats;
  current = {static_cast<std::size_t>(-1), -1};
  const auto settle = [&] {
    if (current.first == static_cast<std::size_t>(-1)) return;
    if (statistics.open && statistics.open->state == current.first && statistics.open->segment == current.second) {
      statistics.open->pipeline = std::move(p);
      statistics.open->stats = std::move(stats);   // its rows go on in its last run
    } else {
      statistics.cases[current.first].stats.add(std::move(stats));
    }
    stats = RunStatistics();
  };
  for (const BufferedRows& b : buffer) {
    if (current != std::pair{b.state, b.segment}) {
      settle();
      current = {b.state, b.segment};
      p = statistics.pipeline(b.period);
    }
    statistics.add_rows(*p, stats, b.period, b.base, b.y, b.inputs, b.phase, b.plan_phase);
  }
  settle();
  buffer.clear();
  buffered_rows = 0;
}

}  // namespace inertia::online
