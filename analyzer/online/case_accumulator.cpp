// The online estimator's statistics per case and mounting (case_accumulator.hpp).
#include "analyzer/online/case_accumulator.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "common/input_error.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Variable;

std::unique_ptr<SegmentPipeline> CaseAccumulator::pipeline(double period) const {
  return std::make_unique<SegmentPipeline>(noise.ar, live.basis->filtered_sources(), live.grid.nodes(), period, live.searched);
}

void CaseAccumulator::add_rows(SegmentPipeline& pipeline, RunStatistics& stats, double period, const Eigen::MatrixXd& x,
                               const Eigen::VectorXd& y, const Eigen::MatrixX3d& inputs,
                               const std::vector<std::uint16_t>& phase, const std::vector<std::int32_t>& plan_phase) const {
  const Index n = y.size();
  const auto cluster_rows = std::max<std::int64_t>(1, std::llround(kClusterS / period));
  for (Index from = 0; from < n;) {
    const auto at = static_cast<std::size_t>(from);
    Index to = from + 1;
    while (to < n && plan_phase[static_cast<std::size_t>(to)] == plan_phase[at] && phase[static_cast<std::size_t>(to)] == phase[at]) ++to;
    Information& info = stats.run_for(plan_phase[at], phase[at], [this] { return live.empty_information(); });
    if (info.runs() > 0) {
      const std::int64_t in_cluster = info.run_samples(info.runs() - 1);
      if (in_cluster >= cluster_rows) info.start_run();
      else to = std::min<Index>(to, from + (cluster_rows - in_cluster));
    }
    pipeline.push(x.middleRows(from, to - from), y.segment(from, to - from), info);
    info.add_inputs(inputs.middleRows(from, to - from));
    from = to;
  }
}

std::string CaseAccumulator::mounting_label(const config::TestCase& tc) const {
  const std::vector<procedure::MountingKey> alone{{tc.name, tc.mounting, tc.kind}};
  const std::vector<procedure::MountingKey>& keys = live.options.plan.empty() ? alone : live.options.plan;
  for (const auto& [label, members] : procedure::group_mountings(keys, live.sensor))
    for (std::size_t i : members)
      if (keys[i].name == tc.name) return label;
  return tc.mounting.empty() ? tc.name : tc.mounting;   // a case the plan does not have
}

std::size_t CaseAccumulator::state_of(std::size_t plan_case, const config::TestCase& tc) {
  for (std::size_t i = 0; i < cases.size(); ++i)
    if (cases[i].plan_case == plan_case) return i;
  const std::string label = mounting_label(tc);
  std::size_t m = mountings.size();
  for (std::size_t i = 0; i < mountings.size(); ++i)
    if (mountings[i].name == label) m = i;
  if (m == mountings.size()) {
    MountingState ms;
    ms.name = label;
    ms.m_cs = live.model_m_cs;
    mountings.push_back(std::move(ms));
  }
  MountingState& ms = mountings[m];
  ms.kind.add_case(tc.kind);
  ms.poses_only = ms.poses_only && (tc.kind == CaseKind::Static || tc.kind == CaseKind::Thermal);
  CaseState cs;
  cs.plan_case = plan_case;
  cs.name = tc.name;
  cs.mounting = m;
  cs.placement_sd_rad = tc.placement_error_rad;
  cases.push_back(std::move(cs));
  ms.cases.push_back(cases.size() - 1);
  return cases.size() - 1;
}

void CaseAccumulator::forget(Index rows) {
  if (!(live.options.forgetting < 1.0)) return;
  const double f = std::pow(live.options.forgetting, static_cast<double>(rows));
  for (CaseState& c : cases) c.stats.scale(f);
  if (open) open->stats.scale(f);
  for (procedure::TermExcitation& e : excitation) e.scale(f);
}

void CaseAccumulator::close_open(bool kept) {
  if (!open) return;
  // The data changed by a whole segment: the next snapshot tests convergence afresh, so the
  // flag after a case's last segment (and at the stream's end) is never up to a second of rows
  // stale.
  segment_closed = true;
  CaseState& c = cases[open->state];
  if (kept) {
    c.stats.add(std::move(open->stats));
    c.rows += open->rows;
  } else {
    // Its rows leave the estimate, and the noise model's window.
    std::erase_if(noise.buffer, [&](const BufferedRows& b) {
      const bool drop = b.state == open->state && b.segment == open->segment;
      if (drop) noise.buffered_rows -= b.y.size();
      return drop;
    });
  }
  open.reset();
}

