// StreamAssembler (stream_assembler.hpp): the daemon's messages in, fused rows out. The bench
// message configures it; the device buffers (device_buffers.hpp) keep each device's samples, the
// plan marks (plan_marks.hpp) the case and phase markers, and the segment builder
// (segment_builder.hpp) fuses the case being fused. This file walks the sensor output's samples
// (the rows) in order, each as soon as its case, its phase and its inputs are known, and hands
// each to the segment builder.
#include "analyzer/fusion/stream_assembler.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>

#include "analyzer/fusion/device_buffers.hpp"
#include "analyzer/fusion/plan_marks.hpp"
#include "analyzer/fusion/segment_builder.hpp"
#include "common/input_error.hpp"

namespace inertia::fusion {

struct StreamAssembler::Impl {
  Impl(AssemblerOptions options_in, FusionSink& sink)
      : options(std::move(options_in)), buffers(options.max_wait_s), builder(options, sink, buffers, notes) {}

  AssemblerOptions options;
  std::optional<config::BenchConfig> bench;
  std::vector<std::string> bench_texts;   // paths + texts of the first bench, to compare repeats
  std::size_t sensor = 0;
  std::vector<StreamGap> gaps;
  std::vector<std::string> notes;
  std::int64_t skipped = 0;
  DeviceBuffers buffers;
  PlanMarks marks;
  SegmentBuilder builder;

  // The row loop: the output block read before the cursor's (its values dropped), to find a gap
  // to the next one, and the time of the last output sample read.
  std::optional<StoredBlock> previous_output;
  double last_read_ns = -std::numeric_limits<double>::infinity();

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
    buffers.configure(b, s);
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
      buffers.clear();
      throw;
    }
    builder.use_bench(*bench, sensor);
    bench_texts = std::move(texts);
  }

  // ---------------------------------------------------------------------------------------------
  // Blocks and markers

  void on_block(const sample_block_t& block, const std::string& where) {
    if (!bench) {
      ++skipped;
      return;
    }
    if (!buffers.store(block, where, gaps)) return;
    advance();
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
    marks.add(ev, index, buffers.output_period_ns(), where, notes);
    advance();
  }

  // ---------------------------------------------------------------------------------------------
  // Rows

  /// Reads and fuses every output sample whose inputs are all known.
  void advance() {
    if (!bench) return;
    auto it = buffers.devices.find(buffers.output_device);
    if (it == buffers.devices.end()) return;
    DeviceState& od = it->second;
    while (buffers.cursor_block < od.blocks.size()) {
      const StoredBlock& b = od.blocks[buffers.cursor_block];
      if (buffers.cursor_sample == 0 && previous_output) {
        builder.note_output_gap(*previous_output, b);
        previous_output.reset();
      }
      if (buffers.cursor_sample >= b.n) {
        previous_output = StoredBlock{b.seq0, b.n, b.t0_ns, b.period_ns, {}, {}};
        ++buffers.cursor_block;
        buffers.cursor_sample = 0;
        continue;
      }
      if (!process_row(b, buffers.cursor_sample)) break;
      last_read_ns = b.time(buffers.cursor_sample);
      ++buffers.cursor_sample;
    }
    // A case whose end marker arrived and whose last row is read is over now, not at the next row.
    const CaseMarks* fused = builder.case_marks();
    if (fused != nullptr && fused->ended && last_read_ns + 0.5 * buffers.output_period_ns() >= fused->last_ns &&
        &marks.cases.front() == fused)
      close_case();
    buffers.release();
    builder.flush_chunk();
  }

  /// One output sample. False when it must wait for more messages.
  bool process_row(const StoredBlock& ob, std::int32_t s) {
    const double t = ob.time(s);
    const double half = 0.5 * ob.period_ns;
    bool ready = true;
    const CaseMarks* c = marks.case_of(t, half, buffers.given_up(t), ready);
    if (!ready) return false;
    // Cases wholly before this row are over.
    while (!marks.cases.empty() && &marks.cases.front() != c && marks.cases.front().ended &&
           marks.cases.front().last_ns + half < t)
      close_case();
    if (c == nullptr) return true;   // between cases
    if (!marks.phase_settled(*c, t, half, buffers.given_up(t))) return false;
    if (builder.case_marks() != c) builder.open_case(*c);
    return builder.add_row(ob, s, *c, t, half);
  }

  /// The front case is over: its fusion ends.
  void close_case() {
    if (builder.case_marks() == &marks.cases.front()) builder.end_case();
    marks.cases.erase(marks.cases.begin());
  }

  void finish() {
    buffers.finishing = true;
    advance();
    const CaseMarks* fused = builder.case_marks();
    if (fused != nullptr && !fused->ended) notes.push_back("case " + fused->name + " has no end marker: cut at the last sample recorded");
    builder.end_case();
    marks.cases.clear();
  }
};

StreamAssembler::StreamAssembler(AssemblerOptions options, FusionSink& sink)
    : impl_(std::make_unique<Impl>(std::move(options), sink)) {}

StreamAssembler::StreamAssembler(AssemblerOptions options, SegmentSink sink)
    : own_collector_(std::make_unique<SegmentCollector>(std::move(sink))),
      impl_(std::make_unique<Impl>(std::move(options), *own_collector_)) {}

StreamAssembler::~StreamAssembler() = default;

void StreamAssembler::push(const bench_config_t& bench, const std::string& where) { impl_->on_bench(bench, where); }
void StreamAssembler::push(const sample_block_t& block, const std::string& where) { impl_->on_block(block, where); }
void StreamAssembler::push(const plan_event_t& event, const std::string& where) { impl_->on_event(event, where); }

void StreamAssembler::finish() {
  if (!impl_->bench) throw InputError("no INERTIA_BENCH message: the bench the data was recorded on is unknown");
  if (!impl_->marks.saw_case_marker)
    throw InputError("no case markers (INERTIA_EVENT MARK_CASE_START): the samples cannot be cut into cases");
  impl_->finish();
}

bool StreamAssembler::has_bench() const noexcept { return impl_->bench.has_value(); }
const config::BenchConfig& StreamAssembler::bench() const {
  if (!impl_->bench) throw std::logic_error("StreamAssembler: no bench yet");
  return *impl_->bench;
}
std::size_t StreamAssembler::sensor_index() const { return impl_->sensor; }
const std::vector<Exclusion>& StreamAssembler::exclusions() const noexcept { return impl_->builder.exclusions(); }
const std::vector<StreamGap>& StreamAssembler::gaps() const noexcept { return impl_->gaps; }

std::string describe(const StreamGap& gap) {
  return fmt::format("{} missing {} sample(s) (channel_seq jump {}) before {}", gap.device, gap.missing_samples,
                     gap.missing_seq, gap.where);
}
std::int64_t StreamAssembler::skipped_blocks() const noexcept { return impl_->skipped; }
std::int64_t StreamAssembler::fused_rows() const noexcept { return impl_->builder.rows_kept(); }
std::int64_t StreamAssembler::rows_out() const noexcept { return impl_->builder.rows_out(); }
const std::vector<std::string>& StreamAssembler::notes() const noexcept { return impl_->notes; }

}  // namespace inertia::fusion
