#pragma once
// Shape and size rules of inertia::sample_block_t that every producer and reader shares:
// the validity bitmap layout and the largest block that still fits one UDP datagram.
//
// These live in namespace inertia beside the generated types, not in inertia::lcm: a namespace
// inertia::lcm would hide LCM's own ::lcm (lcm::LCM) from all code inside namespace inertia.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "inertia/sample_block_t.hpp"

namespace inertia {

/// LCM 1.3.1 sends a message as one datagram only when channel name + NUL + encoded message is
/// below this (lcm_udpm.c: `payload_size < LCM_SHORT_MESSAGE_MAX_SIZE`); above it the message
/// is fragmented and one lost fragment loses all of it.
inline constexpr std::size_t kLcmShortMessageMaxSize = 65499;

/// Sets num_channels, num_samples and valid_bytes and sizes every array to match, values 0.0,
/// every sample invalid. Allocates: call at configure time and reuse the block.
void shape_sample_block(sample_block_t& block, std::int32_t num_channels, std::int32_t num_samples);

/// Bytes LCM sends for `block` on `channel`, counted as lcm_udpm.c compares them with
/// kLcmShortMessageMaxSize (channel + NUL + fingerprint + payload).
std::size_t udp_payload_size(const sample_block_t& block, std::string_view channel);

/// Largest num_samples for which a block with the header of `header` (device, channel count,
/// names, units; its sample arrays are ignored) still goes out as one datagram on `channel`.
/// Returns 0 when not even one sample fits or the block has no channels. Not real-time.
std::int32_t max_samples_per_block(const sample_block_t& header, std::string_view channel);

/// Bound on t0_mono_ns (ns), the block's end time and channel_seq: CLOCK_MONOTONIC and sample
/// counters since the daemon started stay far below it (2^62 ns is 146 years).
inline constexpr std::int64_t kMaxStreamCount = std::int64_t{1} << 62;

/// Why `block` cannot be read safely (empty when it can): a negative count, a valid_bytes that
/// does not match num_samples (the bitmap would be read out of bounds), a non-finite or
/// non-positive sample period, a t0_mono_ns, end time or channel_seq outside [0, 2^62).
/// Every reader of blocks from outside (LCM, logs) checks this first.
std::string block_shape_error(const sample_block_t& block);

/// Validity bit of sample `s` of channel `c`: bit (s % 8) of valid[c][s / 8], LSB first
/// (the layout documented in sample_block_t.lcm). Bounds are the caller's duty.
/// Thread: any. Real-time: yes.
[[nodiscard]] inline bool sample_valid(const sample_block_t& block, std::int32_t c, std::int32_t s) noexcept {
  return (block.valid[static_cast<std::size_t>(c)][static_cast<std::size_t>(s / 8)] >> (s % 8)) & 1U;
}

inline void set_sample_valid(sample_block_t& block, std::int32_t c, std::int32_t s, bool valid) noexcept {
  std::uint8_t& byte = block.valid[static_cast<std::size_t>(c)][static_cast<std::size_t>(s / 8)];
  const auto bit = static_cast<std::uint8_t>(1U << (s % 8));
  byte = valid ? static_cast<std::uint8_t>(byte | bit) : static_cast<std::uint8_t>(byte & ~bit);
}

}  // namespace inertia
