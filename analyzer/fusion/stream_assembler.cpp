#include "analyzer/fusion/stream_assembler.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "analyzer/fusion/reference_fusion.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "common/units.hpp"

namespace inertia::fusion {
namespace {

// What a needed channel is to the fusion of the sensor under test.
enum class Role { Output, Monitor, LinearEncoder, TableEncoder };

struct ChannelRef {
  std::string device;
  std::string signal;
  [[nodiscard]] std::string label() const { return device + "." + signal; }
};

// "<device>.<signal>" from the bench file, or the simulator's device and signal names.
ChannelRef channel_of(const std::string& configured, const std::string& sim_device, const std::string& sim_signal) {
  if (configured.empty()) return {sim_device, sim_signal};
  const auto dot = configured.find('.');
  if (dot == std::string::npos) return {configured, sim_signal};
  return {configured.substr(0, dot), configured.substr(dot + 1)};
}

struct Need {
  Role role;
  std::size_t index = 0;   // monitor index
  ChannelRef ref;
};

// One stored block of a fast device: the needed channels only.
struct StoredBlock {
  std::int64_t first = 0;                       // timeline index of sample 0
  std::int32_t n = 0;
  std::vector<std::vector<double>> values;      // per device-need slot
  std::vector<std::vector<std::uint8_t>> valid;
};

struct DeviceState {
  std::vector<std::size_t> needs;               // indices into Impl::needs
  std::vector<std::int32_t> columns;            // block column of each need, -1 until seen
  std::vector<StoredBlock> blocks;              // ascending `first`
  std::int64_t next_index = std::numeric_limits<std::int64_t>::min();
  std::int64_t next_channel_seq = -1;
  std::int64_t last_index = std::numeric_limits<std::int64_t>::min();  // highest index received
};

struct TempSample {
  std::int64_t t_ns;
  double value;
};

struct PhaseMark {
  std::int64_t start_ns;
  std::int32_t phase_index;
  std::string label;
};

struct CaseMarks {
  std::size_t case_index = 0;
  std::string name;
  std::int64_t start_ns = 0;
  std::int64_t last_ns = 0;      // last sample (inclusive); valid when ended
  bool ended = false;
  bool aborted = false;
  std::vector<PhaseMark> phases;
};

std::int64_t round_index(double x) { return static_cast<std::int64_t>(std::llround(x)); }

}  // namespace

struct StreamAssembler::Impl {
  AssemblerOptions options;
  SegmentSink sink;
  std::optional<config::BenchConfig> bench;
  std::vector<std::string> bench_texts;   // paths + texts of the first bench, to compare repeats
  std::size_t sensor = 0;
  std::vector<Need> needs;
  std::map<std::string, DeviceState> devices;
  ChannelRef temp_ref;
  std::vector<TempSample> temps;
  double period_s = 0.0;
  double period_ns = 0.0;
  std::optional<std::int64_t> origin_ns;
  std::vector<CaseMarks> cases;           // in marker order; fused ones are removed
  bool saw_case_marker = false;
  std::vector<Exclusion> exclusions;
  std::vector<StreamGap> gaps;
  std::vector<std::string> notes;
  std::int64_t skipped = 0;
  std::int64_t rows = 0;

  [[nodiscard]] std::int64_t index_of(std::int64_t t_ns) const {
    return round_index(static_cast<double>(t_ns - *origin_ns) / period_ns);
  }

