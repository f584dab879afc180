#include "hal/socketcan/frame_map.hpp"

#include <linux/can.h>

#include <algorithm>
#include <cmath>

namespace inertia::hal::socketcan {
namespace {

constexpr std::size_t kMaxPayload = 64;  // CANFD_MAX_DLEN

std::uint64_t low_mask(unsigned bits) noexcept {
  return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
}

// Significance (bit position within the signal's raw value) of the LSB of the j-th byte of the
// span the signal covers; negative when part of that byte lies below the signal.
int byte_lsb_shift(const CanSignal& s, std::size_t j) noexcept {
  const int total = s.bit_offset + s.bit_length;  // bits from the span's start to the signal's end
  const int jj = static_cast<int>(j);
  return s.byte_order == ByteOrder::LittleEndian ? 8 * jj - s.bit_offset : total - 8 - 8 * jj;
}

}  // namespace

std::size_t bytes_needed(const CanSignal& s) noexcept {
  return s.byte_offset + (static_cast<std::size_t>(s.bit_offset) + s.bit_length + 7) / 8;
}

std::uint64_t extract_raw(std::span<const std::uint8_t> payload, const CanSignal& s) noexcept {
  const std::size_t n = (static_cast<std::size_t>(s.bit_offset) + s.bit_length + 7) / 8;  // <= 9
  std::uint64_t raw = 0;
  for (std::size_t j = 0; j < n; ++j) {
    const std::uint64_t b = payload[s.byte_offset + j];
    const int shift = byte_lsb_shift(s, j);
    if (shift >= 64) continue;
    raw |= shift >= 0 ? b << shift : b >> -shift;
  }
  return raw & low_mask(s.bit_length);
}

void insert_raw(std::span<std::uint8_t> payload, const CanSignal& s, std::uint64_t raw) noexcept {
  raw &= low_mask(s.bit_length);
  const std::size_t n = (static_cast<std::size_t>(s.bit_offset) + s.bit_length + 7) / 8;
  for (std::size_t j = 0; j < n; ++j) {
    const int shift = byte_lsb_shift(s, j);
    if (shift >= 64) continue;
    // Which bits of this byte belong to the signal: those whose significance is in [0, length).
    std::uint8_t mask = 0;
    std::uint8_t bits = 0;
    for (int k = 0; k < 8; ++k) {
      const int sig = shift + k;
      if (sig < 0 || sig >= s.bit_length) continue;
      mask |= static_cast<std::uint8_t>(1u << k);
      bits |= static_cast<std::uint8_t>(((raw >> sig) & 1u) << k);
    }
    std::uint8_t& byte = payload[s.byte_offset + j];
    byte = static_cast<std::uint8_t>((byte & ~mask) | bits);
  }
}

double to_value(std::uint64_t raw, const CanSignal& s) noexcept {
  double counts;
  if (s.is_signed) {
    const std::uint64_t sign = std::uint64_t{1} << (s.bit_length - 1);
    if (s.bit_length < 64 && (raw & sign)) raw |= ~low_mask(s.bit_length);
    counts = static_cast<double>(static_cast<std::int64_t>(raw));
  } else {
    counts = static_cast<double>(raw);
  }
  return s.scale * counts + s.offset;
}

std::uint32_t frame_key(std::uint32_t id, bool extended) noexcept {
  return extended ? ((id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (id & CAN_SFF_MASK);
}

bool CanFrameMap::is_valid(std::string* why) const {
  auto fail = [&](const CanSignal& s, const std::string& what) {
    if (why) *why = "signal '" + s.name + "': " + what;
    return false;
  };
  if (signals.empty()) {
    if (why) *why = "the frame map has no signals";
    return false;
  }
  for (std::size_t i = 0; i < signals.size(); ++i) {
    const CanSignal& s = signals[i];
    if (s.name.empty()) return fail(s, "empty name (signal #" + std::to_string(i) + ")");
    for (std::size_t k = 0; k < i; ++k)
      if (signals[k].name == s.name) return fail(s, "name used twice");
    if (s.bit_length < 1 || s.bit_length > 64)
      return fail(s, "bit_length " + std::to_string(s.bit_length) + " is outside 1..64");
    if (s.bit_offset > 7) return fail(s, "bit_offset " + std::to_string(s.bit_offset) + " is outside 0..7");
    if (bytes_needed(s) > kMaxPayload)
      return fail(s, "ends at byte " + std::to_string(bytes_needed(s)) + ", beyond the 64-byte CAN FD payload");
    if (s.extended ? s.id > CAN_EFF_MASK : s.id > CAN_SFF_MASK)
      return fail(s, "id " + std::to_string(s.id) + " does not fit a " +
                         (s.extended ? "29" : "11") + "-bit identifier");
    if (!std::isfinite(s.scale) || s.scale == 0.0 || !std::isfinite(s.offset))
      return fail(s, "scale must be finite and non-zero, offset finite");
    // Every raw value must give a finite value: an infinite one would be pushed as a valid
    // sample (found by tests/fuzz/fuzz_can_frame_map: 64 bits at scale 1e300).
    const double largest_counts = std::ldexp(1.0, s.is_signed ? s.bit_length - 1 : s.bit_length);
    if (!std::isfinite(std::abs(s.scale) * largest_counts + std::abs(s.offset)))
      return fail(s, "scale and offset take a " + std::to_string(s.bit_length) +
                         "-bit raw value beyond the range of a double");
    if (!(s.min < s.max) || std::isnan(s.min) || std::isnan(s.max)) return fail(s, "min must be below max");
    if (s.wraps && s.counter) return fail(s, "a frame counter is unwrapped as the frame's number; wraps is for counts");
    if (s.counter) {
      if (s.is_signed) return fail(s, "a frame counter is unsigned");
      for (std::size_t k = 0; k < i; ++k)
        if (signals[k].counter && signals[k].id == s.id && signals[k].extended == s.extended)
          return fail(s, "a second counter in frame " + std::to_string(s.id) + " (one per frame)");
    }
  }
  return true;
}

CompiledFrameMap::CompiledFrameMap(const CanFrameMap& map) {
  entries_.reserve(map.signals.size());
  for (std::size_t i = 0; i < map.signals.size(); ++i) {
    const CanSignal& s = map.signals[i];
    entries_.push_back(Entry{frame_key(s.id, s.extended), static_cast<std::uint32_t>(i), s});
  }
  std::stable_sort(entries_.begin(), entries_.end(),
                   [](const Entry& a, const Entry& b) { return a.key < b.key; });
}

std::span<const CompiledFrameMap::Entry> CompiledFrameMap::find(std::uint32_t key) const noexcept {
  const auto lo = std::lower_bound(entries_.begin(), entries_.end(), key,
                                   [](const Entry& e, std::uint32_t k) { return e.key < k; });
  auto hi = lo;
  while (hi != entries_.end() && hi->key == key) ++hi;
  return {lo, hi};
}

std::vector<std::uint32_t> CompiledFrameMap::keys() const {
  std::vector<std::uint32_t> out;
  for (const Entry& e : entries_)
    if (out.empty() || out.back() != e.key) out.push_back(e.key);
  return out;
}

}  // namespace inertia::hal::socketcan
