// libFuzzer target: the CAN frame map (hal/socketcan/frame_map): signal layouts as a bench file
// may give them, and frames as a bus may carry them. A map that passes is_valid (as the bench
// loader requires) is compiled and every frame decoded the way CanDevice decodes it. Checked:
// no read outside the payload; raw values fit their bit length; insert_raw(extract_raw(p)) leaves
// p unchanged and extract_raw(insert_raw(r)) gives r back; a valid sample's value is finite.
#include <fuzzer/FuzzedDataProvider.h>
#include <linux/can.h>

#include <cmath>

#include "hal/socketcan/frame_map.hpp"

using namespace inertia::hal::socketcan;

namespace {

CanSignal signal_from(FuzzedDataProvider& in, int index) {
  CanSignal s;
  s.name = "s" + std::to_string(index);
  s.extended = in.ConsumeBool();
  s.id = in.ConsumeIntegral<std::uint32_t>() & (s.extended ? 0x3FFFFFFFu : 0xFFFu);   // one bit past the valid range
  s.byte_offset = in.ConsumeIntegralInRange<std::uint8_t>(0, 70);
  s.bit_offset = in.ConsumeIntegralInRange<std::uint8_t>(0, 9);
  s.bit_length = in.ConsumeIntegralInRange<std::uint8_t>(0, 70);
  s.byte_order = in.ConsumeBool() ? ByteOrder::BigEndian : ByteOrder::LittleEndian;
  s.is_signed = in.ConsumeBool();
  s.scale = in.ConsumeBool() ? in.ConsumeFloatingPoint<double>() : 1e-6;
  s.offset = in.ConsumeBool() ? in.ConsumeFloatingPoint<double>() : 0.0;
  if (in.ConsumeBool()) s.invalid_raw = in.ConsumeIntegral<std::uint64_t>();
  return s;
}

std::uint64_t low_mask(unsigned bits) { return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1; }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  CanFrameMap map;
  const int signals = in.ConsumeIntegralInRange<int>(1, 6);
  for (int i = 0; i < signals; ++i) map.signals.push_back(signal_from(in, i));
  std::string why;
  if (!map.is_valid(&why)) return 0;
  const CompiledFrameMap compiled(map);

  while (in.remaining_bytes() > 0) {
    // A frame: id with the EFF flag, a length (a classic frame's 0..8, or FD's up to 64), payload.
    const bool eff = in.ConsumeBool();
    const std::uint32_t id = in.ConsumeIntegral<std::uint32_t>() & (eff ? CAN_EFF_MASK : CAN_SFF_MASK);
    const std::size_t len = in.ConsumeIntegralInRange<std::size_t>(0, CANFD_MAX_DLEN);
    // Exactly `len` bytes on the heap, so that ASan sees any read past the frame's payload.
    std::vector<std::uint8_t> payload = in.ConsumeBytes<std::uint8_t>(len);
    payload.resize(len);
    payload.shrink_to_fit();
    for (const CompiledFrameMap::Entry& e : compiled.find(frame_key(id, eff))) {
      if (e.key != frame_key(id, eff) || e.channel >= map.signals.size()) __builtin_trap();
      if (bytes_needed(e.signal) > len) continue;   // CanDevice: a decode error, the sample marked invalid
      const std::uint64_t raw = extract_raw(payload, e.signal);
      if ((raw & ~low_mask(e.signal.bit_length)) != 0) __builtin_trap();
      std::vector<std::uint8_t> copy = payload;
      insert_raw(copy, e.signal, raw);
      if (copy != payload) __builtin_trap();
      const std::uint64_t other = ~raw & low_mask(e.signal.bit_length);
      insert_raw(copy, e.signal, other);
      if (extract_raw(copy, e.signal) != other) __builtin_trap();
      if (!is_invalid_raw(raw, e.signal) && !std::isfinite(to_value(raw, e.signal))) __builtin_trap();
    }
  }
  return 0;
}
