#include "analyzer/fusion/stream_assembler.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <stdexcept>

#include "analyzer/fusion/channel_ref.hpp"
#include "analyzer/fusion/reference_fusion.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "common/units.hpp"

namespace inertia::fusion {

// ---- SegmentCollector ----

void SegmentCollector::on_rows(FusedChunk&& chunk) {
  open_[{chunk.case_index, chunk.segment}].push_back(std::move(chunk));
}

void SegmentCollector::on_segment_end(const SegmentEnd& end) {
  const auto it = open_.find({end.case_index, end.segment});
  if (it == open_.end()) return;
  std::vector<FusedChunk> chunks = std::move(it->second);
  open_.erase(it);
  if (!end.kept || chunks.empty()) return;
  Eigen::Index n = 0;
  for (const FusedChunk& c : chunks) n += c.rows();
  const FusedChunk& first = chunks.front();
  FusedSegment s;
  s.case_index = first.case_index;
  s.case_name = first.case_name;
  s.kind = first.kind;
  s.segment = kept_[first.case_index]++;
  s.sample_period_s = first.sample_period_s;
  s.t.resize(n);
  s.a_e.resize(n, 3);
  Rows3 w(n, 3);
  s.y.resize(n);
  if (first.temp) s.temp = Eigen::VectorXd(n);
  Eigen::Index at = 0;
  for (const FusedChunk& c : chunks) {
    const Eigen::Index m = c.rows();
    s.t.segment(at, m) = c.t;
    s.a_e.middleRows(at, m) = c.a_e;
    w.middleRows(at, m) = c.w_e;
    s.y.segment(at, m) = c.y;
    if (s.temp) s.temp->segment(at, m) = *c.temp;
    s.phase.insert(s.phase.end(), c.phase.begin(), c.phase.end());
    at += m;
  }
  s.w_e = std::move(w);
  s.phase_names = chunks.back().phase_names;
  sink_(std::move(s));
}

namespace {

// What a needed channel is to the fusion of the sensor under test.
enum class Role { Output, Monitor, LinearEncoder, TableEncoder };

struct Need {
  Role role;
  std::size_t index = 0;   // monitor index
  ChannelRef ref;
};

// One stored block of a device: the needed channels only.
struct StoredBlock {
  std::int64_t seq0 = 0;                        // the device's sample counter at sample 0
  std::int32_t n = 0;
  double t0_ns = 0.0;
  double period_ns = 0.0;
  std::vector<std::vector<double>> values;      // per device-need slot
  std::vector<std::vector<std::uint8_t>> valid;
  [[nodiscard]] double time(std::int64_t s) const { return t0_ns + static_cast<double>(s) * period_ns; }
  [[nodiscard]] double last_ns() const { return time(n - 1); }
};

struct DeviceState {
  std::vector<std::size_t> needs;               // indices into Impl::needs
  std::vector<std::int32_t> columns;            // block column of each need, -1 until seen
  std::deque<StoredBlock> blocks;               // in arrival order (ascending time)
  std::optional<std::int64_t> next_seq;         // channel_seq the next block should start at
  double next_ns = std::numeric_limits<double>::quiet_NaN();   // time it should start at
  double newest_ns = -std::numeric_limits<double>::infinity();  // newest sample received
};

struct TempSample {
  double t_ns;
  double value;
};

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

// Stream time a thermal case's first row waits for the fixture's first temperature reading before
// its segment goes on without temperature (a controller that never answers).
constexpr double kFirstTemperatureWaitS = 30.0;

// A row read from the devices, waiting for the differences it needs.
struct RawRow {
  double t_ns = 0.0;
  double t_case_s = 0.0;
  double y = 0.0;
  Eigen::Vector3d monitors_a = Eigen::Vector3d::Zero();   // monitor WLS (non-table cases)
  double encoder = 0.0;                                   // displacement or table angle
  std::int32_t phase_index = -1;
  std::uint16_t phase_label = 0;
  double temp = 0.0;
  // A hole: the sensor's output or a monitor is lost here while the encoder is not, so the
  // fusion's state (differences, the shaker's filter, the table's attitude) goes on through the
  // row; the row itself is excluded and ends the piece of the segment before it.
  bool hole = false;
};

// Largest sample index read() converts to an integer: block_shape_error keeps channel_seq below
// 2^62 as well, so seq0 + index stays within int64.
constexpr double kMaxSampleIndex = 0x1p62;

// Values and validity of one need at one row time.
enum class Read { Ok, Invalid, Missing, NotYet };

// Exclusions per reason, as runs of consecutive rows.
struct Run {
  double t_case_s = 0.0;
  std::int64_t samples = 0;
};

}  // namespace

struct StreamAssembler::Impl {
  AssemblerOptions options;
  FusionSink* sink = nullptr;
  std::optional<config::BenchConfig> bench;
  std::vector<std::string> bench_texts;   // paths + texts of the first bench, to compare repeats
  std::size_t sensor = 0;
  std::vector<Need> needs;
  std::map<std::string, DeviceState> devices;
  std::string output_device;
  std::size_t output_slot = 0;            // the output need's slot in its device
  ChannelRef temp_ref;
  std::vector<TempSample> temps;
  double temp_newest_ns = -std::numeric_limits<double>::infinity();
  double marker_newest_ns = -std::numeric_limits<double>::infinity();
  std::deque<CaseMarks> cases;            // in marker order; finished ones are removed (a deque: Fuser points into it)
  bool saw_case_marker = false;
  std::vector<Exclusion> exclusions;
  std::vector<StreamGap> gaps;
  std::vector<std::string> notes;
  std::int64_t skipped = 0;
  std::int64_t rows_kept = 0;
  std::int64_t rows_out = 0;
  bool finishing = false;