bool CaseAccumulator::push(const fusion::FusedChunk& chunk, const config::TestCase& tc) {
  const Index n = chunk.rows();
  if (n == 0) return false;
  if (live.basis->reads(Variable::T) && !chunk.temp) {
    throw InputError(fmt::format("case '{}': the model reads T, and the stream has no fixture temperature for it "
                                 "(a [fixture.thermal] controller channel 'temp' or the bench's thermal.channel)",
                                 tc.name));
  }
  const std::size_t state = state_of(chunk.case_index, tc);
  if (chunk.phase_names.size() > cases[state].phase_names.size()) cases[state].phase_names = chunk.phase_names;
  if (!open || open->plan_case != chunk.case_index || open->segment != chunk.segment) {
    close_open(true);   // its end was not announced: what it has counts
    OpenSegment s;
    s.state = state;
    s.plan_case = chunk.case_index;
    s.segment = chunk.segment;
    s.period = chunk.sample_period_s;
    s.pipeline = pipeline(chunk.sample_period_s);
    // Lags of the structure table's candidates beyond the model's own see zeros before the
    // segment's first row, so the model's rows start where the batch starts them.
    const Index pad = live.basis->max_lag() - live.model_max_lag;
    s.history.t = Eigen::VectorXd::Zero(pad);
    s.history.a_e = dataset::Matrix3Columns::Zero(pad, 3);
    s.history.w_e = dataset::Matrix3Columns::Zero(pad, 3);
    s.history.y = Eigen::VectorXd::Zero(pad);
    if (chunk.temp) s.history.temp = Eigen::VectorXd::Constant(pad, (*chunk.temp)(0));
    open = std::move(s);
  }
  forget(n);
  if (chunk.temp && chunk.temp->size() > 0) {
    temp_lo = std::min(temp_lo, chunk.temp->minCoeff());
    temp_hi = std::max(temp_hi, chunk.temp->maxCoeff());
  }
  OpenSegment& seg = *open;
  // The rows in the mounting's nominal case frame, after the kept history.
  dataset::CaseData work;
  work.name = tc.name;
  work.kind = tc.kind;
  work.sample_period_s = chunk.sample_period_s;
  const Index kept = seg.history.y.size();
  const Index total = kept + n;
  work.t.resize(total);
  work.a_e.resize(total, 3);
  work.w_e = dataset::Matrix3Columns(total, 3);
  work.y.resize(total);
  if (chunk.temp) work.temp = Eigen::VectorXd(total);
  if (kept > 0) {
    work.t.head(kept) = seg.history.t;
    work.a_e.topRows(kept) = seg.history.a_e;
    work.w_e->topRows(kept) = *seg.history.w_e;
    work.y.head(kept) = seg.history.y;
    if (work.temp && seg.history.temp) work.temp->head(kept) = *seg.history.temp;
  }
  work.t.tail(n) = chunk.t;
  const frames::Dcm m_ec = config::nominal_m_ec(tc, live.options.unit_axis);
  work.a_e.bottomRows(n) = chunk.a_e * m_ec.transpose();
  work.w_e->bottomRows(n) = chunk.w_e * m_ec.transpose();
  work.y.tail(n) = chunk.y;
  if (work.temp) work.temp->tail(n) = *chunk.temp;
  const Index max_lag = live.basis->max_lag();
  const Index first_row = kept + std::min<Index>(std::max<Index>(0, live.model_max_lag - seg.raw_rows), n);
  seg.raw_rows += n;
  // Keep the newest max_lag rows for the next chunk.
  const Index tail = std::min<Index>(max_lag, total);
  seg.history.t = work.t.tail(tail);
  seg.history.a_e = work.a_e.bottomRows(tail);
  seg.history.w_e = dataset::Matrix3Columns(work.w_e->bottomRows(tail));
  seg.history.y = work.y.tail(tail);
  if (work.temp) seg.history.temp = Eigen::VectorXd(work.temp->tail(tail));
  const Index rows = total - first_row;
  if (rows <= 0) return false;
  if (excitation.empty()) excitation.resize(live.basis->terms().size());
  {
    std::vector<ident::Term> model_terms;
    for (const Index t : live.model) model_terms.push_back(live.basis->terms()[static_cast<std::size_t>(t)]);
    std::vector<procedure::TermExcitation> added(model_terms.size());
    procedure::add_excitation(model_terms, work, Eigen::Matrix3d::Identity(), live.t_ref, first_row, added);
    for (std::size_t i = 0; i < model_terms.size(); ++i) {
      procedure::TermExcitation& tally = excitation[static_cast<std::size_t>(live.model[i])];
      tally.nominal += added[i].nominal;
      tally.full += added[i].full;
    }
  }
  const MountingState& ms = mountings[cases[state].mounting];
  const ident::SignalSet signals = ident::signals_from_case(work, ms.m_cs, live.t_ref, "live stream");
  Eigen::MatrixXd x(rows, live.basis->base_size());
  live.basis->evaluate(signals, first_row, x);
  const Eigen::VectorXd y = work.y.tail(rows);
  const Eigen::MatrixX3d inputs = live.sensor == dataset::SensorKind::Gyroscope ? work.w_e->bottomRows(rows) : work.a_e.bottomRows(rows);
  // The rows' phase labels (a chunk without them is one phase).
  const std::vector<std::uint16_t> phase = chunk.phase.size() == static_cast<std::size_t>(n)
                                               ? std::vector<std::uint16_t>(chunk.phase.end() - rows, chunk.phase.end())
                                               : std::vector<std::uint16_t>(static_cast<std::size_t>(rows), 0);
  const std::vector<std::int32_t> plan_phase =
      chunk.plan_phase.size() == static_cast<std::size_t>(n)
          ? std::vector<std::int32_t>(chunk.plan_phase.end() - rows, chunk.plan_phase.end())
          : std::vector<std::int32_t>(phase.begin(), phase.end());
  if (!noise.fitted) {
    noise.buffer.push_back({state, chunk.case_index, chunk.segment, chunk.sample_period_s, x, y, inputs, phase, plan_phase});
    noise.buffered_rows += rows;
  }
  add_rows(*seg.pipeline, seg.stats, seg.period, x, y, inputs, phase, plan_phase);
  seg.rows += rows;
  rows_total += rows;
  if (nominal_period <= 0.0) nominal_period = chunk.sample_period_s;
  return true;
}