  void configure(const std::string& where) {
    const config::BenchConfig& b = *bench;
    if (b.sensors.empty()) throw InputError(where + ": the bench on INERTIA_BENCH has no [[sensor]] under test");
    if (options.sensor.empty()) {
      if (b.sensors.size() > 1) {
        std::string names;
        for (const auto& s : b.sensors) names += (names.empty() ? "" : ", ") + s.name;
        throw InputError(where + ": the bench has " + std::to_string(b.sensors.size()) +
                         " sensors under test (" + names + "): choose one with --sensor NAME");
      }
      sensor = 0;
    } else {
      bool found = false;
      for (std::size_t i = 0; i < b.sensors.size(); ++i) {
        if (b.sensors[i].name == options.sensor) {
          sensor = i;
          found = true;
        }
      }
      if (!found) {
        std::string names;
        for (const auto& s : b.sensors) names += (names.empty() ? "" : ", ") + s.name;
        throw InputError(where + ": unknown sensor '" + options.sensor + "' (the bench's sensors: " + names + ")");
      }
    }
    period_s = 1.0 / b.sample_rate_hz;
    period_ns = 1e9 * period_s;
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
    try {
      bench = config::load_bench_config_from_sources(sources);
    } catch (const InputError& e) {
      throw InputError(where + ": the bench file on INERTIA_BENCH: " + e.what());
    }
    bench_texts = std::move(texts);
    configure(where);
  }

  void on_block(const sample_block_t& block, const std::string& where) {
    if (!bench) {
      ++skipped;
      return;
    }
    if (block.device == temp_ref.device) on_temperature(block);
    const auto it = devices.find(block.device);
    if (it == devices.end()) return;
    DeviceState& d = it->second;
    if (block.num_samples <= 0) return;
    if (std::abs(block.sample_period_s - period_s) > 1e-9 * period_s)
      throw InputError(fmt::format("{}: device {} samples every {} s, the bench every {} s: its samples cannot be "
                                   "put on the bench's sample timeline",
                                   where, block.device, block.sample_period_s, period_s));
    for (std::size_t k = 0; k < d.needs.size(); ++k) {
      const std::string& signal = needs[d.needs[k]].ref.signal;
      std::int32_t col = -1;
      for (std::int32_t c = 0; c < block.num_channels; ++c)
        if (block.channel_names[static_cast<std::size_t>(c)] == signal) col = c;
      if (col < 0)
        throw InputError(where + ": device " + block.device + " has no channel '" + signal + "' (needed as " +
                         needs[d.needs[k]].ref.label() + ")");
      d.columns[k] = col;
    }
    if (!origin_ns) origin_ns = block.t0_mono_ns;
    const std::int64_t first = index_of(block.t0_mono_ns);
    const std::int64_t seq = block.num_channels > 0 ? block.channel_seq[0] : 0;
    if (d.next_index != std::numeric_limits<std::int64_t>::min()) {
      if (first < d.next_index)
        throw InputError(fmt::format("{}: device {} block starts at sample {} of the timeline, before the end of the "
                                     "previous block ({}): blocks out of order or overlapping",
                                     where, block.device, first, d.next_index));
      if (first > d.next_index || seq != d.next_channel_seq) {
        gaps.push_back({block.device, where, first - d.next_index, std::max<std::int64_t>(0, seq - d.next_channel_seq)});
      }
    }
    d.next_index = first + block.num_samples;
    d.next_channel_seq = seq + block.num_samples;
    d.last_index = d.next_index - 1;
    StoredBlock sb;
    sb.first = first;
    sb.n = block.num_samples;
    for (std::size_t k = 0; k < d.needs.size(); ++k) {
      const auto c = d.columns[k];
      const auto& v = block.values[static_cast<std::size_t>(c)];
      sb.values.emplace_back(v.begin(), v.begin() + block.num_samples);
      std::vector<std::uint8_t> ok(static_cast<std::size_t>(block.num_samples));
      for (std::int32_t s = 0; s < block.num_samples; ++s)
        ok[static_cast<std::size_t>(s)] = sample_valid(block, c, s) && std::isfinite(v[static_cast<std::size_t>(s)]);
      sb.valid.push_back(std::move(ok));
    }
    d.blocks.push_back(std::move(sb));
    fuse_ready(false);
  }