  // The output device's next row: block (front of its deque after release) and sample.
  std::size_t cursor_block = 0;
  std::int32_t cursor_sample = 0;
  std::optional<StoredBlock> previous_output;  // header of the last output block read (its values dropped)
  double last_read_ns = -std::numeric_limits<double>::infinity();   // time of the last output sample read
  double last_row_ns = -std::numeric_limits<double>::infinity();    // time of the last row fused

  // ---- the case being fused ----
  // A segment is a stretch of continuous fusion; holes cut its output into pieces, each handed to
  // the sink as a segment of its own (number), so the sink's segments stay contiguous.
  struct Segment {
    int number = 0;
    std::int64_t piece_rows = 0;       // rows appended to the current piece
    double piece_first_t_case = 0.0;
    bool next_piece = false;           // a hole ended a piece: the next row starts another
    bool has_temp = false;
    CentralDifferences differences{1.0};
    std::int32_t differenced_phase = -1;   // the plan phase of the newest row differenced
    std::optional<ComplementaryFilter> filter;
    std::deque<RawRow> pending;
    FusedChunk out;
  };
  struct Fuser {
    CaseMarks* marks = nullptr;       // points into `cases` (front)
    std::size_t case_index = 0;
    std::string name;
    CaseKind kind = CaseKind::Static;
    std::vector<std::size_t> used;
    std::vector<std::size_t> monitor_needs;
    std::optional<std::size_t> encoder_need;   // table or linear encoder
    std::optional<MonitorFusion> monitors;
    // A static or thermal case on a bench without three monitors: the specific force is gravity in
    // the plan's pose, which a static pose is by definition (a placement error is the fixture's,
    // for the analyzer's honest inference to carry, as on a tumble with a known pose and no monitor).
    std::optional<Eigen::Vector3d> pose_specific_force;
    bool needs_temperature = false;   // a thermal case, or one with a thermal_step phase
    Eigen::VectorXd readings, monitor_bias, monitor_gain;   // calibration from the bench file
    std::vector<std::string> phase_names;
    std::map<std::int32_t, std::uint16_t> phase_labels;   // phase index (-1 unplanned) -> label
    // Table attitude, carried from phase to phase through the encoder.
    std::map<std::int32_t, frames::Dcm> attitude;
    std::map<std::int32_t, double> base;
    std::int32_t phases_seen = -1;            // highest phase index with a row
    bool attitude_pending = false;            // that phase's attitude not fixed yet
    std::optional<ComplementaryFilter> filter_before_break;   // the shaker filter of the last segment
    std::int32_t attitude_lost_from = std::numeric_limits<std::int32_t>::max();
    Eigen::Vector3d prev_axis = Eigen::Vector3d::UnitZ();
    std::optional<double> prev_base;
    frames::Dcm running_attitude = frames::Dcm::Identity();
    std::optional<Segment> segment;
    int segments_started = 0;
    std::int64_t rows = 0;
    std::map<std::string, Run> runs;
  };
  std::optional<Fuser> fuser;

  // ---------------------------------------------------------------------------------------------
  // Configuration

  void configure(const std::string& where) {
    const config::BenchConfig& b = *bench;
    if (b.sensors.empty()) throw InputError(where + ": the bench on INERTIA_BENCH has no [[sensor]] under test");
    const auto names = [&b] {
      std::string s;
      for (const auto& x : b.sensors) s += (s.empty() ? "" : ", ") + x.name;
      return s;
    };
    if (options.sensor.empty()) {
      if (b.sensors.size() > 1)
        throw InputError(where + ": the bench has " + std::to_string(b.sensors.size()) + " sensors under test (" +
                         names() + "): choose one with --sensor NAME");
      sensor = 0;
    } else {
      const auto it = std::find_if(b.sensors.begin(), b.sensors.end(), [&](const auto& s) { return s.name == options.sensor; });
      if (it == b.sensors.end())
        throw InputError(where + ": unknown sensor '" + options.sensor + "' (the bench's sensors: " + names() + ")");
      sensor = static_cast<std::size_t>(it - b.sensors.begin());
    }
    const config::SensorUnderTest& s = b.sensors[sensor];
    needs.push_back({Role::Output, 0, channel_of(s.channel, "accel", s.name)});
    for (std::size_t i = 0; i < b.monitors.size(); ++i)
      needs.push_back({Role::Monitor, i, channel_of(b.monitors[i].channel, "accel", b.monitors[i].name)});
    if (b.linear_encoder.present)
      needs.push_back({Role::LinearEncoder, 0, channel_of(b.linear_encoder.channel, "linear_encoder", "position")});
    if (b.table_encoder.present)
      needs.push_back({Role::TableEncoder, 0, channel_of(b.table_encoder.channel, "table_encoder", "position")});
    for (std::size_t i = 0; i < needs.size(); ++i) {
      DeviceState& d = devices[needs[i].ref.device];
      d.needs.push_back(i);
      d.columns.push_back(-1);
    }
    output_device = needs[0].ref.device;
    const DeviceState& od = devices[output_device];
    output_slot = static_cast<std::size_t>(std::find(od.needs.begin(), od.needs.end(), 0) - od.needs.begin());
    temp_ref = channel_of(b.thermal.channel, "controller", "temperature");
  }