void CaseAccumulator::end_segment(const fusion::SegmentEnd& end) {
  if (open && open->plan_case == end.case_index && open->segment == end.segment) close_open(end.kept);
}

bool CaseAccumulator::open_counts() const {
  return open && open->period > 0.0 && static_cast<double>(open->rows) * open->period >= live.options.min_segment_s;
}

bool CaseAccumulator::has_data(std::size_t c) const {
  return cases[c].stats.samples() > 0 || (open_counts() && open->state == c);
}

std::vector<const RunStatistics::Run*> CaseAccumulator::runs_of(std::size_t c) const {
  std::vector<const RunStatistics::Run*> out;
  for (const RunStatistics::Run& r : cases[c].stats.runs()) out.push_back(&r);
  if (open_counts() && open->state == c)
    for (const RunStatistics::Run& r : open->stats.runs()) out.push_back(&r);
  return out;
}

std::optional<Information> CaseAccumulator::case_information(std::size_t c, const std::optional<LeftOut>& left_out) const {
  if (!has_data(c)) return std::nullopt;
  if (!left_out || left_out->case_index != c) {
    Information out = cases[c].stats.total();
    if (open_counts() && open->state == c) out.add(open->stats.total());
    return out;
  }
  if (!left_out->runs) return std::nullopt;
  // From the runs themselves: taking one out of the sum would leave it among the case
  // scatter's clusters (and cancel large numbers for a small phase).
  Information out;
  const std::vector<const RunStatistics::Run*> runs = runs_of(c);
  for (std::size_t r = 0; r < runs.size(); ++r)
    if (!left_out->leaves(r)) out.add(runs[r]->info, runs[r]->joins_previous && (r == 0 || !left_out->leaves(r - 1)));
  return out;
}

bool CaseAccumulator::every_plan_case_in() const {
  if (live.options.plan.empty()) return false;
  return std::all_of(live.options.plan.begin(), live.options.plan.end(), [&](const procedure::MountingKey& k) {
    for (std::size_t c = 0; c < cases.size(); ++c)
      if (cases[c].name == k.name && has_data(c)) return true;
    return false;
  });
}

bool CaseAccumulator::excited(Index term) const {
  return static_cast<std::size_t>(term) >= excitation.size() || excitation[static_cast<std::size_t>(term)].excited();
}

bool CaseAccumulator::temperature_moved() const { return temp_hi - temp_lo >= procedure::kMinTemperatureSpanC; }

std::size_t CaseAccumulator::cases_with_data() const {
  std::size_t n = 0;
  for (std::size_t c = 0; c < cases.size(); ++c) n += has_data(c) ? 1 : 0;
  return n;
}

}  // namespace inertia::online