  void on_temperature(const sample_block_t& block) {
    for (std::int32_t c = 0; c < block.num_channels; ++c) {
      if (block.channel_names[static_cast<std::size_t>(c)] != temp_ref.signal) continue;
      for (std::int32_t s = 0; s < block.num_samples; ++s) {
        const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
        if (!sample_valid(block, c, s) || !std::isfinite(v)) continue;
        const double dt_ns = block.sample_period_s * 1e9 * s;
        temps.push_back({block.t0_mono_ns + static_cast<std::int64_t>(std::llround(dt_ns)), v});
      }
    }
  }

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
    CaseMarks* open = nullptr;
    for (CaseMarks& c : cases)
      if (c.case_index == index && !c.ended) open = &c;
    switch (ev.mark) {
      case plan_event_t::MARK_CASE_START:
        saw_case_marker = true;
        if (open != nullptr) {
          notes.push_back(where + ": case " + ev.case_name + " started again before it ended; the first run ends here");
          open->ended = true;
          open->last_ns = ev.start_mono_ns - static_cast<std::int64_t>(period_ns);
        }
        cases.push_back({index, ev.case_name, ev.start_mono_ns, 0, false, false, {}});
        break;
      case plan_event_t::MARK_CASE_END:
      case plan_event_t::MARK_ABORT:
        if (open == nullptr) {
          notes.push_back(where + ": end of case " + ev.case_name + " without its start: ignored");
          break;
        }
        open->ended = true;
        open->aborted = ev.mark == plan_event_t::MARK_ABORT;
        open->last_ns = ev.mark == plan_event_t::MARK_ABORT ? ev.mono_ns : ev.end_mono_ns;
        if (open->aborted) notes.push_back(where + ": case " + ev.case_name + " aborted; its samples up to the abort are used");
        break;
      case plan_event_t::MARK_PHASE_START:
        if (open == nullptr) {
          notes.push_back(where + ": phase marker of case " + ev.case_name + " outside the case: ignored");
          break;
        }
        open->phases.push_back({ev.start_mono_ns, ev.phase_index, ev.phase.empty() ? std::string("phase") : ev.phase});
        break;
      default: break;  // MARK_PHASE_END: the next start (or the case end) closes a phase
    }
    fuse_ready(false);
  }

  // Fuses every ended case whose samples have all arrived (at the end: every case).
  void fuse_ready(bool final) {
    if (!origin_ns) return;
    while (!cases.empty()) {
      CaseMarks& c = cases.front();
      if (!c.ended && !final) return;
      std::int64_t last;
      if (c.ended) {
        last = index_of(c.last_ns);
      } else {
        last = std::numeric_limits<std::int64_t>::min();
        for (const auto& [name, d] : devices) last = std::max(last, d.last_index);
        notes.push_back("case " + c.name + " has no end marker: cut at the last sample recorded");
      }
      if (!final) {
        for (const auto& [name, d] : devices)
          if (d.last_index < last) return;   // still arriving
      }
      CaseMarks done = std::move(c);
      cases.erase(cases.begin());
      fuse_case(done, index_of(done.start_ns), last);
      release_before(last + 1);
    }
  }

  void release_before(std::int64_t index) {
    for (auto& [name, d] : devices) {
      auto keep = std::find_if(d.blocks.begin(), d.blocks.end(),
                               [index](const StoredBlock& b) { return b.first + b.n > index; });
      d.blocks.erase(d.blocks.begin(), keep);
    }
    if (!cases.empty() || temps.size() < 2) return;
    // Keep the last temperature before the next case: it is held into it.
    const double t_ns = static_cast<double>(*origin_ns) + static_cast<double>(index) * period_ns;
    auto it = std::upper_bound(temps.begin(), temps.end(), t_ns,
                               [](double t, const TempSample& s) { return t < static_cast<double>(s.t_ns); });
    if (it != temps.begin()) temps.erase(temps.begin(), it - 1);
  }

