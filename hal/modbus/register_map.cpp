#include "hal/modbus/register_map.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace inertia::hal::modbus {
namespace {

// Bytes A..D (A most significant) <-> two registers in the given order.
std::uint32_t join(WordOrder order, std::uint16_t w0, std::uint16_t w1) noexcept {
  auto swap = [](std::uint16_t w) { return static_cast<std::uint16_t>((w << 8) | (w >> 8)); };
  switch (order) {
    case WordOrder::ABCD: return (std::uint32_t{w0} << 16) | w1;
    case WordOrder::CDAB: return (std::uint32_t{w1} << 16) | w0;
    case WordOrder::BADC: return (std::uint32_t{swap(w0)} << 16) | swap(w1);
    case WordOrder::DCBA: return (std::uint32_t{swap(w1)} << 16) | swap(w0);
  }
  return 0;
}

void split(WordOrder order, std::uint32_t v, std::span<std::uint16_t> w) noexcept {
  auto swap = [](std::uint16_t x) { return static_cast<std::uint16_t>((x << 8) | (x >> 8)); };
  const auto hi = static_cast<std::uint16_t>(v >> 16);
  const auto lo = static_cast<std::uint16_t>(v & 0xFFFF);
  switch (order) {
    case WordOrder::ABCD: w[0] = hi; w[1] = lo; break;
    case WordOrder::CDAB: w[0] = lo; w[1] = hi; break;
    case WordOrder::BADC: w[0] = swap(hi); w[1] = swap(lo); break;
    case WordOrder::DCBA: w[0] = swap(lo); w[1] = swap(hi); break;
  }
}

template <class T>
double saturate_round(double x) noexcept {
  const double lo = static_cast<double>(std::numeric_limits<T>::min());
  const double hi = static_cast<double>(std::numeric_limits<T>::max());
  if (std::isnan(x)) return 0.0;
  return std::clamp(std::round(x), lo, hi);
}

}  // namespace

int word_count(DataType type) noexcept {
  return type == DataType::UInt16 || type == DataType::Int16 ? 1 : 2;
}

double decode(const RegisterSpec& s, std::span<const std::uint16_t> w) noexcept {
  double raw = 0.0;
  switch (s.type) {
    case DataType::UInt16: raw = w[0]; break;
    case DataType::Int16: raw = static_cast<std::int16_t>(w[0]); break;
    case DataType::UInt32: raw = join(s.order, w[0], w[1]); break;
    case DataType::Int32: raw = static_cast<std::int32_t>(join(s.order, w[0], w[1])); break;
    case DataType::Float32: raw = std::bit_cast<float>(join(s.order, w[0], w[1])); break;
  }
  return s.scale * raw + s.offset;
}

std::optional<double> decode_reading(const RegisterSpec& s, std::span<const std::uint16_t> w) noexcept {
  const double value = decode(s, w);
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

double encode(const RegisterSpec& s, double value, std::span<std::uint16_t> w) noexcept {
  const double x = (value - s.offset) / s.scale;
  double raw = 0.0;
  switch (s.type) {
    case DataType::UInt16:
      raw = saturate_round<std::uint16_t>(x);
      w[0] = static_cast<std::uint16_t>(raw);
      break;
    case DataType::Int16:
      raw = saturate_round<std::int16_t>(x);
      w[0] = static_cast<std::uint16_t>(static_cast<std::int16_t>(raw));
      break;
    case DataType::UInt32:
      raw = saturate_round<std::uint32_t>(x);
      split(s.order, static_cast<std::uint32_t>(raw), w);
      break;
    case DataType::Int32:
      raw = saturate_round<std::int32_t>(x);
      split(s.order, static_cast<std::uint32_t>(static_cast<std::int32_t>(raw)), w);
      break;
    case DataType::Float32: {
      const float f = static_cast<float>(x);
      raw = f;
      split(s.order, std::bit_cast<std::uint32_t>(f), w);
      break;
    }
  }
  return s.scale * raw + s.offset;
}

bool RegisterMap::is_valid(std::string* why) const {
  for (std::size_t i = 0; i < registers.size(); ++i) {
    const RegisterSpec& r = registers[i];
    auto fail = [&](const std::string& what) {
      if (why) *why = "register '" + r.name + "': " + what;
      return false;
    };
    if (r.name.empty()) return fail("empty name (register #" + std::to_string(i) + ")");
    if (find(r.name) != static_cast<int>(i)) return fail("name used twice");
    if (r.address < 0 || r.address + word_count(r.type) - 1 > 0xFFFF)
      return fail("address " + std::to_string(r.address) + " is outside 0..65535");
    if (!std::isfinite(r.scale) || r.scale == 0.0 || !std::isfinite(r.offset))
      return fail("scale must be finite and non-zero, offset finite");
    if (r.writable && r.kind == RegisterKind::Input) return fail("writable, but input registers are read-only");
    if (r.writable && !(r.min <= r.max)) return fail("min must not exceed max");
    if (!(r.max_rate > 0.0)) return fail("max_rate must be positive");
  }
  return true;
}

int RegisterMap::find(std::string_view name) const noexcept {
  for (std::size_t i = 0; i < registers.size(); ++i)
    if (registers[i].name == name) return static_cast<int>(i);
  return -1;
}

}  // namespace inertia::hal::modbus