  void on_bench(const bench_config_t& msg, const std::string& where) {
    if (msg.num_files < 1 || msg.paths.size() != static_cast<std::size_t>(msg.num_files) ||
        msg.texts.size() != static_cast<std::size_t>(msg.num_files))
      throw InputError(where + ": INERTIA_BENCH carries no bench file");
    std::vector<std::string> texts;
    for (std::int32_t i = 0; i < msg.num_files; ++i) {
      texts.push_back(msg.paths[static_cast<std::size_t>(i)]);
      texts.push_back(msg.texts[static_cast<std::size_t>(i)]);
    }
    if (bench) {
      if (texts != bench_texts)
        throw InputError(where + ": INERTIA_BENCH differs from the first one (bench '" + msg.bench_name +
                         "'): one log, one bench");
      return;
    }
    std::vector<config::SourceFile> sources;
    for (std::int32_t i = 0; i < msg.num_files; ++i)
      sources.push_back({msg.paths[static_cast<std::size_t>(i)], msg.texts[static_cast<std::size_t>(i)]});
    config::BenchConfig loaded;
    try {
      loaded = config::load_bench_config_from_sources(sources);
    } catch (const InputError& e) {
      throw InputError(where + ": the bench file on INERTIA_BENCH: " + e.what());
    }
    bench = std::move(loaded);
    try {
      configure(where);
    } catch (...) {
      bench.reset();
      needs.clear();
      devices.clear();
      throw;
    }
    bench_texts = std::move(texts);
  }

  // ---------------------------------------------------------------------------------------------
  // Blocks

  void on_block(const sample_block_t& block, const std::string& where) {
    if (!bench) {
      ++skipped;
      return;
    }
    if (const std::string why = block_shape_error(block); !why.empty())
      throw InputError(fmt::format("{}: device {}: malformed sample block ({})", where, block.device, why));
    if (block.num_samples == 0) return;
    if (block.device == temp_ref.device) on_temperature(block);
    const auto it = devices.find(block.device);
    if (it == devices.end()) return;
    DeviceState& d = it->second;
    std::vector<std::int32_t> columns(d.needs.size(), -1);
    for (std::size_t k = 0; k < d.needs.size(); ++k) {
      const std::string& signal = needs[d.needs[k]].ref.signal;
      for (std::int32_t c = 0; c < block.num_channels; ++c)
        if (block.channel_names[static_cast<std::size_t>(c)] == signal) columns[k] = c;
      if (columns[k] < 0)
        throw InputError(where + ": device " + block.device + " has no channel '" + signal + "' (needed as " +
                         needs[d.needs[k]].ref.label() + ")");
    }
    const double period_ns = 1e9 * block.sample_period_s;
    const double t0 = static_cast<double>(block.t0_mono_ns);
    const std::int64_t seq = block.num_channels > 0 ? block.channel_seq[0] : 0;
    if (!std::isnan(d.next_ns)) {
      if (t0 < d.next_ns - 0.5 * period_ns)
        throw InputError(fmt::format("{}: device {} block starts {:.1f} us before the end of its previous block: blocks "
                                     "out of order or overlapping",
                                     where, block.device, (d.next_ns - t0) * 1e-3));
      const double missing = (t0 - d.next_ns) / period_ns;
      if (missing > 0.5 || seq != *d.next_seq)
        gaps.push_back({block.device, where, std::llround(missing), std::max<std::int64_t>(0, seq - *d.next_seq)});
    }
    d.columns = columns;
    d.next_ns = t0 + static_cast<double>(block.num_samples) * period_ns;
    d.next_seq = seq + block.num_samples;
    StoredBlock sb;
    sb.seq0 = seq;
    sb.n = block.num_samples;
    sb.t0_ns = t0;
    sb.period_ns = period_ns;
    for (std::size_t k = 0; k < d.needs.size(); ++k) {
      const auto c = static_cast<std::size_t>(d.columns[k]);
      const auto& v = block.values[c];
      sb.values.emplace_back(v.begin(), v.begin() + block.num_samples);
      std::vector<std::uint8_t> ok(static_cast<std::size_t>(block.num_samples));
      for (std::int32_t s = 0; s < block.num_samples; ++s)
        ok[static_cast<std::size_t>(s)] =
            sample_valid(block, d.columns[k], s) && std::isfinite(v[static_cast<std::size_t>(s)]);
      sb.valid.push_back(std::move(ok));
    }
    d.newest_ns = std::max(d.newest_ns, sb.last_ns());
    d.blocks.push_back(std::move(sb));
    advance();
  }

