#include "analyzer/fusion/log_dataset.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <map>
#include <ostream>

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

}  // namespace

void feed_log(const std::filesystem::path& file, StreamAssembler& assembler, std::ostream& messages) {
  EventLogReader log(file);
  LogRecord record;
  while (log.next(record)) {
    const std::string where = fmt::format("{}: event {} at byte {}", file.string(), log.records_read() - 1, record.offset);
    if (record.channel == channels::kBench) {
      assembler.push(decode<bench_config_t>(record, where, "bench_config_t"), where);
    } else if (record.channel == channels::kEvent) {
      assembler.push(decode<plan_event_t>(record, where, "plan_event_t"), where);
    } else if (record.channel.rfind(channels::kRawPrefix, 0) == 0) {
      assembler.push(decode<sample_block_t>(record, where, "sample_block_t"), where);
    }
  }
  if (!log.stop_reason().empty())
    fmt::print(messages, "{}: {} (of {} bytes): read up to it\n", file.string(), log.stop_reason(), log.size());
  try {
    assembler.finish();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{} ({} events): {}", file.string(), log.records_read(), e.what()));
  }
}

dataset::CaseData to_case_data(FusedSegment&& segment, const config::TestCase& tc) {
  dataset::CaseData cd;
  cd.name = tc.name;
  cd.kind = tc.kind;
  cd.m_ec = tc.m_ec;   // nominal, as simulate writes it: the analysis estimates the misalignment
  cd.mounting = tc.mounting;
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

  dataset::Dataset ds;
  ds.sensor = sut.type == config::SensorType::Accelerometer ? dataset::SensorKind::Accelerometer
                                                            : dataset::SensorKind::Gyroscope;
  ds.output_unit = sut.output_unit;
  ds.t_ref = bench.t_ref_c;
  std::stable_sort(segments.begin(), segments.end(),
                   [](const FusedSegment& a, const FusedSegment& b) { return a.case_index < b.case_index; });
  std::map<std::size_t, int> pieces;
  for (const FusedSegment& s : segments) ++pieces[s.case_index];
  std::map<std::size_t, int> seen;
  for (FusedSegment& s : segments) {
    const config::TestCase& tc = bench.cases[s.case_index];
    const int k = seen[s.case_index]++;
    const std::size_t case_index = s.case_index;
    dataset::CaseData cd = to_case_data(std::move(s), tc);
    cd.name = k == 0 ? tc.name : fmt::format("{}-seg{}", tc.name, k + 1);
    cd.file = cd.name + ".csv";
    // Pieces of one case are one mounting of the sensor, whatever the plan says of the others.
    if (tc.mounting.empty() && pieces[case_index] > 1) cd.mounting = tc.name;
    ds.cases.push_back(std::move(cd));
  }
  // A dataset is all temperature columns or none for a case: keep what each case has.

  fmt::print(messages, "log {}: bench {}, sensor {}, {} fused rows in {} dataset case(s)\n", file.string(), bench.name,
             sut.name, assembler.fused_rows(), ds.cases.size());
  if (assembler.skipped_blocks() > 0)
    fmt::print(messages, "  {} sample block(s) recorded before INERTIA_BENCH skipped\n", assembler.skipped_blocks());
  for (const StreamGap& g : assembler.gaps())
    fmt::print(messages, "  gap: {} missing {} sample(s) (channel_seq jump {}) before {}\n", g.device,
               g.missing_samples, g.missing_seq, g.where);
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
