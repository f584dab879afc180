// Building the fused segments of the case being fused (segment_builder.hpp).
#include "analyzer/fusion/segment_builder.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "common/input_error.hpp"
#include "common/units.hpp"

namespace inertia::fusion {

namespace {

// Stream time a thermal case's first row waits for the fixture's first temperature reading before
// its segment goes on without temperature (a controller that never answers).
constexpr double kFirstTemperatureWaitS = 30.0;

}  // namespace

void SegmentBuilder::open_case(const CaseMarks& c) {
  if (fuser_) end_case();
  const config::BenchConfig& b = *bench_;
  const config::TestCase& tc = b.cases[c.case_index];
  Fuser f;
  f.marks = &c;
  f.case_index = c.case_index;
  f.name = c.name;
  f.kind = tc.kind;
  // A static or thermal case is a pose: its specific force is the pose's gravity by definition
  // (a placement error is the fixture's, which the inference carries). Monitors there would add
  // their noise to every row's regressors, where a nonlinear candidate of an axis that sees
  // nothing (sign, abs, squares of a_i near 0) fits that noise; they are the vibration's reference.
  const bool pose = tc.kind == CaseKind::Static || tc.kind == CaseKind::Thermal;
  for (std::size_t k = 0; k < buffers_.needs.size(); ++k) {
    const ChannelRole r = buffers_.needs[k].role;
    const bool use = r == ChannelRole::Output || (r == ChannelRole::Monitor && tc.kind != CaseKind::RotationTable && !pose) ||
                     (r == ChannelRole::LinearEncoder && tc.kind == CaseKind::Shaker) ||
                     (r == ChannelRole::TableEncoder && tc.kind == CaseKind::RotationTable);
    if (!use) continue;
    f.used.push_back(k);
    if (r == ChannelRole::Monitor) f.monitor_needs.push_back(k);
    if (r == ChannelRole::LinearEncoder || r == ChannelRole::TableEncoder) f.encoder_need = k;
  }
  if (tc.kind == CaseKind::RotationTable && !f.encoder_need)
    throw InputError("case " + c.name + " (rotation_table): the bench has no [table_encoder] to fuse it with");
  if (pose) {
    f.pose_specific_force = kStandardGravity * tc.start_attitude.dcm().col(2);
  } else if (tc.kind != CaseKind::RotationTable) {
    if (f.monitor_needs.size() < 3)
      throw InputError("case " + c.name + " (" + to_string(tc.kind) +
                       "): fusion needs at least three [[monitor]] accelerometers, the bench has " +
                       std::to_string(f.monitor_needs.size()));
    // Monitors: calibrated (bias, scale, misalignment from the bench file), then WLS.
    MonitorLayout layout;
    const auto count = static_cast<Eigen::Index>(f.monitor_needs.size());
    f.readings.resize(count);
    f.monitor_bias.resize(count);
    f.monitor_gain.resize(count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const config::MonitorAccelerometer& m = b.monitors[buffers_.needs[f.monitor_needs[static_cast<std::size_t>(j)]].index];
      f.monitor_gain(j) = 1.0 + m.scale_error;
      f.monitor_bias(j) = m.bias_mps2;
      layout.axes.push_back(m.misalignment.dcm().transpose() * m.axis.normalized());
      layout.noise_sd_mps2.push_back(std::max(m.noise_sd_mps2, 1e-12) / f.monitor_gain(j));
    }
    // The geometry comes from the bench file in the stream (outside bytes): monitors whose
    // axes do not span three dimensions, or a zero axis or noise figure, are bad input for
    // this case, never an escaping std::invalid_argument (found by fuzz_event_log).
    try {
      f.monitors.emplace(layout);
    } catch (const std::invalid_argument& e) {
      throw InputError("case " + c.name + " (" + to_string(tc.kind) +
                       "): the bench's [[monitor]] accelerometers cannot be fused: " + e.what());
    }
  }
  f.running_attitude = tc.start_attitude.dcm();
  f.needs_temperature = tc.varies_temperature();
  fuser_ = std::move(f);
}

bool SegmentBuilder::add_row(const StoredBlock& ob, std::int32_t s, const CaseMarks& c, double t, double half) {
  Fuser& f = *fuser_;

  // Every input of the row, or the reason it has none.
  std::vector<std::string> reasons;
  bool encoder_lost = false;   // the fusion's state cannot go on through this row
  const double y = ob.values[buffers_.output_slot][static_cast<std::size_t>(s)];
  if (!ob.valid[buffers_.output_slot][static_cast<std::size_t>(s)]) reasons.push_back(buffers_.needs[0].ref.label() + " invalid");
  Eigen::Index m = 0;
  double encoder = 0.0;
  for (std::size_t k : f.used) {
    if (k == 0) continue;
    double v = 0.0;
    const ReadResult r = buffers_.read(k, t, v);
    if (r == ReadResult::NotYet) return false;
    if (r == ReadResult::Invalid) reasons.push_back(buffers_.needs[k].ref.label() + " invalid");
    if (r == ReadResult::Missing) reasons.push_back(buffers_.needs[k].ref.label() + " missing (gap)");
    if (r != ReadResult::Ok && buffers_.needs[k].role != ChannelRole::Monitor) encoder_lost = true;
    if (buffers_.needs[k].role == ChannelRole::Monitor) {
      f.readings(m) = (v - f.monitor_bias(m)) / f.monitor_gain(m);
      ++m;
    } else {
      encoder = v;
    }
  }
  double temp = 0.0;
  // A segment carries temperature when a reading has come by its first row. A case that needs
  // it (thermal) waits for the first: the controller is polled at its own pace (10 Hz; in a
  // --fast run, in wall time), and its first reading may come after the first sensor rows.
  if (!f.segment && buffers_.temps.empty() && f.needs_temperature && !buffers_.finishing &&
      buffers_.output_newest_ns() - t < kFirstTemperatureWaitS * 1e9)
    return false;
  const bool with_temp = f.segment ? f.segment->has_temp : !buffers_.temps.empty();
  if (with_temp) {
    if (buffers_.temp_newest_ns < t && !buffers_.given_up(t)) return false;
    temp = buffers_.held_temperature(t);
  }

  const double t_case = (t - c.start_ns) * 1e-9;
  RawRow row;
  row.t_ns = t;
  row.t_case_s = t_case;
  row.y = y;
  row.encoder = encoder;
  row.temp = temp;
  label_phase(f, c, t, half, row);
  if (f.kind == CaseKind::RotationTable && !table_attitude(f, row, !encoder_lost) && !encoder_lost) {
    reasons.push_back("table attitude unknown (a phase without encoder data before it)");
    encoder_lost = true;
  }
  count_exclusions(f, reasons, t_case);
  if (!reasons.empty()) {
    // Only the output or monitors lost (a lost frame of their device): the fusion goes on
    // through the row, which cuts the output. Anything else breaks the fusion.
    if (encoder_lost || !f.segment) {
      if (f.segment) end_segment();
      return true;
    }
    row.hole = true;
  }
  if (f.monitors && !row.hole) row.monitors_a = f.monitors->fuse(f.readings);
  if (f.pose_specific_force) row.monitors_a = *f.pose_specific_force;
  if (!f.segment) start_segment(with_temp);
  f.segment->pending.push_back(row);
  // A table's rate steps between phases (a rate phase runs at its rate from its first sample):
  // a central difference across the change gives half of each, on the wrong phase's axis. So
  // each phase of a table case is differenced on its own, its end rows extrapolated from inside.
  Segment& seg = *f.segment;
  if (f.kind == CaseKind::RotationTable && seg.differences.pushed() > 0 && row.phase_index != seg.differenced_phase)
    seg.differences.finish();
  seg.differenced_phase = row.phase_index;
  seg.differences.push(row.encoder);
  finalize_ready(false);
  return true;
}

void SegmentBuilder::note_output_gap(const StoredBlock& a, const StoredBlock& b) {
  const double missing = (b.t0_ns - a.time(a.n)) / a.period_ns;
  if (missing <= 0.5 && b.seq0 == a.seq0 + a.n) return;
  if (fuser_ && fuser_->segment) {
    const auto n = std::max<std::int64_t>(std::llround(missing), b.seq0 - (a.seq0 + a.n));
    const double t_case = (a.time(a.n) - fuser_->marks->start_ns) * 1e-9;
    end_segment();
    exclusions_.push_back({fuser_->name, buffers_.needs[0].ref.label() + " missing (gap)", t_case, std::max<std::int64_t>(n, 1)});
  }
}

void SegmentBuilder::label_phase(Fuser& f, const CaseMarks& c, double t, double half, RawRow& row) {
  const PhaseMark* current = nullptr;
  for (const PhaseMark& p : c.phases)
    if (p.start_ns <= t + half) current = &p;
  row.phase_index = current ? current->phase_index : -1;
  auto [it, fresh] = f.phase_labels.try_emplace(row.phase_index, 0);
  if (fresh) {
    const std::string label = current ? current->label : std::string("unplanned");
    auto named = std::find(f.phase_names.begin(), f.phase_names.end(), label);
    if (named == f.phase_names.end()) {
      f.phase_names.push_back(label);
      named = std::prev(f.phase_names.end());
    }
    it->second = static_cast<std::uint16_t>(named - f.phase_names.begin());
  }
  row.phase_label = it->second;
}

bool SegmentBuilder::table_attitude(Fuser& f, const RawRow& row, bool usable) {
  const std::int32_t p = row.phase_index;
  if (p < 0) return false;
  const config::TestCase& tc = bench_->cases[f.case_index];
  const bool rotation = static_cast<std::size_t>(p) < tc.phases.size() &&
                        tc.phases[static_cast<std::size_t>(p)].kind == config::PhaseKind::Rotation;
  if (p > f.phases_seen) {
    // The phase's first row: its start angle fixes the attitude (the phases turn about
    // different axes, so one angle does not give it). Skipped phases lose it for good.
    if (p > f.phases_seen + 1) f.attitude_lost_from = std::min(f.attitude_lost_from, f.phases_seen + 1);
    f.phases_seen = p;
    f.attitude_pending = true;
  }
  if (f.attitude_pending && p < f.attitude_lost_from) {
    if (usable) {
      if (f.prev_base) f.running_attitude = frames::frame_rotation(f.prev_axis, row.encoder - *f.prev_base) * f.running_attitude;
      f.attitude[p] = f.running_attitude;
      f.base[p] = row.encoder;
      f.prev_axis = rotation ? tc.phases[static_cast<std::size_t>(p)].axis.normalized() : Eigen::Vector3d::UnitZ();
      f.prev_base = row.encoder;
      f.attitude_pending = false;
    } else if (rotation) {
      f.attitude_lost_from = std::min(f.attitude_lost_from, p);
      f.attitude_pending = false;
    }
  }
  return p < f.attitude_lost_from && f.attitude.count(p) != 0;
}

void SegmentBuilder::count_exclusions(Fuser& f, const std::vector<std::string>& reasons, double t_case) {
  for (auto it = f.runs.begin(); it != f.runs.end();) {
    if (std::find(reasons.begin(), reasons.end(), it->first) == reasons.end()) {
      exclusions_.push_back({f.name, it->first, it->second.t_case_s, it->second.samples});
      it = f.runs.erase(it);
    } else {
      ++it;
    }
  }
  for (const std::string& r : reasons) {
    auto [it, fresh] = f.runs.try_emplace(r, ExclusionRun{t_case, 0});
    ++it->second.samples;
  }
}

void SegmentBuilder::start_segment(bool with_temp) {
  Fuser& f = *fuser_;
  Segment s;
  s.number = f.segments_started++;
  s.has_temp = with_temp;
  const double dt = buffers_.output_period_ns() * 1e-9;
  s.differences = CentralDifferences(dt);
  if (f.kind == CaseKind::Shaker && f.encoder_need && 1.0 / dt > 2.0 * options_.crossover_hz) {
    // After a break within the case the filter goes on from its state before it: what its low
    // paths hold (the monitors' slow error against the encoder) does not change over a gap,
    // while a filter started afresh in mid-vibration would settle on one sample of the
    // encoder's second difference, whose error at high frequency is a large fraction of the
    // vibration, and ring on it for a few tenths of a second.
    if (f.filter_before_break) {
      s.filter = std::move(f.filter_before_break);
      f.filter_before_break.reset();
    } else {
      s.filter.emplace(dt, options_.crossover_hz);
    }
  }
  f.segment = std::move(s);
}

void SegmentBuilder::finalize_ready(bool ending) {
  Fuser& f = *fuser_;
  Segment& s = *f.segment;
  if (ending) s.differences.finish();
  const config::TestCase& tc = bench_->cases[f.case_index];
  const config::SensorUnderTest& sut = bench_->sensors[sensor_];
  while (s.differences.ready()) {
    const CentralDifferences::Value d = s.differences.pop();
    const RawRow row = s.pending.front();
    s.pending.pop_front();
    if (row.hole) {
      if (s.filter) s.filter->coast(d.second);
      end_piece();
      continue;
    }
    Eigen::Vector3d a = row.monitors_a;
    Eigen::Vector3d w = Eigen::Vector3d::Zero();
    if (f.kind == CaseKind::RotationTable) {
      const std::int32_t p = row.phase_index;
      const config::Phase* ph = static_cast<std::size_t>(p) < tc.phases.size() ? &tc.phases[static_cast<std::size_t>(p)] : nullptr;
      const Eigen::Vector3d axis = ph != nullptr && ph->kind == config::PhaseKind::Rotation ? ph->axis.normalized()
                                                                                           : Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d f0 = kStandardGravity * f.attitude.at(p).col(2);
      a = table_specific_force_at(row.encoder - f.base.at(p), d.first, d.second, axis, f0, sut.position_m);
      w = d.first * axis;
    } else if (s.filter) {
      // The armature moves along the vibration axis x_E (config: the Fig. 2 fixture).
      a.x() = s.filter->step(a.x(), d.second);
    }
    append(s, row, a, w);
  }
}

void SegmentBuilder::append(Segment& s, const RawRow& row, const Eigen::Vector3d& a, const Eigen::Vector3d& w) {
  FusedChunk& out = s.out;
  if (out.rows() == 0) {
    Fuser& f = *fuser_;
    if (s.next_piece) {
      s.number = f.segments_started++;
      s.next_piece = false;
    }
    out.case_index = f.case_index;
    out.case_name = f.name;
    out.kind = f.kind;
    out.segment = s.number;
    out.sample_period_s = buffers_.output_period_ns() * 1e-9;
    out.first_row = s.piece_rows;
    out.phase.clear();
    out.plan_phase.clear();
    if (s.piece_rows == 0) s.piece_first_t_case = row.t_case_s;
  }
  ++s.piece_rows;
  const Eigen::Index n = out.rows();
  out.t.conservativeResize(n + 1);
  out.t(n) = row.t_case_s;
  out.a_e.conservativeResize(n + 1, Eigen::NoChange);
  out.a_e.row(n) = a.transpose();
  out.w_e.conservativeResize(n + 1, Eigen::NoChange);
  out.w_e.row(n) = w.transpose();
  out.y.conservativeResize(n + 1);
  out.y(n) = row.y;
  if (s.has_temp) {
    if (!out.temp) out.temp = Eigen::VectorXd(0);
    out.temp->conservativeResize(n + 1);
    (*out.temp)(n) = row.temp;
  }
  out.phase.push_back(row.phase_label);
  out.plan_phase.push_back(row.phase_index);
  out.newest_mono_ns = static_cast<std::int64_t>(row.t_ns);
  if (out.rows() >= 4096) flush_chunk();
}

void SegmentBuilder::flush_chunk() {
  if (!fuser_ || !fuser_->segment || fuser_->segment->out.rows() == 0) return;
  FusedChunk& out = fuser_->segment->out;
  out.phase_names = fuser_->phase_names;
  rows_out_ += out.rows();
  sink_.on_rows(std::move(out));
  out = FusedChunk{};
}

void SegmentBuilder::end_piece() {
  Fuser& f = *fuser_;
  Segment& s = *f.segment;
  flush_chunk();
  if (s.piece_rows == 0) return;
  // In rows of the output's period; a hostile period (1e-150 s) would make the count overflow
  // int64 (found by fuzz_stream_assembler): no segment is that long, so it keeps none.
  const double min_rows = std::ceil(options_.min_segment_s / (buffers_.output_period_ns() * 1e-9));
  const std::int64_t min_len = min_rows < 9.0e18 ? static_cast<std::int64_t>(min_rows) : std::numeric_limits<std::int64_t>::max();
  const bool kept = s.piece_rows >= std::max<std::int64_t>(min_len, 3);
  if (kept) {
    rows_kept_ += s.piece_rows;
    f.rows += s.piece_rows;
  } else {
    exclusions_.push_back({f.name, fmt::format("valid stretch shorter than {} s", options_.min_segment_s),
                          s.piece_first_t_case, s.piece_rows});
  }
  sink_.on_segment_end({f.case_index, f.name, s.number, s.piece_rows, kept});
  s.piece_rows = 0;
  s.next_piece = true;
}

void SegmentBuilder::end_segment() {
  Fuser& f = *fuser_;
  if (!f.segment) return;
  finalize_ready(true);
  end_piece();
  Segment& s = *f.segment;
  if (s.filter) f.filter_before_break = std::move(s.filter);
  f.segment.reset();
}

void SegmentBuilder::end_case() {
  if (!fuser_) return;
  end_segment();
  Fuser& f = *fuser_;
  for (const auto& [reason, run] : f.runs) exclusions_.push_back({f.name, reason, run.t_case_s, run.samples});
  if (f.rows == 0) notes_.push_back("case " + f.name + " has no usable samples");
  fuser_.reset();
}

}  // namespace inertia::fusion
