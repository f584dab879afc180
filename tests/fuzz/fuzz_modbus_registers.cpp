// libFuzzer target: Modbus register decoding (hal/modbus/register_map), for register specs that
// pass RegisterMap::is_valid (as the bench loader requires) and any words a controller may send.
// Checked: decode_reading gives a finite value or no reading (NaN and infinity never become
// samples); a finite value written with encode() reads back through decode() as exactly the value
// encode() said the device would hold.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>

#include "hal/modbus/register_map.hpp"

using namespace inertia::hal::modbus;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  RegisterSpec spec;
  spec.name = "r";
  spec.address = in.ConsumeIntegralInRange<int>(0, 0xFFFF);
  spec.kind = in.ConsumeBool() ? RegisterKind::Input : RegisterKind::Holding;
  spec.type = static_cast<DataType>(in.ConsumeIntegralInRange<int>(0, 4));
  spec.order = static_cast<WordOrder>(in.ConsumeIntegralInRange<int>(0, 3));
  spec.scale = in.ConsumeBool() ? in.ConsumeFloatingPoint<double>() : 0.01;
  spec.offset = in.ConsumeBool() ? in.ConsumeFloatingPoint<double>() : 0.0;
  RegisterMap map;
  map.registers.push_back(spec);
  std::string why;
  if (!map.is_valid(&why)) return 0;

  while (in.remaining_bytes() > 0) {
    const std::uint16_t words[2] = {in.ConsumeIntegral<std::uint16_t>(), in.ConsumeIntegral<std::uint16_t>()};
    const std::span<const std::uint16_t> span(words, static_cast<std::size_t>(word_count(spec.type)));
    if (const auto reading = decode_reading(spec, span); reading && !std::isfinite(*reading)) __builtin_trap();

    const double value = in.ConsumeFloatingPoint<double>();
    if (!std::isfinite(value)) continue;   // ModbusController::write refuses these (NotFinite)
    std::uint16_t written[2] = {0, 0};
    const double held = encode(spec, value, written);
    const double back = decode(spec, std::span<const std::uint16_t>(written, span.size()));
    if (!(back == held) && !(std::isnan(back) && std::isnan(held))) __builtin_trap();
  }
  return 0;
}