  void on_temperature(const sample_block_t& block) {
    for (std::int32_t c = 0; c < block.num_channels; ++c) {
      if (block.channel_names[static_cast<std::size_t>(c)] != temp_ref.signal) continue;
      for (std::int32_t s = 0; s < block.num_samples; ++s) {
        const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
        const double t = static_cast<double>(block.t0_mono_ns) + block.sample_period_s * 1e9 * s;
        temp_newest_ns = std::max(temp_newest_ns, t);
        if (!sample_valid(block, c, s) || !std::isfinite(v)) continue;
        if (!temps.empty() && t < temps.back().t_ns) continue;   // out of order: keep the timeline monotonic
        temps.push_back({t, v});
      }
    }
  }

  // ---------------------------------------------------------------------------------------------
  // Markers

  void on_event(const plan_event_t& ev, const std::string& where) {
    if (!bench) {
      notes.push_back(where + ": plan marker before INERTIA_BENCH ignored");
      return;
    }
    std::size_t index = bench->cases.size();
    for (std::size_t i = 0; i < bench->cases.size(); ++i)
      if (bench->cases[i].name == ev.case_name) index = i;
    if (index == bench->cases.size())
      throw InputError(where + ": marker for case '" + ev.case_name + "', which the bench's test plan does not have");
    const double period_ns = output_period_ns();
    CaseMarks* open = nullptr;
    for (CaseMarks& c : cases)
      if (!c.ended) open = &c;
    switch (ev.mark) {
      case plan_event_t::MARK_CASE_START:
        saw_case_marker = true;
        if (open != nullptr) {
          // A bench runs one case at a time: the new start ends the open one (its end marker was
          // lost, or the case was restarted).
          notes.push_back(where + ": case " + ev.case_name + " started while case " + open->name +
                          " had not ended: that case ends here");
          open->ended = true;
          open->last_ns = static_cast<double>(ev.start_mono_ns) - period_ns;
        }
        cases.push_back({index, ev.case_name, static_cast<double>(ev.start_mono_ns), 0.0, false, false, {}});
        break;
      case plan_event_t::MARK_CASE_END:
      case plan_event_t::MARK_ABORT:
        if (open == nullptr || open->case_index != index) {
          notes.push_back(where + ": end of case " + ev.case_name + " without its start: ignored");
          break;
        }
        open->ended = true;
        open->aborted = ev.mark == plan_event_t::MARK_ABORT;
        open->last_ns = static_cast<double>(ev.mark == plan_event_t::MARK_ABORT ? ev.mono_ns : ev.end_mono_ns);
        if (open->aborted) notes.push_back(where + ": case " + ev.case_name + " aborted; its samples up to the abort are used");
        break;
      case plan_event_t::MARK_PHASE_START:
        if (open == nullptr || open->case_index != index) {
          notes.push_back(where + ": phase marker of case " + ev.case_name + " outside the case: ignored");
          break;
        }
        open->phases.push_back({static_cast<double>(ev.start_mono_ns), static_cast<double>(ev.end_mono_ns),
                                ev.phase_index, ev.phase.empty() ? std::string("phase") : ev.phase});
        std::stable_sort(open->phases.begin(), open->phases.end(),
                         [](const PhaseMark& a, const PhaseMark& c) { return a.start_ns < c.start_ns; });
        break;
      default: break;  // MARK_PHASE_END: the next start (or the case end) closes a phase
    }
    const double t = static_cast<double>(std::max({ev.mono_ns, ev.start_mono_ns, ev.mark == plan_event_t::MARK_CASE_END ? ev.end_mono_ns : 0}));
    marker_newest_ns = std::max(marker_newest_ns, t);
    advance();
  }

  // ---------------------------------------------------------------------------------------------
  // Reading the devices at a row's time

  [[nodiscard]] double output_period_ns() const {
    const auto it = devices.find(output_device);
    if (it != devices.end() && !it->second.blocks.empty()) return it->second.blocks.front().period_ns;
    return 1e9 / bench->sample_rate_hz;
  }

  [[nodiscard]] double output_newest_ns() const {
    const auto it = devices.find(output_device);
    return it == devices.end() ? -std::numeric_limits<double>::infinity() : it->second.newest_ns;
  }

  /// Past max_wait: a device (or the markers) this far behind the output is not waited for.
  [[nodiscard]] bool given_up(double t_ns) const {
    return finishing || output_newest_ns() - t_ns > options.max_wait_s * 1e9;
  }

  /// Sample `seq` of device `d` (by its sample counter): its block and position, or none.
  static const StoredBlock* find_sample(const DeviceState& d, std::int64_t seq, std::int32_t& s) {
    for (auto it = d.blocks.rbegin(); it != d.blocks.rend(); ++it) {
      if (seq >= it->seq0 && seq < it->seq0 + it->n) {
        s = static_cast<std::int32_t>(seq - it->seq0);
        return &*it;
      }
      if (it->seq0 + it->n <= seq) break;
    }
    return nullptr;
  }