  // Values and validity of need `k` over [i0, i0 + n): missing samples (no block) flagged 2.
  void gather(std::size_t k, std::int64_t i0, std::int64_t n, Eigen::VectorXd& value, std::vector<std::uint8_t>& state) {
    value.setZero(n);
    state.assign(static_cast<std::size_t>(n), 2);
    DeviceState& d = devices.at(needs[k].ref.device);
    std::size_t slot = 0;
    while (d.needs[slot] != k) ++slot;
    for (const StoredBlock& b : d.blocks) {
      const std::int64_t lo = std::max(i0, b.first), hi = std::min(i0 + n, b.first + b.n);
      for (std::int64_t i = lo; i < hi; ++i) {
        const auto s = static_cast<std::size_t>(i - b.first);
        value(i - i0) = b.values[slot][s];
        state[static_cast<std::size_t>(i - i0)] = b.valid[slot][s] ? 0 : 1;
      }
    }
  }

  void exclude_runs(const std::string& case_name, const std::vector<std::uint8_t>& bad, const std::string& reason) {
    for (std::size_t i = 0; i < bad.size();) {
      if (!bad[i]) {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < bad.size() && bad[j]) ++j;
      exclusions.push_back({case_name, reason, static_cast<double>(i) * period_s, static_cast<std::int64_t>(j - i)});
      i = j;
    }
  }

