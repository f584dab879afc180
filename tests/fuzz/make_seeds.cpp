// Writes the seed corpora of the LCM fuzz targets (tests/fuzz/corpus/{lcm_decode,
// stream_assembler,event_log}) from config/sim-paper-daq.toml: the messages inertia-daqd
// publishes on that bench (its INERTIA_BENCH, plan markers, and short sample blocks of the
// devices the fusion of acc1 reads), small enough to commit. Run from the fuzz build:
//   build-fuzz/tests/fuzz/fuzz_make_seeds SOURCE_DIR
// The seeds are committed; rerun this only when a message type or the bench changes.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/lcm/channels.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "inertia/bench_config_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"
#include "tests/fuzz/lcm_chunks.hpp"

using namespace inertia;
namespace fs = std::filesystem;

namespace {

constexpr std::int64_t kStartNs = 1'000'000'000;
constexpr double kPeriod = 1e-3;   // the bench's 1 kHz
constexpr int kSamplesPerBlock = 10;

template <class Message>
std::vector<std::uint8_t> encode(const Message& m) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(out.data(), 0, static_cast<int>(out.size()));
  return out;
}

struct Stream {
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> messages;   // channel, bytes
};

sample_block_t block(const std::string& device, const std::vector<std::string>& names, int index,
                     double (*value)(int channel, double t)) {
  sample_block_t b;
  shape_sample_block(b, static_cast<std::int32_t>(names.size()), kSamplesPerBlock);
  b.device = device;
  b.seq = index;
  b.t0_mono_ns = kStartNs + static_cast<std::int64_t>(index) * kSamplesPerBlock * 1'000'000;
  b.t0_utime = 1'700'000'000'000'000 + b.t0_mono_ns / 1000;
  b.sample_period_s = kPeriod;
  for (std::size_t c = 0; c < names.size(); ++c) {
    b.channel_ids[c] = static_cast<std::int32_t>(c);
    b.channel_names[c] = names[c];
    b.units[c] = "m/s^2";
    b.channel_seq[c] = static_cast<std::int64_t>(index) * kSamplesPerBlock;
    for (int s = 0; s < kSamplesPerBlock; ++s) {
      const double t = (index * kSamplesPerBlock + s) * kPeriod;
      b.values[c][static_cast<std::size_t>(s)] = value(static_cast<int>(c), t);
      set_sample_valid(b, static_cast<std::int32_t>(c), s, true);
    }
  }
  return b;
}

plan_event_t marker(std::int8_t mark, const std::string& case_name, const std::string& kind, const std::string& phase,
                    int phase_index, double start_s, double end_s) {
  plan_event_t e;
  e.mark = mark;
  e.case_name = case_name;
  e.kind = kind;
  e.phase = phase;
  e.phase_index = phase_index;
  e.start_mono_ns = kStartNs + static_cast<std::int64_t>(start_s * 1e9);
  e.end_mono_ns = kStartNs + static_cast<std::int64_t>(end_s * 1e9);
  e.mono_ns = mark == plan_event_t::MARK_CASE_END || mark == plan_event_t::MARK_PHASE_END ? e.end_mono_ns : e.start_mono_ns;
  e.utime = 1'700'000'000'000'000 + e.mono_ns / 1000;
  e.num_setpoints = 1;
  e.setpoint_names = {"frequency"};
  e.setpoint_values = {10.0};
  e.setpoint_units = {"Hz"};
  return e;
}

double accel(int channel, double t) { return channel == 0 ? 1e-3 + 0.0877 * std::sin(62.8 * t) : 9.80665 * std::sin(62.8 * t); }
double position(int, double t) { return 1e-4 * std::sin(62.8 * t); }
double angle(int, double t) { return 1.0 * t; }

