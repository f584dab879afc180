#pragma once
// CAN signal map: where each named signal sits in which frame, and how its bits become SI.
// Plain structs so the bench config loader can fill them from TOML (common/config).
//
// Bit numbering (documented once, used by the decoder and the simulator's encoder):
//   byte_offset: first payload byte that holds the signal (0-based, data[byte_offset]).
//   bit_offset (0..7) and bit_length (1..64):
//   * LittleEndian (Intel): the payload from data[byte_offset] on is read as a little-endian
//     integer; the signal's least significant bit is bit `bit_offset` of data[byte_offset]
//     (bit 0 = the byte's LSB) and its higher bits continue into the following bytes.
//     DBC start bit (LSB) = 8 * byte_offset + bit_offset.
//   * BigEndian (Motorola): the payload from data[byte_offset] on is read as a big-endian bit
//     stream, MSB first; the signal's most significant bit is `bit_offset` bits below the MSB
//     of data[byte_offset] (bit_offset 0: it is bit 7 of that byte) and its lower bits continue
//     into the following bytes. DBC start bit (MSB, sawtooth numbering) = 8 * byte_offset +
//     7 - bit_offset. With bit_offset 0 and a whole number of bytes this is the plain
//     network-order integer.
//   value = scale * raw + offset, raw two's complement when is_signed.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace inertia::hal::socketcan {

enum class ByteOrder { LittleEndian, BigEndian };

struct CanSignal {
  std::string name;                 // channel name within the device
  std::uint32_t id = 0;             // 11-bit (standard) or 29-bit (extended) identifier
  bool extended = false;            // CAN_EFF_FLAG frames
  std::uint8_t byte_offset = 0;     // 0..63
  std::uint8_t bit_offset = 0;      // 0..7, see above
  std::uint8_t bit_length = 16;     // 1..64
  ByteOrder byte_order = ByteOrder::LittleEndian;
  bool is_signed = false;
  double scale = 1.0;               // SI units per count
  double offset = 0.0;              // SI
  // The raw value the sender puts on the bus for "no valid reading" (a sensor whose output is
  // NaN or out of range; e.g. 0x80000000 in a signed 32-bit signal). Such a sample is pushed
  // marked invalid with the value kNoReading. Unset: every raw value is a reading.
  std::optional<std::uint64_t> invalid_raw;
  // The frame's sample counter: every signal of this frame is that sample of the device's clock
  // (the decoder unwraps the counter when it rolls over at 2^bit_length). At most one per frame.
  // With it a lost frame leaves exactly its samples missing and the device is timed by its own
  // clock (daq/clock_fit.hpp) instead of by the order frames arrive in.
  bool counter = false;
  // An accumulating count (an encoder counter card's position) that rolls over at 2^bit_length:
  // the decoder unwraps it to 64 bits by the shortest step between consecutive frames, so a
  // 32-bit count of 1 urad per step goes on past its 340 turns. value = scale * unwrapped + offset.
  bool wraps = false;
  // Plausible readings, SI: a value outside [min, max] is pushed marked invalid (the value kept,
  // so the log shows what came) and counted as a range fault. Unset: +-infinity.
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
};

/// The value of a sample whose raw value was the signal's invalid_raw.
inline constexpr double kNoReading = std::numeric_limits<double>::quiet_NaN();

struct CanFrameMap {
  std::vector<CanSignal> signals;   // channel index = position in this vector
  /// False with a reason naming the signal ("signal 'ax': bit_length 0 is outside 1..64").
  bool is_valid(std::string* why) const;
};

/// Raw bits of one signal from a payload; the caller has checked that the payload is long
/// enough (bytes_needed). Real-time safe.
std::uint64_t extract_raw(std::span<const std::uint8_t> payload, const CanSignal& signal) noexcept;
/// scale * (raw, sign-extended when is_signed) + offset. Real-time safe.
double to_value(std::uint64_t raw, const CanSignal& signal) noexcept;
/// Whether `raw` (as extract_raw returns it) is the signal's "no valid reading". Real-time safe.
inline bool is_invalid_raw(std::uint64_t raw, const CanSignal& signal) noexcept {
  return signal.invalid_raw.has_value() && raw == *signal.invalid_raw;
}
/// Writes raw bits of one signal into a payload (the simulator's encoder; tests). Bits outside
/// the signal are kept. Real-time safe.
void insert_raw(std::span<std::uint8_t> payload, const CanSignal& signal, std::uint64_t raw) noexcept;
/// Payload bytes the signal needs (byte_offset + bytes spanned).
std::size_t bytes_needed(const CanSignal& signal) noexcept;

/// The map compiled for lookup: signals ordered by (id, extended) so that one frame finds its
/// signals by binary search with no allocation. Built in configure(); read in the sampling thread.
class CompiledFrameMap {
 public:
  explicit CompiledFrameMap(const CanFrameMap& map);
  struct Entry {
    std::uint32_t key;        // id | (extended ? CAN_EFF_FLAG : 0)
    std::uint32_t channel;    // index into CanFrameMap::signals
    CanSignal signal;
  };
  /// Entries for one frame key (empty when the id is not in the map). Real-time safe.
  [[nodiscard]] std::span<const Entry> find(std::uint32_t key) const noexcept;
  /// Distinct keys (for receive filters).
  [[nodiscard]] std::vector<std::uint32_t> keys() const;

 private:
  std::vector<Entry> entries_;
};

/// The key a frame with this id and format has in CompiledFrameMap.
std::uint32_t frame_key(std::uint32_t id, bool extended) noexcept;

}  // namespace inertia::hal::socketcan
