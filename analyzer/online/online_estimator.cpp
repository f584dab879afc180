#include "analyzer/online/online_estimator.hpp"

#include "analyzer/ident/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "analyzer/diagnose/candidate_library.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/input_error.hpp"

namespace inertia::online {

using Eigen::Index;
using ident::Term;
using ident::Variable;

namespace {

Term product(Variable a, Variable b) { return Term::from_factors({ident::Factor{a}, ident::Factor{b}}); }

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

struct OnlineEstimator::Impl {
  dataset::SensorKind sensor;
  double t_ref;
  OnlineOptions options;
  std::vector<Term> model_terms;
  frames::Dcm model_m_cs = frames::Dcm::Identity();
  std::unique_ptr<LiveBasis> basis;
  std::unique_ptr<LiveSolver> solver;
  std::vector<Index> frame_free_model;   // the model's frame-free terms: what is fitted with no mounting aligned
  std::vector<Index> model, candidates;
  CornerGrid grid;   // the squares' corner: the model's, or the nodes it is interpolated on
  bool rational = false;
  Index model_max_lag = 0;

  struct CaseState {
    std::size_t plan_case = 0;
    std::string name;
    std::size_t mounting = 0;
    RunStatistics stats;
    std::vector<std::string> phase_names;   // the stream's, for the run labels
    std::int64_t rows = 0;
  };
  struct MountingState {
    std::string name;
    std::vector<std::size_t> cases;
    procedure::MountingKind kind;
    bool poses_only = true;   // static and thermal cases only: its tilts are read from the poses' levels
    frames::Dcm m_cs = frames::Dcm::Identity();
    MountingFit fit;
  };
  struct OpenSegment {
    std::size_t state = 0;
    std::size_t plan_case = 0;
    int segment = 0;
    double period = 0.0;
    std::unique_ptr<SegmentPipeline> pipeline;
    RunStatistics stats;
    dataset::CaseData history;   // the last max_lag rows (case frame), for lagged columns
    std::int64_t rows = 0;       // rows into the statistics
    std::int64_t raw_rows = 0;   // rows received
  };
  struct Buffered {
    std::size_t state = 0;
    std::size_t plan_case = 0;
    int segment = 0;
    double period = 0.0;
    Eigen::MatrixXd base;
    Eigen::VectorXd y;
    Eigen::MatrixX3d inputs;   // along the case axes (Information::add_inputs)
    std::vector<std::uint16_t> phase;   // per row: the chunk's phase label
    std::vector<std::int32_t> plan_phase;   // per row: the plan's phase index
  };

  std::vector<CaseState> cases;
  std::vector<MountingState> mountings;
  std::optional<OpenSegment> open;
  std::vector<Buffered> buffer;
  std::int64_t buffered_rows = 0;
  bool noise_fitted = false;
  // The fixture temperature's range over the rows pushed (temperature_moved()).
  double temp_lo = std::numeric_limits<double>::infinity(), temp_hi = -std::numeric_limits<double>::infinity();
  bool hold_unexcited = true;   // MountingStatistics::hold_unexcited of the next solve()
  Eigen::VectorXd ar;
  std::int64_t rows_total = 0;
  double nominal_period = 0.0;

  // The convergence test runs on a stream-time interval; its verdict is kept in between.
  std::int64_t last_convergence_rows = -1;
  std::size_t last_convergence_cases = 0;
  bool converged = false;
  std::string convergence = "not tested yet";

  [[nodiscard]] Information empty_information() const {
    return Information(basis->base_size(), basis->filtered_size(), grid.nodes().size());
  }

  std::unique_ptr<SegmentPipeline> pipeline(double period) const {
    return std::make_unique<SegmentPipeline>(ar, basis->filtered_sources(), grid.nodes(), period);
  }

  /// The longest stretch of a phase that is one cluster of the case scatter. Slow noise (1/f,
  /// drift) moves a minute's rows together; cut into minutes, a thermal step's offsets carry it
  /// into the sd of what varies within the step (its T terms), which the whole step's offset
  /// cannot. Shorter than every phase of the shipped benches but the thermal ones.
  static constexpr double kClusterS = 60.0;

