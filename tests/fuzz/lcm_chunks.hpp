#pragma once
// A sequence of LCM messages in one fuzz input: chunks of [kind: 1 byte][length: 2 bytes,
// big-endian][the encoded message]. A last chunk cut short keeps the bytes that are there.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace inertia::fuzz {

enum class MessageKind : std::uint8_t { Block = 0, Event = 1, Bench = 2 };
inline constexpr int kMessageKinds = 3;

struct Chunk {
  MessageKind kind;
  std::span<const std::uint8_t> bytes;
};

inline std::vector<Chunk> split_chunks(const std::uint8_t* data, std::size_t size) {
  std::vector<Chunk> chunks;
  std::size_t at = 0;
  while (at + 3 <= size) {
    const auto kind = static_cast<MessageKind>(data[at] % kMessageKinds);
    const std::size_t length = (std::size_t{data[at + 1]} << 8) | data[at + 2];
    at += 3;
    const std::size_t n = length < size - at ? length : size - at;
    chunks.push_back({kind, {data + at, n}});
    at += n;
  }
  return chunks;
}

inline void append_chunk(std::vector<std::uint8_t>& out, MessageKind kind, const std::vector<std::uint8_t>& bytes) {
  out.push_back(static_cast<std::uint8_t>(kind));
  out.push_back(static_cast<std::uint8_t>(bytes.size() >> 8));
  out.push_back(static_cast<std::uint8_t>(bytes.size() & 0xFF));
  out.insert(out.end(), bytes.begin(), bytes.end());
}

}  // namespace inertia::fuzz