  void fuse_case(const CaseMarks& marks, std::int64_t i0, std::int64_t i1) {
    const config::BenchConfig& b = *bench;
    const config::TestCase& tc = b.cases[marks.case_index];
    const std::int64_t n = i1 - i0 + 1;
    if (n <= 0) {
      notes.push_back("case " + marks.name + " has no samples");
      return;
    }
    // Which references this case's fusion needs.
    std::vector<std::size_t> used;
    for (std::size_t k = 0; k < needs.size(); ++k) {
      const Role r = needs[k].role;
      const bool use = r == Role::Output ||
                       (r == Role::Monitor && tc.kind != CaseKind::RotationTable) ||
                       (r == Role::LinearEncoder && tc.kind == CaseKind::Shaker) ||
                       (r == Role::TableEncoder && tc.kind == CaseKind::RotationTable);
      if (use) used.push_back(k);
    }
    std::size_t monitors = 0;
    bool table = false;
    for (std::size_t k : used) {
      monitors += needs[k].role == Role::Monitor ? 1 : 0;
      table = table || needs[k].role == Role::TableEncoder;
    }
    if (tc.kind == CaseKind::RotationTable && !table)
      throw InputError("case " + marks.name + " (rotation_table): the bench has no [table_encoder] to fuse it with");
    if (tc.kind != CaseKind::RotationTable && monitors < 3)
      throw InputError("case " + marks.name + " (" + to_string(tc.kind) +
                       "): fusion needs at least three [[monitor]] accelerometers, the bench has " +
                       std::to_string(monitors));

    std::map<std::size_t, Eigen::VectorXd> value;
    std::vector<std::uint8_t> usable(static_cast<std::size_t>(n), 1);
    for (std::size_t k : used) {
      std::vector<std::uint8_t> state;
      gather(k, i0, n, value[k], state);
      std::vector<std::uint8_t> invalid(state.size()), missing(state.size());
      for (std::size_t i = 0; i < state.size(); ++i) {
        invalid[i] = state[i] == 1;
        missing[i] = state[i] == 2;
        if (state[i] != 0) usable[i] = 0;
      }
      exclude_runs(marks.name, invalid, needs[k].ref.label() + " invalid");
      exclude_runs(marks.name, missing, needs[k].ref.label() + " missing (gap)");
    }

    // Phase label of every sample: the last phase started at or before it.
    std::vector<std::string> phase_names;
    std::vector<std::uint16_t> phase(static_cast<std::size_t>(n), 0);
    std::vector<std::int32_t> phase_index(static_cast<std::size_t>(n), -1);
    {
      std::vector<PhaseMark> ph = marks.phases;
      std::stable_sort(ph.begin(), ph.end(), [](const PhaseMark& a, const PhaseMark& c) { return a.start_ns < c.start_ns; });
      auto label_of = [&phase_names](const std::string& l) {
        const auto it = std::find(phase_names.begin(), phase_names.end(), l);
        if (it != phase_names.end()) return static_cast<std::uint16_t>(it - phase_names.begin());
        phase_names.push_back(l);
        return static_cast<std::uint16_t>(phase_names.size() - 1);
      };
      std::uint16_t current = 0;
      bool any = false;
      std::size_t next = 0;
      std::int32_t current_index = -1;
      for (std::int64_t i = 0; i < n; ++i) {
        while (next < ph.size() && index_of(ph[next].start_ns) <= i0 + i) {
          current = label_of(ph[next].label);
          current_index = ph[next].phase_index;
          any = true;
          ++next;
        }
        if (!any) {
          current = label_of("unplanned");
          any = true;
        }
        phase[static_cast<std::size_t>(i)] = current;
        phase_index[static_cast<std::size_t>(i)] = current_index;
      }
    }

    // Contiguous usable segments.
    std::vector<std::pair<std::int64_t, std::int64_t>> segments;   // [begin, end)
    const auto min_len = static_cast<std::int64_t>(std::ceil(options.min_segment_s / period_s));
    for (std::int64_t i = 0; i < n;) {
      if (!usable[static_cast<std::size_t>(i)]) {
        ++i;
        continue;
      }
      std::int64_t j = i;
      while (j < n && usable[static_cast<std::size_t>(j)]) ++j;
      if (j - i >= std::max<std::int64_t>(min_len, 3)) {
        segments.emplace_back(i, j);
      } else {
        exclusions.push_back({marks.name, fmt::format("valid stretch shorter than {} s", options.min_segment_s),
                              static_cast<double>(i) * period_s, j - i});
      }
      i = j;
    }

    const config::SensorUnderTest& sut = b.sensors[sensor];
    // Table attitude at each phase's first sample, tracked through the encoder (the phases turn
    // about different axes, so one angle does not give the attitude).
    std::map<std::int32_t, frames::Dcm> phase_attitude;
    std::map<std::int32_t, double> phase_base;
    std::int32_t attitude_lost_from = std::numeric_limits<std::int32_t>::max();
    std::size_t table_k = 0;
    if (tc.kind == CaseKind::RotationTable) {
      for (std::size_t k : used)
        if (needs[k].role == Role::TableEncoder) table_k = k;
      const Eigen::VectorXd& angle = value[table_k];
      frames::Dcm att = tc.start_attitude.dcm();
      Eigen::Vector3d prev_axis = Eigen::Vector3d::UnitZ();
      std::optional<double> prev_base;
      for (std::int32_t p = 0; p < static_cast<std::int32_t>(tc.phases.size()); ++p) {
        std::optional<double> base;
        for (std::int64_t i = 0; i < n; ++i) {
          if (phase_index[static_cast<std::size_t>(i)] == p) {
            if (usable[static_cast<std::size_t>(i)]) base = angle(i);
            break;   // only the phase's first sample fixes its start angle
          }
        }
        if (!base) {
          attitude_lost_from = std::min(attitude_lost_from, p + 1);
          continue;
        }
        if (prev_base) att = frames::frame_rotation(prev_axis, *base - *prev_base) * att;
        phase_attitude[p] = att;
        phase_base[p] = *base;
        const config::Phase& ph = tc.phases[static_cast<std::size_t>(p)];
        prev_axis = ph.kind == config::PhaseKind::Rotation ? ph.axis.normalized() : Eigen::Vector3d::UnitZ();
        prev_base = base;
      }
    }

    int seg_no = 0;
    for (const auto& [s0, s1] : segments) {
      const std::int64_t len = s1 - s0;
      FusedSegment out;
      out.case_index = marks.case_index;
      out.case_name = marks.name;
      out.kind = tc.kind;
      out.sample_period_s = period_s;
      out.t.resize(len);
      for (std::int64_t i = 0; i < len; ++i) out.t(i) = static_cast<double>(s0 + i) * period_s;
      out.y.resize(len);
      out.a_e.resize(len, 3);
      for (std::size_t k : used)
        if (needs[k].role == Role::Output) out.y = value[k].segment(s0, len);

      if (tc.kind == CaseKind::RotationTable) {
        Rows3 w(len, 3);
        const Eigen::VectorXd& angle = value[table_k];
        std::vector<std::uint8_t> lost(static_cast<std::size_t>(n), 0);
        // One piece per phase inside the segment: its axis, start attitude and start angle.
        for (std::int64_t i = 0; i < len;) {
          const std::int32_t p = phase_index[static_cast<std::size_t>(s0 + i)];
          std::int64_t j = i;
          while (j < len && phase_index[static_cast<std::size_t>(s0 + j)] == p) ++j;
          if (p < 0 || p >= attitude_lost_from || phase_attitude.count(p) == 0) {
            for (std::int64_t q = i; q < j; ++q) lost[static_cast<std::size_t>(s0 + q)] = 1;
            out.a_e.middleRows(i, j - i).setConstant(std::numeric_limits<double>::quiet_NaN());
            i = j;
            continue;
          }
          const config::Phase& ph = tc.phases[static_cast<std::size_t>(p)];
          const Eigen::Vector3d axis = ph.kind == config::PhaseKind::Rotation ? ph.axis : Eigen::Vector3d::UnitZ();
          const Eigen::Vector3d f0 = kStandardGravity * phase_attitude[p].col(2);
          // Differences across the piece's ends: take the neighbours in the segment so rate and
          // angular acceleration stay central at a phase boundary.
          const std::int64_t a = std::max<std::int64_t>(0, i - 1), z = std::min<std::int64_t>(len, j + 1);
          Eigen::VectorXd rel = angle.segment(s0 + a, z - a).array() - phase_base[p];
          Rows3 rate;
          const Rows3 f = table_specific_force(rel, axis, f0, sut.position_m, period_s, &rate);
          out.a_e.middleRows(i, j - i) = f.middleRows(i - a, j - i);
          w.middleRows(i, j - i) = rate.middleRows(i - a, j - i);
          i = j;
        }
        out.w_e = std::move(w);
        exclude_runs(marks.name, lost, "table attitude unknown (a phase without encoder data before it)");
      } else {
        // Monitors: calibrated (bias, scale, misalignment from the bench file), then WLS.
        MonitorLayout layout;
        Eigen::MatrixXd readings(len, static_cast<Eigen::Index>(monitors));
        Eigen::Index col = 0;
        for (std::size_t k : used) {
          if (needs[k].role != Role::Monitor) continue;
          const config::MonitorAccelerometer& m = b.monitors[needs[k].index];
          const double gain = 1.0 + m.scale_error;
          layout.axes.push_back(m.misalignment.dcm().transpose() * m.axis.normalized());
          layout.noise_sd_mps2.push_back(std::max(m.noise_sd_mps2, 1e-12) / gain);
          readings.col(col++) = (value[k].segment(s0, len).array() - m.bias_mps2) / gain;
        }
        out.a_e = fuse_monitors(readings, layout);
        if (tc.kind == CaseKind::Shaker) {
          for (std::size_t k : used) {
            if (needs[k].role != Role::LinearEncoder) continue;
            // The armature moves along the vibration axis x_E (config: the Fig. 2 fixture).
            const Eigen::VectorXd along = out.a_e.col(0);
            if (1.0 / period_s > 2.0 * options.crossover_hz)
              out.a_e.col(0) = complementary_vibration(along, value[k].segment(s0, len), period_s, options.crossover_hz);
          }
        }
        out.w_e = Rows3::Zero(len, 3);   // the shaker, static and thermal fixtures do not turn
      }
      if (!temps.empty()) {
        Eigen::VectorXd temp(len);
        std::size_t at = 0;
        for (std::int64_t i = 0; i < len; ++i) {
          const double t_ns = static_cast<double>(*origin_ns) + static_cast<double>(i0 + s0 + i) * period_ns;
          while (at + 1 < temps.size() && static_cast<double>(temps[at + 1].t_ns) <= t_ns) ++at;
          temp(i) = temps[at].value;
        }
        out.temp = std::move(temp);
      }
      out.phase_names = phase_names;
      out.phase.assign(phase.begin() + s0, phase.begin() + s1);
      // Drop rows the table could not fuse (NaN) by cutting the segment at them.
      std::vector<std::pair<std::int64_t, std::int64_t>> pieces;
      for (std::int64_t i = 0; i < len;) {
        if (!std::isfinite(out.a_e(i, 0))) {
          ++i;
          continue;
        }
        std::int64_t j = i;
        while (j < len && std::isfinite(out.a_e(j, 0))) ++j;
        pieces.emplace_back(i, j);
        i = j;
      }
      for (const auto& [p0, p1] : pieces) {
        if (p1 - p0 < std::max<std::int64_t>(min_len, 3)) {
          exclusions.push_back({marks.name, fmt::format("valid stretch shorter than {} s", options.min_segment_s),
                                out.t(p0), p1 - p0});
          continue;
        }
        FusedSegment piece;
        piece.case_index = out.case_index;
        piece.case_name = out.case_name;
        piece.kind = out.kind;
        piece.segment = seg_no++;
        piece.sample_period_s = period_s;
        piece.t = out.t.segment(p0, p1 - p0);
        piece.a_e = out.a_e.middleRows(p0, p1 - p0);
        if (out.w_e) piece.w_e = Rows3(out.w_e->middleRows(p0, p1 - p0));
        if (out.temp) piece.temp = Eigen::VectorXd(out.temp->segment(p0, p1 - p0));
        piece.y = out.y.segment(p0, p1 - p0);
        piece.phase_names = out.phase_names;
        piece.phase.assign(out.phase.begin() + p0, out.phase.begin() + p1);
        rows += p1 - p0;
        sink(std::move(piece));
      }
    }
  }
};

