// libFuzzer target: the stream assembler (analyzer/fusion) pushed a sequence of messages, as
// `online` and `characterize --log` push what arrives. The bench of config/sim-paper-daq.toml is
// pushed first, as its INERTIA_BENCH; the input is chunks (lcm_chunks.hpp) of sample blocks,
// plan markers and further benches, each decoded with decode_outside (undecodable chunks are
// skipped, as the readers skip them). InputError is the assembler's normal refusal of a message;
// any other exception, a crash or a sanitizer report is a bug.
#include <sstream>

#include "analyzer/fusion/stream_assembler.hpp"
#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "common/lcm/message_decode.hpp"
#include "tests/fuzz/lcm_chunks.hpp"

using namespace inertia;

namespace {

class CountingSink final : public fusion::FusionSink {
 public:
  void on_rows(fusion::FusedChunk&& chunk) override {
    const Eigen::Index n = chunk.rows();
    if (chunk.t.size() != n || chunk.a_e.rows() != n || chunk.w_e.rows() != n) __builtin_trap();
    rows += n;
  }
  void on_segment_end(const fusion::SegmentEnd&) override {}
  std::int64_t rows = 0;
};

const bench_config_t& bench_message() {
  static const bench_config_t message = [] {
    const config::BenchConfig bench = config::load_bench_config(INERTIA_SOURCE_DIR "/config/sim-paper-daq.toml");
    bench_config_t m;
    m.bench_name = bench.name;
    m.num_files = static_cast<std::int32_t>(bench.sources.size());
    for (const config::SourceFile& f : bench.sources) {
      m.paths.push_back(f.path.filename().string());
      m.texts.push_back(f.text);
    }
    return m;
  }();
  return message;
}

template <class Message>
void push(fusion::StreamAssembler& assembler, std::span<const std::uint8_t> bytes, const std::string& where) {
  Message m;
  if (!decode_outside(bytes.data(), bytes.size(), m).empty()) return;
  try {
    assembler.push(m, where);
  } catch (const InputError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  CountingSink sink;
  fusion::AssemblerOptions options;
  // Short segments count, so that short inputs reach the fusion's end-of-segment paths; the
  // live bound on waiting, so that the give-up paths are reached too.
  options.min_segment_s = 0.005;
  options.max_wait_s = 0.5;
  fusion::StreamAssembler assembler(options, sink);
  assembler.push(bench_message(), "bench");
  int index = 0;
  for (const fuzz::Chunk& chunk : fuzz::split_chunks(data, size)) {
    const std::string where = "chunk " + std::to_string(index++);
    switch (chunk.kind) {
      case fuzz::MessageKind::Block: push<sample_block_t>(assembler, chunk.bytes, where); break;
      case fuzz::MessageKind::Event: push<plan_event_t>(assembler, chunk.bytes, where); break;
      case fuzz::MessageKind::Bench: push<bench_config_t>(assembler, chunk.bytes, where); break;
    }
  }
  try {
    assembler.finish();
  } catch (const InputError&) {
  }
  if (sink.rows < assembler.fused_rows()) __builtin_trap();
  return 0;
}
