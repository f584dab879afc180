#include "analyzer/fusion/log_dataset.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <limits>
#include <map>
#include <optional>
#include <ostream>

#include "analyzer/fusion/log_segmenter.hpp"
#include "common/dataset/bench_dataset.hpp"
#include "common/input_error.hpp"
#include "common/lcm/channels.hpp"
#include "common/lcm/event_log_reader.hpp"
#include "common/lcm/message_decode.hpp"

namespace inertia::fusion {
namespace {

template <class Message>
Message decode(const LogRecord& r, const std::string& where, const char* type) {
  Message m;
  if (const std::string why = decode_outside(r.data.data(), r.data.size(), m); !why.empty())
    throw InputError(fmt::format("{}: {} does not decode as {}: {}", where, r.channel, type, why));
  return m;
}

// Walks the records of `file` in order, calling visit(record, where) until it returns false.
// Returns the reader, for its stop reason and count.
template <class Visit>
void walk_log(EventLogReader& log, const std::filesystem::path& file, Visit&& visit) {
  LogRecord record;
  while (log.next(record)) {
    const std::string where = fmt::format("{}: event {} at byte {}", file.string(), log.records_read() - 1, record.offset);
    if (!visit(record, where)) break;
  }
}

// A log without a single case start marker: the plan's cases and phases cut from the references'
// motion (log_segmenter.hpp), or nullopt when the log has markers (or no bench to segment by).
std::optional<Segmentation> segment_unmarked(const std::filesystem::path& file) {
  bool marked = false;
  std::optional<bench_config_t> bench_msg;
  {
    EventLogReader log(file);
    walk_log(log, file, [&](const LogRecord& r, const std::string& where) {
      if (r.channel == channels::kEvent) {
        marked = decode<plan_event_t>(r, where, "plan_event_t").mark == plan_event_t::MARK_CASE_START;
      } else if (r.channel == channels::kBench && !bench_msg) {
        bench_msg = decode<bench_config_t>(r, where, "bench_config_t");
      }
      return !marked;
    });
  }
  if (marked || !bench_msg) return std::nullopt;
  std::vector<config::SourceFile> sources;
  for (std::int32_t i = 0; i < bench_msg->num_files; ++i)
    sources.push_back({bench_msg->paths[static_cast<std::size_t>(i)], bench_msg->texts[static_cast<std::size_t>(i)]});
  const config::BenchConfig bench = config::load_bench_config_from_sources(sources);
  MotionClassifier motion(bench);
  double origin_ns = std::numeric_limits<double>::infinity();
  EventLogReader log(file);
  walk_log(log, file, [&](const LogRecord& r, const std::string& where) {
    if (r.channel.rfind(channels::kRawPrefix, 0) == 0) {
      const auto block = decode<sample_block_t>(r, where, "sample_block_t");
      origin_ns = std::min(origin_ns, static_cast<double>(block.t0_mono_ns));
      motion.push(block);
    }
    return true;
  });
  VibrationEdgeRefiner edges(motion, motion.runs());
  EventLogReader again(file);
  walk_log(again, file, [&](const LogRecord& r, const std::string& where) {
    if (r.channel.rfind(channels::kRawPrefix, 0) == 0) edges.push(decode<sample_block_t>(r, where, "sample_block_t"));
    return true;
  });
  Segmentation seg = segment_plan(bench, edges.runs(), origin_ns);
  seg.description.insert(
      seg.description.begin(),
      fmt::format("no plan markers in this log: cases and phases cut from the references' motion (rotation: table "
                  "encoder above {:.2f} deg/s{}; vibration: a monitor's detrended sd above {:.4f} m/s^2 per {:.4g} s "
                  "window); times from the first sample:",
                  kRotationRate * 180.0 / 3.14159265358979323846, motion.has_table_encoder() ? "" : " (no table encoder)",
                  motion.vibration_threshold(), motion.window_s()));
  return seg;
}

}  // namespace

void feed_log(const std::filesystem::path& file, StreamAssembler& assembler, std::ostream& messages) {
  std::optional<Segmentation> segmentation;
  try {
    segmentation = segment_unmarked(file);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", file.string(), e.what()));
  }
  if (segmentation)
    for (const std::string& line : segmentation->description) fmt::print(messages, "{}\n", line);
  bool markers_given = false;
  EventLogReader log(file);
  walk_log(log, file, [&](const LogRecord& r, const std::string& where) {
    if (r.channel == channels::kBench) {
      assembler.push(decode<bench_config_t>(r, where, "bench_config_t"), where);
      if (segmentation && !markers_given && assembler.has_bench()) {
        for (const plan_event_t& m : segmentation->markers) assembler.push(m, where + " (segmented)");
        markers_given = true;
      }
    } else if (r.channel == channels::kEvent) {
      assembler.push(decode<plan_event_t>(r, where, "plan_event_t"), where);
    } else if (r.channel.rfind(channels::kRawPrefix, 0) == 0) {
      assembler.push(decode<sample_block_t>(r, where, "sample_block_t"), where);
    }
    return true;
  });
  if (!log.stop_reason().empty())
    fmt::print(messages, "{}: {} (of {} bytes): read up to it\n", file.string(), log.stop_reason(), log.size());
  try {
    assembler.finish();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{} ({} events): {}", file.string(), log.records_read(), e.what()));
  }
}

dataset::CaseData to_case_data(FusedSegment&& segment, const config::TestCase& tc, const config::SensorUnderTest& sensor) {
  dataset::CaseData cd;
  cd.name = tc.name;
  cd.kind = tc.kind;
  cd.m_ec = config::nominal_m_ec(tc, sensor);   // nominal, as simulate writes it: the analysis estimates the misalignment
  cd.mounting = tc.mounting;
  cd.placement_sd_rad = tc.placement_error_rad;   // the fixture's stated accuracy
  cd.sample_period_s = segment.sample_period_s;
  cd.t = std::move(segment.t);
  cd.a_e = std::move(segment.a_e);
  if (segment.w_e) cd.w_e = std::move(*segment.w_e);
  if (segment.temp) cd.temp = std::move(*segment.temp);
  cd.y = std::move(segment.y);
  cd.phase_names = std::move(segment.phase_names);
  cd.phase = std::move(segment.phase);
  return cd;
}

dataset::Dataset log_dataset(const std::filesystem::path& file, const std::string& sensor, std::ostream& messages,
                             const AssemblerOptions& options) {
  std::vector<FusedSegment> segments;
  AssemblerOptions o = options;
  o.sensor = sensor;
  StreamAssembler assembler(o, [&segments](FusedSegment&& s) { segments.push_back(std::move(s)); });
  feed_log(file, assembler, messages);
  const config::BenchConfig& bench = assembler.bench();
  const config::SensorUnderTest& sut = bench.sensors[assembler.sensor_index()];
  dataset::Dataset ds = dataset::bench_sensor_dataset(bench, assembler.sensor_index());
  std::stable_sort(segments.begin(), segments.end(),
                   [](const FusedSegment& a, const FusedSegment& b) { return a.case_index < b.case_index; });
  std::map<std::size_t, int> pieces;
  for (const FusedSegment& s : segments) ++pieces[s.case_index];
  std::map<std::size_t, int> seen;
  for (FusedSegment& s : segments) {
    const config::TestCase& tc = bench.cases[s.case_index];
    const int k = seen[s.case_index]++;
    const std::size_t case_index = s.case_index;
    dataset::CaseData cd = to_case_data(std::move(s), tc, sut);
    cd.name = k == 0 ? tc.name : fmt::format("{}-seg{}", tc.name, k + 1);
    cd.file = cd.name + ".csv";
    if (pieces[case_index] > 1) cd.piece_of = tc.name;
    ds.cases.push_back(std::move(cd));
  }
  // A dataset is all temperature columns or none for a case: keep what each case has.

  fmt::print(messages, "log {}: bench {}, sensor {}, {} fused rows in {} dataset case(s)\n", file.string(), bench.name,
             sut.name, assembler.fused_rows(), ds.cases.size());
  if (assembler.skipped_blocks() > 0)
    fmt::print(messages, "  {} sample block(s) recorded before INERTIA_BENCH skipped\n", assembler.skipped_blocks());
  for (const StreamGap& g : assembler.gaps())
    fmt::print(messages, "  gap: {}\n", describe(g));
  std::map<std::pair<std::string, std::string>, std::pair<std::int64_t, double>> excluded;   // total, first t
  for (const Exclusion& x : assembler.exclusions()) {
    auto [it, fresh] = excluded.try_emplace({x.case_name, x.reason}, 0, x.t_s);
    it->second.first += x.samples;
  }
  for (const auto& [key, v] : excluded)
    fmt::print(messages, "  case {}: {} sample(s) excluded: {} (first at t = {:.4f} s)\n", key.first, v.first,
               key.second, v.second);
  for (const std::string& n : assembler.notes()) fmt::print(messages, "  note: {}\n", n);
  for (const config::TestCase& tc : bench.cases)
    if (pieces.count(static_cast<std::size_t>(&tc - bench.cases.data())) == 0)
      fmt::print(messages, "  case {}: no usable samples in this log\n", tc.name);
  if (ds.cases.empty()) throw InputError(file.string() + ": no case has a usable stretch of samples");
  return ds;
}

}  // namespace inertia::fusion
