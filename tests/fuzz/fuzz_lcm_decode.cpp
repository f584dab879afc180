// libFuzzer target: decoding and validation of the messages the analyzer takes from outside
// (sample_block_t, plan_event_t, bench_config_t; common/lcm). Input: one byte naming the type
// (MessageKind), then the message's bytes. decode_outside must refuse or accept any bytes without
// throwing; an accepted message re-encodes to its size; a sample block that passes
// block_shape_error can have every value and validity bit read (sample_valid) in bounds.
#include <cmath>

#include "common/lcm/message_decode.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "tests/fuzz/lcm_chunks.hpp"

using namespace inertia;

namespace {
template <class Message>
void decode_and_check(const std::uint8_t* data, std::size_t size) {
  Message m;
  if (!decode_outside(data, size, m).empty()) return;
  if (static_cast<std::size_t>(m.getEncodedSize()) != size) __builtin_trap();
  if constexpr (std::is_same_v<Message, sample_block_t>) {
    if (!block_shape_error(m).empty()) return;
    // What every reader does with a block that passed the check.
    std::size_t valid = 0;
    for (std::int32_t c = 0; c < m.num_channels; ++c)
      for (std::int32_t s = 0; s < m.num_samples; ++s)
        valid += sample_valid(m, c, s) && std::isfinite(m.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)]);
    if (!(m.sample_period_s > 0.0) || valid > static_cast<std::size_t>(m.num_channels) * static_cast<std::size_t>(m.num_samples))
      __builtin_trap();
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  switch (static_cast<fuzz::MessageKind>(data[0] % fuzz::kMessageKinds)) {
    case fuzz::MessageKind::Block: decode_and_check<sample_block_t>(data + 1, size - 1); break;
    case fuzz::MessageKind::Event: decode_and_check<plan_event_t>(data + 1, size - 1); break;
    case fuzz::MessageKind::Bench: decode_and_check<bench_config_t>(data + 1, size - 1); break;
  }
  return 0;
}