StreamAssembler::StreamAssembler(AssemblerOptions options, SegmentSink sink) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->sink = std::move(sink);
}

StreamAssembler::~StreamAssembler() = default;

void StreamAssembler::push(const bench_config_t& bench, const std::string& where) { impl_->on_bench(bench, where); }
void StreamAssembler::push(const sample_block_t& block, const std::string& where) { impl_->on_block(block, where); }
void StreamAssembler::push(const plan_event_t& event, const std::string& where) { impl_->on_event(event, where); }

void StreamAssembler::finish() {
  if (!impl_->bench) throw InputError("no INERTIA_BENCH message: the bench the data was recorded on is unknown");
  if (!impl_->saw_case_marker)
    throw InputError("no case markers (INERTIA_EVENT MARK_CASE_START): the samples cannot be cut into cases");
  impl_->fuse_ready(true);
}

bool StreamAssembler::has_bench() const noexcept { return impl_->bench.has_value(); }
const config::BenchConfig& StreamAssembler::bench() const {
  if (!impl_->bench) throw std::logic_error("StreamAssembler: no bench yet");
  return *impl_->bench;
}
std::size_t StreamAssembler::sensor_index() const { return impl_->sensor; }
const std::vector<Exclusion>& StreamAssembler::exclusions() const noexcept { return impl_->exclusions; }
const std::vector<StreamGap>& StreamAssembler::gaps() const noexcept { return impl_->gaps; }
std::int64_t StreamAssembler::skipped_blocks() const noexcept { return impl_->skipped; }
std::int64_t StreamAssembler::fused_rows() const noexcept { return impl_->rows; }
const std::vector<std::string>& StreamAssembler::notes() const noexcept { return impl_->notes; }

}  // namespace inertia::fusion