// One case of `blocks` blocks per device, the devices interleaved as the daemon publishes them.
Stream case_stream(const std::string& case_name, const std::string& kind, int blocks, bool with_gap) {
  Stream s;
  const double end_s = blocks * kSamplesPerBlock * kPeriod;
  auto add_event = [&s](const plan_event_t& e) { s.messages.emplace_back(std::string(channels::kEvent), encode(e)); };
  add_event(marker(plan_event_t::MARK_CASE_START, case_name, kind, "", 0, 0.0, end_s));
  add_event(marker(plan_event_t::MARK_PHASE_START, case_name, kind, "dwell", 0, 0.0, end_s));
  for (int i = 0; i < blocks; ++i) {
    if (with_gap && i == blocks / 2) continue;   // a lost block of every device
    sample_block_t a = block("accel", {"acc1", "mon1", "mon2", "mon3", "mon4"}, i, accel);
    if (with_gap && i == 1) set_sample_valid(a, 2, 3, false);   // one invalid monitor sample
    s.messages.emplace_back(channels::raw_channel("accel"), encode(a));
    s.messages.emplace_back(channels::raw_channel("linear_encoder"), encode(block("linear_encoder", {"position"}, i, position)));
    s.messages.emplace_back(channels::raw_channel("table_encoder"), encode(block("table_encoder", {"position"}, i, angle)));
  }
  add_event(marker(plan_event_t::MARK_PHASE_END, case_name, kind, "dwell", 0, 0.0, end_s));
  add_event(marker(plan_event_t::MARK_CASE_END, case_name, kind, "", 0, 0.0, end_s - kPeriod));
  return s;
}

void write(const fs::path& file, const std::vector<std::uint8_t>& bytes) {
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  std::cout << file.string() << ": " << bytes.size() << " bytes\n";
}

void put_be(std::vector<std::uint8_t>& out, std::uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// The LCM event-log format (lcm/eventlog.c), as inertia-daqd's LogWriter writes it.
std::vector<std::uint8_t> event_log(const std::vector<std::pair<std::string, std::vector<std::uint8_t>>>& messages) {
  std::vector<std::uint8_t> out;
  std::int64_t n = 0;
  for (const auto& [channel, data] : messages) {
    put_be(out, 0xEDA1DA01, 4);
    put_be(out, static_cast<std::uint64_t>(n), 8);
    put_be(out, static_cast<std::uint64_t>(1'700'000'000'000'000 + 1000 * n), 8);
    put_be(out, channel.size(), 4);
    put_be(out, data.size(), 4);
    out.insert(out.end(), channel.begin(), channel.end());
    out.insert(out.end(), data.begin(), data.end());
    ++n;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: fuzz_make_seeds SOURCE_DIR\n";
    return 2;
  }
  const fs::path source = argv[1];
  const fs::path corpus = source / "tests/fuzz/corpus";
  const config::BenchConfig bench = config::load_bench_config(source / "config/sim-paper-daq.toml");
  bench_config_t bc;
  bc.utime = 1'700'000'000'000'000;
  bc.bench_name = bench.name;
  bc.num_files = static_cast<std::int32_t>(bench.sources.size());
  for (const config::SourceFile& f : bench.sources) {
    bc.paths.push_back(f.path.filename().string());
    bc.texts.push_back(f.text);
  }
  const std::vector<std::uint8_t> bench_bytes = encode(bc);

  const Stream shaker = case_stream("shaker-ia", "shaker", 8, false);
  const Stream table = case_stream("rotation-table", "rotation_table", 8, true);

  // lcm_decode: one message of each type (first byte: the type, fuzz::MessageKind).
  auto typed = [](fuzz::MessageKind kind, const std::vector<std::uint8_t>& bytes) {
    std::vector<std::uint8_t> out{static_cast<std::uint8_t>(kind)};
    out.insert(out.end(), bytes.begin(), bytes.end());
    return out;
  };
  write(corpus / "lcm_decode/bench", typed(fuzz::MessageKind::Bench, bench_bytes));
  write(corpus / "lcm_decode/event", typed(fuzz::MessageKind::Event, shaker.messages.front().second));
  write(corpus / "lcm_decode/block", typed(fuzz::MessageKind::Block, shaker.messages[2].second));

  // stream_assembler: message sequences after the bench (the target pushes the bench itself).
  for (const auto& [name, stream] : {std::pair{"shaker", &shaker}, std::pair{"table-with-gap", &table}}) {
    std::vector<std::uint8_t> out;
    for (const auto& [channel, data] : stream->messages) {
      const fuzz::MessageKind kind = channel == channels::kEvent ? fuzz::MessageKind::Event : fuzz::MessageKind::Block;
      fuzz::append_chunk(out, kind, data);
    }
    write(corpus / "stream_assembler" / name, out);
  }

  // event_log: a whole small log, and the same log torn inside its last record (no .lcmlog
  // suffix: .gitignore keeps logs out of the repository).
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> log{{std::string(channels::kBench), bench_bytes}};
  log.insert(log.end(), shaker.messages.begin(), shaker.messages.end());
  std::vector<std::uint8_t> bytes = event_log(log);
  write(corpus / "event_log/shaker-log", bytes);
  bytes.resize(bytes.size() - 100);
  write(corpus / "event_log/shaker-log-torn", bytes);
  return 0;
}