  /// Rows of one segment through its noise pipeline into `stats`, a new run where the plan's phase
  /// changes, a new cluster after every kClusterS of it.
  void add_rows(SegmentPipeline& pipeline, RunStatistics& stats, double period, const Eigen::MatrixXd& x,
                const Eigen::VectorXd& y, const Eigen::MatrixX3d& inputs, const std::vector<std::uint16_t>& phase,
                const std::vector<std::int32_t>& plan_phase) const {
    const Index n = y.size();
    const auto cluster_rows = std::max<std::int64_t>(1, std::llround(kClusterS / period));
    for (Index from = 0; from < n;) {
      const auto at = static_cast<std::size_t>(from);
      Index to = from + 1;
      while (to < n && plan_phase[static_cast<std::size_t>(to)] == plan_phase[at] && phase[static_cast<std::size_t>(to)] == phase[at]) ++to;
      Information& info = stats.run_for(plan_phase[at], phase[at], [this] { return empty_information(); });
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

  /// The mounting case `tc` belongs to: the batch's grouping of the plan (or of `tc` alone).
  [[nodiscard]] std::string mounting_label(const config::TestCase& tc) const {
    const std::vector<procedure::MountingKey> alone{{tc.name, tc.mounting, tc.kind}};
    const std::vector<procedure::MountingKey>& keys = options.plan.empty() ? alone : options.plan;
    for (const auto& [label, members] : procedure::group_mountings(keys, sensor))
      for (std::size_t i : members)
        if (keys[i].name == tc.name) return label;
    return tc.mounting.empty() ? tc.name : tc.mounting;   // a case the plan does not have
  }

  std::size_t state_of(std::size_t plan_case, const config::TestCase& tc) {
    for (std::size_t i = 0; i < cases.size(); ++i)
      if (cases[i].plan_case == plan_case) return i;
    const std::string label = mounting_label(tc);
    std::size_t m = mountings.size();
    for (std::size_t i = 0; i < mountings.size(); ++i)
      if (mountings[i].name == label) m = i;
    if (m == mountings.size()) {
      MountingState ms;
      ms.name = label;
      ms.m_cs = model_m_cs;
      mountings.push_back(std::move(ms));
    }
    MountingState& ms = mountings[m];
    ms.kind.add_case(tc.kind);
    ms.poses_only = ms.poses_only && (tc.kind == CaseKind::Static || tc.kind == CaseKind::Thermal);
    CaseState cs;
    cs.plan_case = plan_case;
    cs.name = tc.name;
    cs.mounting = m;
    cases.push_back(std::move(cs));
    ms.cases.push_back(cases.size() - 1);
    return cases.size() - 1;
  }

  void forget(Index rows) {
    if (!(options.forgetting < 1.0)) return;
    const double f = std::pow(options.forgetting, static_cast<double>(rows));
    for (CaseState& c : cases) c.stats.scale(f);
    if (open) open->stats.scale(f);
  }

  void close_open(bool kept) {
    if (!open) return;
    // The data changed by a whole segment: the next snapshot tests convergence afresh, so the
    // flag after a case's last segment (and at the stream's end) is never up to a second of rows
    // stale.
    last_convergence_rows = -1;
    CaseState& c = cases[open->state];
    if (kept) {
      c.stats.add(std::move(open->stats));
      c.rows += open->rows;
    } else {
      // Its rows leave the estimate, and the noise model's window.
      std::erase_if(buffer, [&](const Buffered& b) {
        const bool drop = b.state == open->state && b.segment == open->segment;
        if (drop) buffered_rows -= b.y.size();
        return drop;
      });
    }
    open.reset();
  }

  void push(const fusion::FusedChunk& chunk, const config::TestCase& tc) {
    const Index n = chunk.rows();
    if (n == 0) return;
    if (basis->reads(Variable::T) && !chunk.temp) {
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
      const Index pad = basis->max_lag() - model_max_lag;
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
    work.a_e.bottomRows(n) = chunk.a_e * tc.m_ec.transpose();
    work.w_e->bottomRows(n) = chunk.w_e * tc.m_ec.transpose();
    work.y.tail(n) = chunk.y;
    if (work.temp) work.temp->tail(n) = *chunk.temp;
    const Index max_lag = basis->max_lag();
    const Index first_row = kept + std::min<Index>(std::max<Index>(0, model_max_lag - seg.raw_rows), n);
    seg.raw_rows += n;
    // Keep the newest max_lag rows for the next chunk.
    const Index tail = std::min<Index>(max_lag, total);
    seg.history.t = work.t.tail(tail);
    seg.history.a_e = work.a_e.bottomRows(tail);
    seg.history.w_e = dataset::Matrix3Columns(work.w_e->bottomRows(tail));
    seg.history.y = work.y.tail(tail);
    if (work.temp) seg.history.temp = Eigen::VectorXd(work.temp->tail(tail));
    const Index rows = total - first_row;
    if (rows <= 0) return;
    const MountingState& ms = mountings[cases[state].mounting];
    const ident::SignalSet signals = ident::signals_from_case(work, ms.m_cs, t_ref, "live stream");
    Eigen::MatrixXd x(rows, basis->base_size());
    basis->evaluate(signals, first_row, x);
    const Eigen::VectorXd y = work.y.tail(rows);
    const Eigen::MatrixX3d inputs = sensor == dataset::SensorKind::Gyroscope ? work.w_e->bottomRows(rows) : work.a_e.bottomRows(rows);
    // The rows' phase labels (a chunk without them is one phase).
    const std::vector<std::uint16_t> phase = chunk.phase.size() == static_cast<std::size_t>(n)
                                                 ? std::vector<std::uint16_t>(chunk.phase.end() - rows, chunk.phase.end())
                                                 : std::vector<std::uint16_t>(static_cast<std::size_t>(rows), 0);
    const std::vector<std::int32_t> plan_phase =
        chunk.plan_phase.size() == static_cast<std::size_t>(n)
            ? std::vector<std::int32_t>(chunk.plan_phase.end() - rows, chunk.plan_phase.end())
            : std::vector<std::int32_t>(phase.begin(), phase.end());
    if (!noise_fitted) {
      buffer.push_back({state, chunk.case_index, chunk.segment, chunk.sample_period_s, x, y, inputs, phase, plan_phase});
      buffered_rows += rows;
    }
    add_rows(*seg.pipeline, seg.stats, seg.period, x, y, inputs, phase, plan_phase);
    seg.rows += rows;
    rows_total += rows;
    if (nominal_period <= 0.0) nominal_period = chunk.sample_period_s;
    if (!noise_fitted && static_cast<double>(buffered_rows) * chunk.sample_period_s >= options.noise_window_s) fit_noise_model();
  }

  void end_segment(const fusion::SegmentEnd& end) {
    if (open && open->plan_case == end.case_index && open->segment == end.segment) close_open(end.kept);
  }

  // ---- The noise model ----

  void fit_noise_model() {
    noise_fitted = true;
    if (options.whitening_max_order <= 0) {
      buffer.clear();
      return;
    }
    // Residuals of the current (white-noise) fit over the kept rows. Every tilt is fitted: an angle
    // held at the nominal frame leaves a misfit that follows the input, which is no noise.
    hold_unexcited = false;
    Solution s = solve(false);
    hold_unexcited = true;
    if (!s.batch.ok) {
      buffer.clear();
      return;
    }
    std::vector<Index> fitted = s.batch.terms;
    const Eigen::VectorXd predicting = s.batch.theta.cwiseProduct(solver->prediction_signs(fitted));
    std::vector<procedure::CaseRows> layout;
    Eigen::VectorXd residuals(buffered_rows);
    Index at = 0;
    std::vector<procedure::HighpassState> hp;
    std::pair<std::size_t, int> current{static_cast<std::size_t>(-1), -1};
    for (const Buffered& b : buffer) {
      Eigen::MatrixXd tb, tf;
      basis->transform(fitted, s.m_cs[cases[b.state].mounting], s.batch.corner_rad_s.has_value(), tb, tf);
      Eigen::VectorXd fit = b.base * (tb.transpose() * predicting);
      if (s.batch.corner_rad_s) {
        if (current != std::pair{b.state, b.segment}) hp.assign(basis->filtered_sources().size(), {});
        Eigen::MatrixXd f(b.base.rows(), basis->filtered_size());
        for (Index j = 0; j < f.cols(); ++j) {
          f.col(j) = b.base.col(basis->filtered_sources()[static_cast<std::size_t>(j)]);
          procedure::highpass_in_place(f.col(j), *s.batch.corner_rad_s, b.period,
                                       hp[static_cast<std::size_t>(j)]);
        }
        fit += f * (tf.transpose() * predicting);
      }
      if (current != std::pair{b.state, b.segment}) {
        layout.push_back({layout.size(), at, 0, 0});
        current = {b.state, b.segment};
      }
      residuals.segment(at, b.y.size()) = b.y - fit;
      layout.back().rows += b.y.size();
      at += b.y.size();
    }
    // An AR(m) fit wants ten rows per order (ArWhitener::fit): a low-rate bench's window holds fewer.
    const int max_order = std::min<int>(options.whitening_max_order, static_cast<int>(residuals.size() / 10));
    const procedure::ArWhitener noise = procedure::ArWhitener::fit(residuals, layout, max_order);
    if (rational) {
      // ULS's correction is derived for white equation errors, so the rows stay unfiltered; the
      // noise model scales the variances instead: by the residual's long-run variance (its
      // spectrum at zero, innovation variance / A(1)^2) over its variance. Exact for columns
      // constant over the noise's memory (rate phases, poses), conservative for faster ones under
      // noise whose spectrum falls with frequency (the sensors' 1/f, brown, AR with a positive pole).
      const double gain = 1.0 - noise.coefficients().sum();
      if (gain > 0.0) {
        solver->set_long_run_variance_factor(std::max(1.0, noise.variance_ratio() / (gain * gain)));
      }
      buffer.clear();
      buffered_rows = 0;
      return;
    }
    ar = noise.coefficients();
    // Every row so far again, through the noise model.
    for (CaseState& c : cases) c.stats.clear();
    std::unique_ptr<SegmentPipeline> p;
    RunStatistics stats;
    current = {static_cast<std::size_t>(-1), -1};
    const auto settle = [&] {
      if (current.first == static_cast<std::size_t>(-1)) return;
      if (open && open->state == current.first && open->segment == current.second) {
        open->pipeline = std::move(p);
        open->stats = std::move(stats);   // its rows go on in its last run
      } else {
        cases[current.first].stats.add(std::move(stats));
      }
      stats = RunStatistics();
    };
    for (const Buffered& b : buffer) {
      if (current != std::pair{b.state, b.segment}) {
        settle();
        current = {b.state, b.segment};
        p = pipeline(b.period);
      }
      add_rows(*p, stats, b.period, b.base, b.y, b.inputs, b.phase, b.plan_phase);
    }
    settle();
    buffer.clear();
    buffered_rows = 0;
  }

  // ---- The answer ----

  struct Solution {
    std::vector<std::size_t> order;          // mountings in fit order
    std::vector<Information> infos;          // per mounting
    std::vector<Eigen::Matrix3d> m_cs;       // per mounting, as the batch used it
    std::vector<Eigen::Matrix3d> angle_covariances;
    StatFit batch;
    CaseScatter scatter;
    bool aligned = true;                     // some mounting aligned (else the frame-free terms only)
    std::vector<Index> model;                // the terms the batch fitted (the solver's model)
    std::vector<Index> confounded;           // left out: at the phases' level, with no phase to spare
    int level_parameters = -1;               // fitted at the level of the phases' means (case scatter's dof)
  };

  [[nodiscard]] bool open_counts() const {
    return open && open->period > 0.0 && static_cast<double>(open->rows) * open->period >= options.min_segment_s;
  }

  /// Whether case c has rows in the estimate (kept ones, or an open segment long enough to count).
  [[nodiscard]] bool has_data(std::size_t c) const {
    return cases[c].stats.samples() > 0 || (open_counts() && open->state == c);
  }

  /// What the convergence test leaves out: a case, or runs [first, last) of it (its phases).
  struct LeftOut {
    std::size_t case_index = 0;
    std::optional<std::pair<std::size_t, std::size_t>> runs;   // into runs_of(case_index)
    [[nodiscard]] bool leaves(std::size_t r) const { return runs && r >= runs->first && r < runs->second; }
  };
  /// At most this many leave-outs per case checked by its phases: a long case (a plan repeated for
  /// hours) leaves out contiguous groups of its phases, so the test's cost stays bounded and one
  /// group's move is not lost among thousands of phases.
  static constexpr std::size_t kMaxPhaseGroups = 10;

  /// Case c's runs, the open segment's included while it counts.
  [[nodiscard]] std::vector<const RunStatistics::Run*> runs_of(std::size_t c) const {
    std::vector<const RunStatistics::Run*> out;
    for (const RunStatistics::Run& r : cases[c].stats.runs()) out.push_back(&r);
    if (open_counts() && open->state == c)
      for (const RunStatistics::Run& r : open->stats.runs()) out.push_back(&r);
    return out;
  }

  /// Case c's statistics as the estimate reads them, `left_out`'s run taken out when it is c's
  /// (nullopt: the case is left out, or has no rows in the estimate).
  [[nodiscard]] std::optional<Information> case_information(std::size_t c, const std::optional<LeftOut>& left_out) const {
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
  /// Whether every case of the plan has rows in the estimate.
  [[nodiscard]] bool every_plan_case_in() const {
    if (options.plan.empty()) return false;
    return std::all_of(options.plan.begin(), options.plan.end(), [&](const procedure::MountingKey& k) {
      for (std::size_t c = 0; c < cases.size(); ++c)
        if (cases[c].name == k.name && has_data(c)) return true;
      return false;
    });
  }
  /// ... and none is still running (its next phase may determine more): what is not determined
  /// then, the plan does not determine.
  [[nodiscard]] bool whole_plan_in() const { return every_plan_case_in() && !open; }

  /// Whether the fixture temperature has moved enough for its terms (the batch's rule).
  [[nodiscard]] bool temperature_moved() const { return temp_hi - temp_lo >= procedure::kMinTemperatureSpanC; }

  /// The solver for what the rows so far can determine: terms of the temperature wait until it
  /// has moved (a near-constant T column stands in for the bias, and y*T for the output itself).
  [[nodiscard]] LiveSolver active_solver(const std::vector<Index>& terms) const {
    if (temperature_moved()) return solver->with_model(terms);
    std::vector<Index> kept;
    for (Index t : terms)
      if (!basis->terms()[static_cast<std::size_t>(t)].uses(Variable::T)) kept.push_back(t);
    return solver->with_model(std::move(kept));
  }

  [[nodiscard]] std::size_t cases_with_data() const {
    std::size_t n = 0;
    for (std::size_t c = 0; c < cases.size(); ++c) n += has_data(c) ? 1 : 0;
    return n;
  }

  /// Blocks 5-6 per mounting and the batch; `left_out`: a case or a run left out, `fixed_m_cs`: the
  /// mountings' misalignments to use instead of estimating them (the convergence test).
  Solution solve(bool update_states, const std::optional<LeftOut>& left_out = std::nullopt,
                 const std::vector<Eigen::Matrix3d>* fixed_m_cs = nullptr,
                 const std::vector<Eigen::Matrix3d>* fixed_angle_covariances = nullptr,
                 const Solution* fixed_from = nullptr) {
    Solution s;
    s.infos.assign(mountings.size(), empty_information());
    for (std::size_t c = 0; c < cases.size(); ++c)
      if (const std::optional<Information> info = case_information(c, left_out)) s.infos[cases[c].mounting].add(*info);
    // The mounting rules' order (procedure/mounting_rules.hpp), as the batch takes them.
    {
      std::vector<procedure::MountingKind> kinds;
      for (const MountingState& ms : mountings) kinds.push_back(ms.kind);
      s.order = procedure::mounting_order(kinds);
    }
    if (fixed_m_cs != nullptr) {
      s.m_cs = *fixed_m_cs;
      std::vector<const Information*> infos;
      for (const Information& i : s.infos) infos.push_back(&i);
      // The terms the full solution determined (what it dropped or could not determine stays out:
      // of three squares that sum to one with the bias, which one goes is rounding's choice) and
      // its count of phase-level parameters.
      const LiveSolver batch_solver = fixed_from != nullptr ? solver->with_model(fixed_from->batch.terms) : *solver;
      s.aligned = fixed_from == nullptr || fixed_from->aligned;
      s.model = batch_solver.model();
      s.batch = batch_solver.fit_batch(infos, s.m_cs);
      if (fixed_angle_covariances != nullptr) batch_solver.add_misalignment_uncertainty(s.batch, infos, s.m_cs, *fixed_angle_covariances);
      const CaseStatistics cs = case_statistics(s.m_cs, left_out);
      if (s.batch.ok) s.level_parameters = level_parameters(s.batch, batch_solver, cs, nullptr);
      add_case_scatter(s, cs, batch_solver);
      return s;
    }
    const LiveSolver active = active_solver(model);
    std::optional<double> bias;
    std::vector<MountingFit> fits(mountings.size());
    for (std::size_t m : s.order) {
      MountingStatistics d;
      d.name = mountings[m].name;
      d.info = s.infos[m];
      d.kind = mountings[m].kind;
      // Algorithm 1 starts where the batch starts it, every time: a start from an earlier, less
      // determined estimate (one orientation so far) can lead the fixed point elsewhere.
      d.m_cs = model_m_cs;
      d.hold_unexcited = hold_unexcited;
      fits[m] = active.fit_mounting(d, procedure::takes_bias(d.kind, options.solver.ieee_1293) ? bias : std::nullopt);
      if (!bias && procedure::hands_on_bias(d.kind) && fits[m].bias) bias = fits[m].bias;
    }
    // A mounting whose data does not fix its misalignment keeps the nominal frame (the batch's
    // rule: another mounting's M_C^S is another fixture's), within the mounting tolerance.
    std::optional<std::size_t> reference;
    for (std::size_t m : s.order)
      if (fits[m].determined && !reference) reference = m;
    // With none aligned, the sensor frame's p and o axes are not known in any case: only the
    // terms that hold in any frame near it are fitted (procedure::frame_free), as in the batch.
    const LiveSolver batch_solver = reference ? active : active_solver(frame_free_model);
    std::vector<const Information*> infos;
    std::vector<Eigen::Matrix3d> m_cs;
    for (std::size_t m = 0; m < mountings.size(); ++m) {
      infos.push_back(&s.infos[m]);
      m_cs.push_back(fits[m].m_cs);
      if (update_states) {
        if (fits[m].determined) mountings[m].m_cs = fits[m].m_cs;
        mountings[m].fit = fits[m];
      }
    }
    s.batch = batch_solver.fit_batch(infos, m_cs);
    // The twists about n_i against the reference, as the batch pipeline finds them (at the corner
    // found first, which the pipeline keeps).
    std::vector<RelativeTurn> turns(mountings.size());
    if (reference && s.batch.ok) {
      std::vector<bool> aligned(fits.size());
      for (std::size_t m = 0; m < fits.size(); ++m) aligned[m] = fits[m].determined;
      turns = active.relative_turns(infos, m_cs, *reference, aligned, s.batch.corner_rad_s);
      if (std::any_of(turns.begin(), turns.end(), [](const RelativeTurn& t) { return t.estimated; }))
        s.batch = active.fit_batch_at(infos, m_cs, s.batch.corner_rad_s);
    }
    std::vector<Eigen::Matrix3d> angle_covariances;
    for (std::size_t m = 0; m < mountings.size(); ++m) {
      Eigen::Matrix3d c = fits[m].angles_covariance;   // a held angle: the tolerance
      if (turns[m].estimated) {
        c = turns[m].covariance;
        // The tilts as algorithm 1 reads them (of n_i alone); about i the twist found.
        MountingFit& f = fits[m];
        f.m_cs = m_cs[m];
        f.angles = procedure::rotation_vector(
            procedure::misalignment_from_sensitivities(m_cs[m].row(0).transpose(), frames::Dcm::Identity()));
        f.angles(0) = turns[m].twist_rad;
        f.angles_covariance = c;
        f.angles_sd = c.diagonal().cwiseMax(0.0).cwiseSqrt();
        if (update_states) {
          mountings[m].m_cs = f.m_cs;
          mountings[m].fit = f;
        }
      }
      if (turns[m].held) c += turns[m].covariance;
      angle_covariances.push_back(c);
    }
    const CaseStatistics cs = case_statistics(m_cs, left_out);
    const LiveSolver fitted = drop_confounded(s, batch_solver, infos, m_cs, cs, fits);
    fitted.add_misalignment_uncertainty(s.batch, infos, m_cs, angle_covariances);
    add_case_scatter(s, cs, fitted);
    s.model = fitted.model();
    s.aligned = reference.has_value();
    s.m_cs = std::move(m_cs);
    s.angle_covariances = std::move(angle_covariances);
    return s;
  }

  /// Each case's statistics (the open segment's included) and its mounting's M_C^S.
  struct CaseStatistics {
    std::vector<Information> with_open;
    std::vector<const Information*> infos;
    std::vector<Eigen::Matrix3d> m_cs;
  };
  [[nodiscard]] CaseStatistics case_statistics(const std::vector<Eigen::Matrix3d>& m_cs,
                                               const std::optional<LeftOut>& left_out) const {
    CaseStatistics out;
    out.with_open.reserve(cases.size());
    for (std::size_t c = 0; c < cases.size(); ++c) {
      std::optional<Information> info = case_information(c, left_out);
      if (!info) continue;
      out.with_open.push_back(std::move(*info));
      out.m_cs.push_back(m_cs[cases[c].mounting]);
    }
    for (const Information& i : out.with_open) out.infos.push_back(&i);
    return out;
  }

  /// Parameters fitted at the level of the phases' means: the terms constant within every phase,
  /// and the tilts of mountings read from poses (static and thermal cases: from the poses' levels).
  [[nodiscard]] int level_parameters(const StatFit& batch, const LiveSolver& batch_solver, const CaseStatistics& cs,
                                     const std::vector<MountingFit>* fits) const {
    int n = static_cast<int>(batch_solver.phase_level_terms(batch, cs.infos, cs.m_cs, 1.0 - ar.sum()).size());
    for (std::size_t m = 0; m < mountings.size(); ++m) {
      const bool determined = fits != nullptr ? (*fits)[m].determined : mountings[m].fit.determined;
      if (mountings[m].poses_only && determined) n += 2;
    }
    return n;
  }

  /// The cases' offsets the noise model does not explain, into the batch's covariance.
  void add_case_scatter(Solution& s, const CaseStatistics& cs, const LiveSolver& batch_solver) {
    s.scatter = batch_solver.add_case_scatter(s.batch, cs.infos, cs.m_cs, 1.0 - ar.sum(), s.level_parameters);
  }

  /// Terms at the level of the phases' means (constant within every phase: a tumble's poses) are
  /// told from the phases' offsets (a pose's placement) only by the phases left over. As the
  /// batch's honest inference: the weakest such term is left out while none are left over, or while
  /// its t, with the offsets' scatter in its sd, fails Student's test on that many degrees of freedom
  /// (Bonferroni over those terms). Never the bias or the scale factor. Refits s.batch with what is
  /// left; returns the solver of that model.
  LiveSolver drop_confounded(Solution& s, const LiveSolver& batch_solver, const std::vector<const Information*>& infos,
                             const std::vector<Eigen::Matrix3d>& m_cs, const CaseStatistics& cs,
                             const std::vector<MountingFit>& fits) {
    std::optional<LiveSolver> current(batch_solver);
    const Index axis = basis->find(plain_term(sensor == dataset::SensorKind::Gyroscope ? Variable::Wi : Variable::Ai));
    const double gain = 1.0 - ar.sum();
    int runs = 0;
    for (const Information* i : cs.infos)
      for (std::size_t r = 0; r < i->runs(); ++r) runs += i->run_samples(r) >= 2 ? 1 : 0;
    for (;;) {
      if (!s.batch.ok) break;
      const std::vector<Index> level = current->phase_level_terms(s.batch, cs.infos, cs.m_cs, gain);
      s.level_parameters = level_parameters(s.batch, *current, cs, &fits);
      const int dof = runs - s.level_parameters;
      StatFit trial = s.batch;
      if (dof >= 1) (void)current->add_case_scatter(trial, cs.infos, cs.m_cs, gain, s.level_parameters);
      std::optional<Index> weakest;
      double weakest_t = std::numeric_limits<double>::infinity();
      int droppable = 0;
      for (std::size_t k = 0; k < trial.terms.size(); ++k) {
        const Index t = trial.terms[k];
        if (t == current->bias_term() || t == axis || std::find(level.begin(), level.end(), t) == level.end()) continue;
        ++droppable;
        const double z = std::abs(trial.theta(static_cast<Index>(k)) / trial.sd(static_cast<Index>(k)));
        if (z < weakest_t) {
          weakest_t = z;
          weakest = t;
        }
      }
      if (!weakest) break;
      if (dof >= 1 && ident::student_t_two_sided_p(weakest_t, dof) <= options.solver.structure_alpha / droppable) break;
      s.confounded.push_back(*weakest);
      std::vector<Index> kept = current->model();
      std::erase(kept, *weakest);
      current.emplace(current->with_model(std::move(kept)));
      s.batch = current->fit_batch_at(infos, m_cs, s.batch.corner_rad_s);
    }
    return *current;
  }

  OnlineSnapshot snapshot() {
    OnlineSnapshot out;
    for (const Term& t : model_terms) out.terms.push_back(t.to_string());
    const auto p = static_cast<Index>(model_terms.size());
    out.values = Eigen::VectorXd::Constant(p, kNaN);
    out.std_devs = Eigen::VectorXd::Constant(p, kNaN);
    out.t = Eigen::VectorXd::Constant(p, kNaN);
    out.noise_model_fitted = noise_fitted;
    out.noise_order = static_cast<int>(ar.size());
    out.long_run_variance_factor = solver->long_run_variance_factor();
    Solution s = solve(true);
    std::int64_t samples = 0;
    for (const Information& i : s.infos) samples += i.samples();
    out.samples_used = samples;
    out.cases_used = static_cast<std::int64_t>(cases_with_data());
    for (std::size_t m = 0; m < mountings.size(); ++m) {
      const MountingState& ms = mountings[m];
      MountingEstimate e;
      e.name = ms.name;
      for (std::size_t c : ms.cases) e.cases.push_back(cases[c].name);
      e.determined = ms.fit.determined;
      e.m_cs = ms.fit.m_cs;
      e.angles_rad = ms.fit.angles;
      e.angles_sd_rad = ms.fit.angles_sd;
      e.samples = s.infos[m].samples();
      e.note = ms.fit.note;
      out.mountings.push_back(std::move(e));
    }
    if (!s.batch.ok) {
      for (const Term& t : model_terms) out.undetermined.push_back(t.to_string());
      out.convergence = s.batch.why.empty() ? "no estimate yet" : s.batch.why;
      return out;
    }
    for (std::size_t j = 0; j < model.size(); ++j) {
      bool found = false;
      for (std::size_t k = 0; k < s.batch.terms.size(); ++k) {
        if (s.batch.terms[k] != model[j]) continue;
        out.values(static_cast<Index>(j)) = s.batch.theta(static_cast<Index>(k));
        out.std_devs(static_cast<Index>(j)) = s.batch.sd(static_cast<Index>(k));
        out.t(static_cast<Index>(j)) = s.batch.theta(static_cast<Index>(k)) / s.batch.sd(static_cast<Index>(k));
        found = true;
      }
      if (found) continue;
      out.undetermined.push_back(model_terms[j].to_string());
      if (std::find(s.confounded.begin(), s.confounded.end(), model[j]) != s.confounded.end())
        out.confounded.push_back(model_terms[j].to_string());
      else if ((!s.aligned && !procedure::frame_free(model_terms[j])) || whole_plan_in())
        out.plan_undetermined.push_back(model_terms[j].to_string());
    }
    out.residual_variance = s.batch.s2;
    out.corner_rad_s = s.batch.corner_rad_s;
    if (options.structure_table) {
      std::vector<const Information*> infos;
      std::vector<Eigen::Matrix3d> m_cs;
      for (std::size_t m = 0; m < mountings.size(); ++m) {
        infos.push_back(&s.infos[m]);
        m_cs.push_back(mountings[m].fit.determined ? mountings[m].fit.m_cs : mountings[m].m_cs);
      }
      for (const CandidateStat& c : solver->with_model(s.model).structure(candidates, s.batch, infos, m_cs)) {
        const Term& t = basis->terms()[static_cast<std::size_t>(c.term)];
        out.structure.push_back({t.to_string(), ident::physical_name(t, sensor), c.err, c.value, c.sd, c.t, c.significant});
      }
      std::stable_sort(out.structure.begin(), out.structure.end(),
                       [](const CandidateEstimate& a, const CandidateEstimate& b) { return a.err > b.err; });
    }
    update_convergence(s, out);
    out.converged = converged;
    out.convergence = convergence;
    return out;
  }

  /// Leave-one-out: the estimate without case c against the estimate with it. Under the model,
  /// theta_without - theta has variance var_without - var (nested estimators), so
  /// z = |difference| / sqrt(var_without - var) is standard normal; a case whose z exceeds the
  /// Bonferroni bound disagrees with the others, and one more such case would move the estimate.
  /// A case without which a term is not determined (a plan with no case to spare: a rotation
  /// table's rate series alone gives the centripetal terms, a thermal bench's two poses the bias)
  /// is checked by leaving out each of its phases instead; a term that rests on one phase alone
  /// is never called converged.
  void update_convergence(const Solution& s, const OnlineSnapshot& out) {
    const auto rate_rows = nominal_period > 0.0 ? options.convergence_interval_s / nominal_period : 1e4;
    const std::size_t with_data = cases_with_data();
    if (last_convergence_rows >= 0 && with_data == last_convergence_cases &&
        static_cast<double>(rows_total - last_convergence_rows) < rate_rows)
      return;
    last_convergence_rows = rows_total;
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
    const std::size_t beyond = out.plan_undetermined.size() + out.confounded.size();
    if (out.undetermined.size() > beyond) {
      convergence = fmt::format("{} term(s) not determined yet{}", out.undetermined.size() - beyond, beyond_plan);
      return;
    }
    // A plan of one case is checked by its phases (below), once it is in.
    if (with_data < 2 && !every_plan_case_in()) {
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
      const Solution without = solve(false, left_out, &s.m_cs, &s.angle_covariances, &s);
      if (!without.batch.ok) return std::string("the model");
      for (std::size_t j = 0; j < model.size(); ++j) {
        const std::string name = model_terms[j].to_string();
        if (std::find(out.plan_undetermined.begin(), out.plan_undetermined.end(), name) != out.plan_undetermined.end() ||
            std::find(out.confounded.begin(), out.confounded.end(), name) != out.confounded.end())
          continue;
        std::optional<Index> a, b;
        for (std::size_t k = 0; k < s.batch.terms.size(); ++k)
          if (s.batch.terms[k] == model[j]) a = static_cast<Index>(k);
        for (std::size_t k = 0; k < without.batch.terms.size(); ++k)
          if (without.batch.terms[k] == model[j]) b = static_cast<Index>(k);
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
    for (std::size_t c = 0; c < cases.size(); ++c) {
      if (!has_data(c)) continue;
      const std::optional<std::string> missing = compare({c, std::nullopt}, "case " + cases[c].name);
      if (!missing) continue;
      const std::vector<const RunStatistics::Run*> runs = runs_of(c);
      std::size_t with_rows = 0;
      for (const RunStatistics::Run* r : runs) with_rows += r->info.samples() > 0 ? 1 : 0;
      if (with_rows < 2) {
        convergence = fmt::format("without case {} {} is not determined, and the case has one phase to check it "
                                  "by{}",
                                  cases[c].name, *missing, beyond_plan);
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
                             label < cases[c].phase_names.size() ? cases[c].phase_names[label] : "unlabelled");
        };
        const std::string where = last - first == 1
                                      ? fmt::format("phase {} of case {}", name(first), cases[c].name)
                                      : fmt::format("phases {} to {} of case {}", name(first), name(last - 1), cases[c].name);
        if (const std::optional<std::string> rests = compare({c, std::pair{first, last}}, where)) {
          convergence = fmt::format("without case {} {} is not determined, nor without its {}: it rests on {}{}",
                                    cases[c].name, *missing, where, last - first == 1 ? "one phase" : "those phases",
                                    beyond_plan);
          return;
        }
      }
    }
    const double z_bound = bonferroni_z(options.convergence_alpha, static_cast<double>(units * s.batch.terms.size()));
    converged = worst <= z_bound;
    convergence = fmt::format("largest leave-one-out z {:.2f} ({}), bound {:.2f}{}", worst, worst_at, z_bound, beyond_plan);
  }
};

std::vector<Term> OnlineEstimator::default_terms(dataset::SensorKind sensor, bool temperature) {
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  std::vector<Term> terms;
  if (gyro) {
    // Eq. 5's static part: bias, scale factor, its rate nonlinearity (c_f1: the output times the
    // rate, fitted with ULS's correction) and the g-sensitivity.
    terms = {Term(),
             plain_term(Variable::Wi),
             product(Variable::Y, Variable::Wi),
             plain_term(Variable::Ai),
             plain_term(Variable::Ap),
             plain_term(Variable::Ao)};
  } else {
    // The paper's complete static model (eq. 4, r = 0, table 3's case 3).
    terms = {Term(),
             plain_term(Variable::Ai),
             plain_term(Variable::Ai, 2),
             plain_term(Variable::Ap, 2),
             plain_term(Variable::Ao, 2),
             product(Variable::Ai, Variable::Ap),
             product(Variable::Ai, Variable::Ao),
             product(Variable::Ap, Variable::Ao)};
  }
  if (temperature) {
    // A thermal plan is run for the temperature coefficients of the bias and the scale factor
    // (IEEE Std 1293's K_0T and K_1T; a gyroscope's as eq. 5 has them, c_T1 T and the output
    // times epsilon_T T): without them the temperature's effect lands in the others.
    terms.push_back(plain_term(Variable::T));
    terms.push_back(product(gyro ? Variable::Y : Variable::Ai, Variable::T));
  }
  return terms;
}

OnlineEstimator::OnlineEstimator(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model, double t_ref,
                                 const OnlineOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.sensor = sensor;
  s.t_ref = t_ref;
  s.options = options;
  const bool gyro = sensor == dataset::SensorKind::Gyroscope;
  if (model) {
    if (model->sensor != sensor) {
      throw InputError("online: the model is for a " + std::string(dataset::to_string(model->sensor)) +
                       ", the bench's sensor is a " + dataset::to_string(sensor));
    }
    s.model_m_cs = model->m_cs;
    for (const model::ModelTerm& t : model->terms) s.model_terms.push_back(t.term);
    if (model->square_highpass_rad_s) s.grid = CornerGrid::single(*model->square_highpass_rad_s);
  } else {
    s.model_terms = default_terms(sensor, options.temperature_candidates);
  }
  for (const Term& t : s.model_terms) {
    if (t.is_noise_term()) {
      throw InputError("online: term '" + t.to_string() +
                       "' is a noise lag; the live estimator keeps no residual history across gaps");
    }
    s.rational = s.rational || t.is_output_multiplied();
    s.model_max_lag = std::max<Index>(s.model_max_lag, t.max_lag());
  }
  const Variable axis = gyro ? Variable::Wi : Variable::Ai;
  if (std::find(s.model_terms.begin(), s.model_terms.end(), plain_term(axis)) == s.model_terms.end()) {
    throw InputError(std::string("online: the model has no scale-factor term '") + ident::variable_name(axis) +
                     "': algorithm 1 needs it to find the misalignment");
  }
  // The squares' corner: the model's, or searched over the batch pipeline's range (1 rad/s to
  // 1e4 rad/s or 0.9 of Nyquist), static squares competing, as the batch does it.
  std::vector<Term> squares;
  for (const Term& t : s.model_terms)
    if (procedure::is_square_term(t)) squares.push_back(t);
  const bool search_corner = !squares.empty() && !model;
  if (search_corner) {
    const double period = options.nominal_sample_period_s;
    const double hi = std::min(1.0e4, period > 0.0 ? 0.9 * std::numbers::pi / period : 1.0e4);
    s.grid = CornerGrid::spanning(1.0, hi);
  }
  if (s.grid.empty()) squares.clear();
  // Every term the estimator may be asked for: the model, its external-frame sensitivities, the
  // structure table's candidates, and the factors of output-multiplied terms.
  std::vector<Term> all = s.model_terms;
  const std::vector<Term> sensitivities = gyro ? std::vector<Term>{plain_term(Variable::Wx), plain_term(Variable::Wy), plain_term(Variable::Wz)}
                                               : std::vector<Term>{plain_term(Variable::Ax), plain_term(Variable::Ay), plain_term(Variable::Az)};
  const auto add = [&all](const Term& t) {
    if (std::find(all.begin(), all.end(), t) == all.end()) all.push_back(t);
  };
  for (const Term& t : sensitivities) add(t);
  std::vector<Term> candidate_terms;
  if (options.structure_table) {
    diagnose::LibraryOptions lo;
    lo.temperature = options.temperature_candidates;
    lo.mounting_rotations = false;
    for (const Term& t : diagnose::candidate_library(sensor, lo)) {
      if (t.is_noise_term() || std::find(s.model_terms.begin(), s.model_terms.end(), t) != s.model_terms.end()) continue;
      // Cross-axis terms are the misalignment's (algorithm 1 per mounting).
      if (t == plain_term(gyro ? Variable::Wp : Variable::Ap) || t == plain_term(gyro ? Variable::Wo : Variable::Ao)) continue;
      candidate_terms.push_back(t);
      add(t);
    }
  }
  for (const Term& t : std::vector<Term>(all))
    if (t.is_output_multiplied()) add(t.denominator_factor());
  s.basis = std::make_unique<LiveBasis>(all, squares);
  for (const Term& t : s.model_terms) s.model.push_back(s.basis->find(t));
  for (const Term& t : candidate_terms) s.candidates.push_back(s.basis->find(t));
  std::vector<Index> sens;
  for (const Term& t : sensitivities) sens.push_back(s.basis->find(t));
  s.solver = std::make_unique<LiveSolver>(*s.basis, s.model, sens, sensor, s.grid, search_corner, s.options.solver);
  for (Index t : s.model)
    if (procedure::frame_free(s.basis->terms()[static_cast<std::size_t>(t)])) s.frame_free_model.push_back(t);
  // No noise window, or no order to fit: white noise from the first row on.
  s.noise_fitted = options.noise_window_s <= 0.0 || options.whitening_max_order <= 0;
}

OnlineEstimator::~OnlineEstimator() = default;

void OnlineEstimator::push(const fusion::FusedChunk& chunk, const config::TestCase& tc) { impl_->push(chunk, tc); }
void OnlineEstimator::end_segment(const fusion::SegmentEnd& end) { impl_->end_segment(end); }
OnlineSnapshot OnlineEstimator::snapshot() { return impl_->snapshot(); }
std::int64_t OnlineEstimator::rows_pushed() const { return impl_->rows_total; }
std::vector<std::string> OnlineEstimator::terms() const { return ident::to_strings(impl_->model_terms); }

}  // namespace inertia::online
