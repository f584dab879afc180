#pragma once
// Decoding of LCM messages that come from outside the process: any publisher on the multicast
// group, or the bytes of a log file.
//
// Why not T::decode alone: lcm-gen 1.3.1's C++ decoders size each array from the count in the
// message before they check that its bytes are there, and assign strings of length `len - 1`
// unchecked. A 60-byte sample_block_t that claims 2^31 - 1 samples makes decode() zero-fill
// 16 GiB; a string length of 0 or a negative count throws std::length_error out of decode()
// (found by tests/fuzz/fuzz_lcm_decode). decode_outside() walks the encoding first,
// with every count and length checked against the bytes left, and decodes only a message whose
// layout fits its size exactly; nothing is allocated for one that does not.
#include <cstddef>
#include <string>

#include "inertia/bench_config_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia {

/// Decodes `size` bytes at `data` into `message`. Returns empty on success, otherwise why the
/// bytes are not one such message (wrong type, truncated, a count or length that does not fit,
/// trailing bytes); `message` is then unspecified. Never throws for any bytes; allocates at
/// most what the message's own size justifies. Thread: any. Not real-time.
std::string decode_outside(const void* data, std::size_t size, sample_block_t& message);
std::string decode_outside(const void* data, std::size_t size, plan_event_t& message);
std::string decode_outside(const void* data, std::size_t size, bench_config_t& message);

}  // namespace inertia