  /// The need's value at time t (ns): the device's sample at that instant, or a 4-point Lagrange
  /// interpolation between its samples around it.
  Read read(std::size_t need, double t, double& value) const {
    const DeviceState& d = devices.at(needs[need].ref.device);
    std::size_t slot = 0;
    while (d.needs[slot] != need) ++slot;
    // The block whose span holds t (or the last one starting before it).
    const StoredBlock* b = nullptr;
    for (auto it = d.blocks.rbegin(); it != d.blocks.rend(); ++it) {
      if (it->t0_ns <= t + 0.5 * it->period_ns) {
        b = &*it;
        break;
      }
    }
    if (b == nullptr) return d.newest_ns < t && !given_up(t) ? Read::NotYet : Read::Missing;
    const double x = (t - b->t0_ns) / b->period_ns;
    // A sample index that no int64 holds (a period of 1e-300 s: the cast below would be undefined;
    // found by fuzz_event_log) lies past every stored sample: as when the next block did not follow on.
    if (!(x < kMaxSampleIndex)) return d.newest_ns < t && !given_up(t) ? Read::NotYet : Read::Missing;
    const double nearest = std::round(x);
    if (std::abs(x - nearest) <= 1e-3) {
      // The device samples at this instant (one clock, as on the simulated benches).
      const auto s = static_cast<std::int64_t>(nearest);
      if (s < b->n) {
        value = b->values[slot][static_cast<std::size_t>(s)];
        return b->valid[slot][static_cast<std::size_t>(s)] ? Read::Ok : Read::Invalid;
      }
      if (d.newest_ns < t && !given_up(t)) return Read::NotYet;
      return Read::Missing;   // past the block, and the next one did not follow on
    }
    // Another clock: Lagrange through the samples at floor(x) - 1 .. floor(x) + 2.
    const std::int64_t base = b->seq0 + static_cast<std::int64_t>(std::floor(x)) - 1;
    const double u = x - std::floor(x) + 1.0;   // position in the 4-point stencil, in (1, 2)
    double sum = 0.0;
    for (int j = 0; j < 4; ++j) {
      std::int32_t s = 0;
      const StoredBlock* sb = find_sample(d, base + j, s);
      if (sb == nullptr) return d.next_seq && base + j >= *d.next_seq && !given_up(t) ? Read::NotYet : Read::Missing;
      if (!sb->valid[slot][static_cast<std::size_t>(s)]) return Read::Invalid;
      double w = 1.0;
      for (int m = 0; m < 4; ++m)
        if (m != j) w *= (u - m) / static_cast<double>(j - m);
      sum += w * sb->values[slot][static_cast<std::size_t>(s)];
    }
    value = sum;
    return Read::Ok;
  }

  // ---------------------------------------------------------------------------------------------
  // Rows

  /// The case a row at t belongs to; nullptr when none. `ready` false when markers still to come
  /// could change the answer.
  CaseMarks* case_of(double t, double half, bool& ready) {
    ready = true;
    for (CaseMarks& c : cases) {
      if (t < c.start_ns - half) continue;
      if (c.ended && t > c.last_ns + half) continue;
      return &c;
    }
    // No case holds it: a start marker could still come for it.
    if (marker_newest_ns < t && !given_up(t)) ready = false;
    return nullptr;
  }

  /// Whether the phase of a row at t in case c is settled: a later marker arrived, the phase's
  /// planned end lies beyond t, or the markers are given up on.
  bool phase_settled(const CaseMarks& c, double t, double half) const {
    if (marker_newest_ns > t + half || c.ended) return true;
    const PhaseMark* current = nullptr;
    for (const PhaseMark& p : c.phases)
      if (p.start_ns <= t + half) current = &p;
    if (current != nullptr && current->end_ns > t + half) return true;
    return given_up(t);
  }

  /// Reads and fuses every output sample whose inputs are all known.
  void advance() {
    if (!bench) return;
    auto it = devices.find(output_device);
    if (it == devices.end()) return;
    DeviceState& od = it->second;
    while (cursor_block < od.blocks.size()) {
      const StoredBlock& b = od.blocks[cursor_block];
      if (cursor_sample == 0 && previous_output) {
        note_output_gap(*previous_output, b);
        previous_output.reset();
      }
      if (cursor_sample >= b.n) {
        previous_output = StoredBlock{b.seq0, b.n, b.t0_ns, b.period_ns, {}, {}};
        ++cursor_block;
        cursor_sample = 0;
        continue;
      }
      if (!process_row(b, cursor_sample)) break;
      last_read_ns = b.time(cursor_sample);
      ++cursor_sample;
    }
    // A case whose end marker arrived and whose last row is read is over now, not at the next row.
    if (fuser && fuser->marks->ended && last_read_ns + 0.5 * output_period_ns() >= fuser->marks->last_ns &&
        &cases.front() == fuser->marks)
      close_case();
    release();
    flush_chunk();
  }

  /// An output gap between two blocks ends the open segment (the rows are not there).
  void note_output_gap(const StoredBlock& a, const StoredBlock& b) {
    const double missing = (b.t0_ns - a.time(a.n)) / a.period_ns;
    if (missing <= 0.5 && b.seq0 == a.seq0 + a.n) return;
    if (fuser && fuser->segment) {
      const auto n = std::max<std::int64_t>(std::llround(missing), b.seq0 - (a.seq0 + a.n));
      const double t_case = (a.time(a.n) - fuser->marks->start_ns) * 1e-9;
      end_segment();
      exclusions.push_back({fuser->name, needs[0].ref.label() + " missing (gap)", t_case, std::max<std::int64_t>(n, 1)});
    }
  }

  /// One output sample. False when it must wait for more messages.
  bool process_row(const StoredBlock& ob, std::int32_t s) {
    const double t = ob.time(s);
    const double half = 0.5 * ob.period_ns;
    bool ready = true;
    CaseMarks* c = case_of(t, half, ready);
    if (!ready) return false;
    // Cases wholly before this row are over.
    while (!cases.empty() && &cases.front() != c && cases.front().ended && cases.front().last_ns + half < t) close_case();
    if (c == nullptr) return true;   // between cases
    if (!phase_settled(*c, t, half)) return false;
    if (!fuser || fuser->marks != c) open_case(*c);
    Fuser& f = *fuser;

    // Every input of the row, or the reason it has none.
    std::vector<std::string> reasons;
    bool encoder_lost = false;   // the fusion's state cannot go on through this row
    const double y = ob.values[output_slot][static_cast<std::size_t>(s)];
    if (!ob.valid[output_slot][static_cast<std::size_t>(s)]) reasons.push_back(needs[0].ref.label() + " invalid");
    Eigen::Index m = 0;
    double encoder = 0.0;
    for (std::size_t k : f.used) {
      if (k == 0) continue;
      double v = 0.0;
      const Read r = read(k, t, v);
      if (r == Read::NotYet) return false;
      if (r == Read::Invalid) reasons.push_back(needs[k].ref.label() + " invalid");
      if (r == Read::Missing) reasons.push_back(needs[k].ref.label() + " missing (gap)");
      if (r != Read::Ok && needs[k].role != Role::Monitor) encoder_lost = true;
      if (needs[k].role == Role::Monitor) {
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
    if (!f.segment && temps.empty() && f.needs_temperature && !finishing &&
        output_newest_ns() - t < kFirstTemperatureWaitS * 1e9)
      return false;
    const bool with_temp = f.segment ? f.segment->has_temp : !temps.empty();
    if (with_temp) {
      if (temp_newest_ns < t && !given_up(t)) return false;
      temp = held_temperature(t);
    }

    const double t_case = (t - c->start_ns) * 1e-9;
    RawRow row;
    row.t_ns = t;
    row.t_case_s = t_case;
    row.y = y;
    row.encoder = encoder;
    row.temp = temp;
    label_phase(f, *c, t, half, row);
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
    last_row_ns = t;
    return true;
  }

  [[nodiscard]] double held_temperature(double t) const {
    // The last controller reading at or before t (the first one for rows before it).
    auto it = std::upper_bound(temps.begin(), temps.end(), t, [](double x, const TempSample& ts) { return x < ts.t_ns; });
    return it == temps.begin() ? temps.front().value : std::prev(it)->value;
  }

  void label_phase(Fuser& f, const CaseMarks& c, double t, double half, RawRow& row) {
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

  /// The table's attitude at the row's phase (tracked through the encoder from the case's start
  /// attitude): false when it is unknown (a rotation whose first row had no angle, or any phase
  /// after it). A phase at rest (not a rotation) may fix it at its first usable row instead: the
  /// table has not turned since the phase began, so any of its angles is the phase's start angle
  /// (on a real time base a device's first sample can come a fraction of a period after another's).
  bool table_attitude(Fuser& f, const RawRow& row, bool usable) {
    const std::int32_t p = row.phase_index;
    if (p < 0) return false;
    const config::TestCase& tc = bench->cases[f.case_index];
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

  void count_exclusions(Fuser& f, const std::vector<std::string>& reasons, double t_case) {
    for (auto it = f.runs.begin(); it != f.runs.end();) {
      if (std::find(reasons.begin(), reasons.end(), it->first) == reasons.end()) {
        exclusions.push_back({f.name, it->first, it->second.t_case_s, it->second.samples});
        it = f.runs.erase(it);
      } else {
        ++it;
      }
    }
    for (const std::string& r : reasons) {
      auto [it, fresh] = f.runs.try_emplace(r, Run{t_case, 0});
      ++it->second.samples;
    }
  }

  // ---------------------------------------------------------------------------------------------
  // Cases and segments

  void open_case(CaseMarks& c) {
    if (fuser) close_fuser();
    const config::BenchConfig& b = *bench;
    const config::TestCase& tc = b.cases[c.case_index];
    Fuser f;
    f.marks = &c;
    f.case_index = c.case_index;
    f.name = c.name;
    f.kind = tc.kind;
    for (std::size_t k = 0; k < needs.size(); ++k) {
      const Role r = needs[k].role;
      const bool use = r == Role::Output || (r == Role::Monitor && tc.kind != CaseKind::RotationTable) ||
                       (r == Role::LinearEncoder && tc.kind == CaseKind::Shaker) ||
                       (r == Role::TableEncoder && tc.kind == CaseKind::RotationTable);
      if (!use) continue;
      f.used.push_back(k);
      if (r == Role::Monitor) f.monitor_needs.push_back(k);
      if (r == Role::LinearEncoder || r == Role::TableEncoder) f.encoder_need = k;
    }
    if (tc.kind == CaseKind::RotationTable && !f.encoder_need)
      throw InputError("case " + c.name + " (rotation_table): the bench has no [table_encoder] to fuse it with");
    const bool pose = tc.kind == CaseKind::Static || tc.kind == CaseKind::Thermal;
    if (pose && f.monitor_needs.size() < 3) {
      f.pose_specific_force = kStandardGravity * tc.start_attitude.dcm().col(2);
      f.monitor_needs.clear();
      std::erase_if(f.used, [&](std::size_t k) { return needs[k].role == Role::Monitor; });
    } else if (tc.kind != CaseKind::RotationTable) {
      if (f.monitor_needs.size() < 3)
        throw InputError("case " + c.name + " (" + to_string(tc.kind) +
                         "): fusion needs at least three [[monitor]] accelerometers (or, in a static or thermal case, "
                         "none: the pose's gravity), the bench has " +
                         std::to_string(f.monitor_needs.size()));
      // Monitors: calibrated (bias, scale, misalignment from the bench file), then WLS.
      MonitorLayout layout;
      const auto count = static_cast<Eigen::Index>(f.monitor_needs.size());
      f.readings.resize(count);
      f.monitor_bias.resize(count);
      f.monitor_gain.resize(count);
      for (Eigen::Index j = 0; j < count; ++j) {
        const config::MonitorAccelerometer& m = b.monitors[needs[f.monitor_needs[static_cast<std::size_t>(j)]].index];
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
    fuser = std::move(f);
  }

  void start_segment(bool with_temp) {
    Fuser& f = *fuser;
    Segment s;
    s.number = f.segments_started++;
    s.has_temp = with_temp;
    const double dt = output_period_ns() * 1e-9;
    s.differences = CentralDifferences(dt);
    if (f.kind == CaseKind::Shaker && f.encoder_need && 1.0 / dt > 2.0 * options.crossover_hz) {
      // After a break within the case the filter goes on from its state before it: what its low
      // paths hold (the monitors' slow error against the encoder) does not change over a gap,
      // while a filter started afresh in mid-vibration would settle on one sample of the
      // encoder's second difference, whose error at high frequency is a large fraction of the
      // vibration, and ring on it for a few tenths of a second.
      if (f.filter_before_break) {
        s.filter = std::move(f.filter_before_break);
        f.filter_before_break.reset();
      } else {
        s.filter.emplace(dt, options.crossover_hz);
      }
    }
    f.segment = std::move(s);
  }

  /// Turns the raw rows whose differences are final into fused rows.
  void finalize_ready(bool ending) {
    Fuser& f = *fuser;
    Segment& s = *f.segment;
    if (ending) s.differences.finish();
    const config::TestCase& tc = bench->cases[f.case_index];
    const config::SensorUnderTest& sut = bench->sensors[sensor];
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

  void append(Segment& s, const RawRow& row, const Eigen::Vector3d& a, const Eigen::Vector3d& w) {
    FusedChunk& out = s.out;
    if (out.rows() == 0) {
      Fuser& f = *fuser;
      if (s.next_piece) {
        s.number = f.segments_started++;
        s.next_piece = false;
      }
      out.case_index = f.case_index;
      out.case_name = f.name;
      out.kind = f.kind;
      out.segment = s.number;
      out.sample_period_s = output_period_ns() * 1e-9;
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

  void flush_chunk() {
    if (!fuser || !fuser->segment || fuser->segment->out.rows() == 0) return;
    FusedChunk& out = fuser->segment->out;
    out.phase_names = fuser->phase_names;
    rows_out += out.rows();
    sink->on_rows(std::move(out));
    out = FusedChunk{};
  }

  /// The piece of output rows before a hole, or at the segment's end, ends: kept or dropped.
  void end_piece() {
    Fuser& f = *fuser;
    Segment& s = *f.segment;
    flush_chunk();
    if (s.piece_rows == 0) return;
    // In rows of the output's period; a hostile period (1e-150 s) would make the count overflow
    // int64 (found by fuzz_stream_assembler): no segment is that long, so it keeps none.
    const double min_rows = std::ceil(options.min_segment_s / (output_period_ns() * 1e-9));
    const std::int64_t min_len = min_rows < 9.0e18 ? static_cast<std::int64_t>(min_rows) : std::numeric_limits<std::int64_t>::max();
    const bool kept = s.piece_rows >= std::max<std::int64_t>(min_len, 3);
    if (kept) {
      rows_kept += s.piece_rows;
      f.rows += s.piece_rows;
    } else {
      exclusions.push_back({f.name, fmt::format("valid stretch shorter than {} s", options.min_segment_s),
                            s.piece_first_t_case, s.piece_rows});
    }
    sink->on_segment_end({f.case_index, f.name, s.number, s.piece_rows, kept});
    s.piece_rows = 0;
    s.next_piece = true;
  }

  void end_segment() {
    Fuser& f = *fuser;
    if (!f.segment) return;
    finalize_ready(true);
    end_piece();
    Segment& s = *f.segment;
    if (s.filter) f.filter_before_break = std::move(s.filter);
    f.segment.reset();
  }

  void close_fuser() {
    if (!fuser) return;
    end_segment();
    Fuser& f = *fuser;
    for (const auto& [reason, run] : f.runs) exclusions.push_back({f.name, reason, run.t_case_s, run.samples});
    if (f.rows == 0) notes.push_back("case " + f.name + " has no usable samples");
    fuser.reset();
  }

  /// The front case is over: its fusion ends.
  void close_case() {
    if (fuser && fuser->marks == &cases.front()) close_fuser();
    cases.erase(cases.begin());
  }

  // ---------------------------------------------------------------------------------------------
  // Memory

  void release() {
    auto it = devices.find(output_device);
    if (it == devices.end()) return;
    DeviceState& od = it->second;
    // Output blocks before the cursor are read.
    while (cursor_block > 0) {
      od.blocks.pop_front();
      --cursor_block;
    }
    if (od.blocks.empty()) return;
    const StoredBlock& cur = od.blocks.front();
    const double keep_from = cur.time(std::min(cursor_sample, cur.n - 1));
    for (auto& [name, d] : devices) {
      if (name == output_device) continue;
      // Keep two samples before the next row's time for interpolation.
      while (d.blocks.size() > 1 && d.blocks[1].t0_ns + 2.0 * d.blocks[1].period_ns < keep_from &&
             d.blocks.front().last_ns() + 2.0 * d.blocks.front().period_ns < keep_from)
        d.blocks.pop_front();
    }
    if (temps.size() > 2) {
      auto t = std::upper_bound(temps.begin(), temps.end(), keep_from, [](double x, const TempSample& ts) { return x < ts.t_ns; });
      if (t != temps.begin() && std::prev(t) != temps.begin()) temps.erase(temps.begin(), std::prev(t));
    }
  }

  void finish() {
    finishing = true;
    advance();
    if (fuser && !fuser->marks->ended) notes.push_back("case " + fuser->name + " has no end marker: cut at the last sample recorded");
    close_fuser();
    cases.clear();
  }
};

StreamAssembler::StreamAssembler(AssemblerOptions options, FusionSink& sink) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->sink = &sink;
}

StreamAssembler::StreamAssembler(AssemblerOptions options, SegmentSink sink)
    : own_collector_(std::make_unique<SegmentCollector>(std::move(sink))), impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->sink = own_collector_.get();
}

StreamAssembler::~StreamAssembler() = default;

void StreamAssembler::push(const bench_config_t& bench, const std::string& where) { impl_->on_bench(bench, where); }
void StreamAssembler::push(const sample_block_t& block, const std::string& where) { impl_->on_block(block, where); }
void StreamAssembler::push(const plan_event_t& event, const std::string& where) { impl_->on_event(event, where); }

void StreamAssembler::finish() {
  if (!impl_->bench) throw InputError("no INERTIA_BENCH message: the bench the data was recorded on is unknown");
  if (!impl_->saw_case_marker)
    throw InputError("no case markers (INERTIA_EVENT MARK_CASE_START): the samples cannot be cut into cases");
  impl_->finish();
}

bool StreamAssembler::has_bench() const noexcept { return impl_->bench.has_value(); }
const config::BenchConfig& StreamAssembler::bench() const {
  if (!impl_->bench) throw std::logic_error("StreamAssembler: no bench yet");
  return *impl_->bench;
}
std::size_t StreamAssembler::sensor_index() const { return impl_->sensor; }
const std::vector<Exclusion>& StreamAssembler::exclusions() const noexcept { return impl_->exclusions; }
const std::vector<StreamGap>& StreamAssembler::gaps() const noexcept { return impl_->gaps; }

std::string describe(const StreamGap& gap) {
  return fmt::format("{} missing {} sample(s) (channel_seq jump {}) before {}", gap.device, gap.missing_samples,
                     gap.missing_seq, gap.where);
}
std::int64_t StreamAssembler::skipped_blocks() const noexcept { return impl_->skipped; }
std::int64_t StreamAssembler::fused_rows() const noexcept { return impl_->rows_kept; }
std::int64_t StreamAssembler::rows_out() const noexcept { return impl_->rows_out; }
const std::vector<std::string>& StreamAssembler::notes() const noexcept { return impl_->notes; }

}  // namespace inertia::fusion
