// decode_outside (common/lcm/message_decode.hpp): what comes from the multicast group or a log
// is walked before lcm-gen's decode() may allocate for it.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <vector>

#include "common/lcm/message_decode.hpp"
#include "common/lcm/sample_block_layout.hpp"

namespace inertia {
namespace {

template <class Message>
std::vector<std::uint8_t> encode(const Message& m) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(out.data(), 0, static_cast<int>(out.size()));
  return out;
}

sample_block_t two_channel_block() {
  sample_block_t b{};   // LCM types leave scalars uninitialized: t0_mono_ns was stack garbage
  shape_sample_block(b, 2, 9);
  b.device = "accel";
  b.sample_period_s = 1e-3;
  b.channel_names = {"acc1", "mon1"};
  b.units = {"mA", "m/s^2"};
  for (int s = 0; s < 9; ++s) set_sample_valid(b, 1, s, true);
  b.values[1][4] = 9.80665;
  return b;
}

void put_int32(std::vector<std::uint8_t>& bytes, std::size_t at, std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  for (int i = 0; i < 4; ++i) bytes[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(u >> (24 - 8 * i));
}

TEST(DecodeOutside, GivesBackWhatEncodeWrote) {
  const sample_block_t sent = two_channel_block();
  const std::vector<std::uint8_t> bytes = encode(sent);
  sample_block_t got;
  EXPECT_EQ(decode_outside(bytes.data(), bytes.size(), got), "");
  EXPECT_EQ(got.device, "accel");
  EXPECT_EQ(got.channel_names, sent.channel_names);
  EXPECT_EQ(got.values, sent.values);
  EXPECT_EQ(got.valid, sent.valid);

  plan_event_t e;
  e.case_name = "shaker-ia";
  e.num_setpoints = 2;
  e.setpoint_names = {"frequency", "amplitude"};
  e.setpoint_values = {10.0, 19.6};
  e.setpoint_units = {"Hz", "m/s^2"};
  const auto eb = encode(e);
  plan_event_t e2;
  EXPECT_EQ(decode_outside(eb.data(), eb.size(), e2), "");
  EXPECT_EQ(e2.setpoint_units, e.setpoint_units);

  bench_config_t c;
  c.bench_name = "b";
  c.num_files = 1;
  c.paths = {"bench.toml"};
  c.texts = {"[bench]\nname = \"b\"\n"};
  const auto cb = encode(c);
  bench_config_t c2;
  EXPECT_EQ(decode_outside(cb.data(), cb.size(), c2), "");
  EXPECT_EQ(c2.texts, c.texts);
}

// The input libFuzzer found in 90 s against lcm-gen's own sample_block_t::decode: a device-name
// length of -370615416 makes decode() throw std::length_error (the process terminates).
TEST(DecodeOutside, RefusesTheFuzzersNegativeStringLength) {
  const std::vector<std::uint8_t> crash = {0xe9, 0x61, 0xdb, 0x88, 0xfe, 0xa8, 0x39, 0x46, 0xe9,
                                           0x61, 0xdb, 0x88, 0xfe, 0xe9, 0x61, 0xdb, 0xfe};
  sample_block_t b;
  EXPECT_NE(decode_outside(crash.data(), crash.size(), b), "");
  // The same with the right fingerprint, so the walk, not the hash, refuses it.
  std::vector<std::uint8_t> bytes = encode(two_channel_block());
  put_int32(bytes, 8, -370615416);   // device's length
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), b).find("device is negative"), std::string::npos);
  put_int32(bytes, 8, 0);            // a string of length 0 has no NUL: decode() would assign size_t(-1) bytes
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), b).find("device has length 0"), std::string::npos);
}

// lcm-gen's decode() resizes values[num_channels][num_samples] before it looks at the bytes: this
// ~200-byte block would have zero-filled 2^31 - 1 doubles (16 GiB) per channel.
TEST(DecodeOutside, RefusesCountsTheMessageHasNoBytesFor) {
  std::vector<std::uint8_t> bytes = encode(two_channel_block());
  // num_samples sits after the fingerprint, device, four 8-byte fields, num_channels, the ids,
  // the names, the units and channel_seq.
  const std::size_t at = 8 + (4 + 6) + 32 + 4 + 2 * 4 + (4 + 5) + (4 + 5) + (4 + 3) + (4 + 6) + 2 * 8;
  ASSERT_EQ(bytes[at + 3], 9);   // num_samples = 9, big-endian
  put_int32(bytes, at, 0x7FFFFFFF);
  sample_block_t b;
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), b).find("values holds more elements"), std::string::npos);
  put_int32(bytes, 8 + 10 + 32, 0x7FFFFFFF);   // num_channels
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), b).find("channel_ids"), std::string::npos);
  put_int32(bytes, 8 + 10 + 32, -2);
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), b).find("num_channels is negative"), std::string::npos);
}

TEST(DecodeOutside, RefusesTruncatedTrailingAndForeignBytes) {
  const std::vector<std::uint8_t> bytes = encode(two_channel_block());
  sample_block_t b;
  for (std::size_t n = 0; n < bytes.size(); ++n) EXPECT_NE(decode_outside(bytes.data(), n, b), "") << n;
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_NE(decode_outside(longer.data(), longer.size(), b).find("after the message's last field"), std::string::npos);
  plan_event_t e;   // a sample block is not a plan event: the fingerprint differs
  EXPECT_NE(decode_outside(bytes.data(), bytes.size(), e), "");
}

// Malformed blocks, refused where every reader checks a decoded block (fuzz_lcm_decode reads
// every validity bit of every block that passes).
TEST(BlockShape, ValidBytesMustMatchNumSamples) {
  sample_block_t b = two_channel_block();
  EXPECT_EQ(block_shape_error(b), "");
  b.num_samples = 100;   // sample_valid(b, c, 99) would read valid[c][12] of a 2-byte row
  for (auto& v : b.values) v.resize(100);
  EXPECT_NE(block_shape_error(b).find("valid_bytes 2 for 100 samples"), std::string::npos) << block_shape_error(b);
  b = two_channel_block();
  b.valid[1].resize(1);   // valid_bytes right, one row short
  EXPECT_NE(block_shape_error(b), "");
}

TEST(BlockShape, NanInfiniteOrNonPositivePeriodIsRefused) {
  sample_block_t b = two_channel_block();
  for (double period : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), 0.0, -1e-3}) {
    b.sample_period_s = period;
    EXPECT_NE(block_shape_error(b).find("sample period"), std::string::npos) << period;
  }
}

// Clock and counters stay within [0, 2^62), so that readers' int64 arithmetic on them cannot
// overflow (see StreamAssembler.ReferenceWithAnAbsurdPeriodIsMissingNotRead).
TEST(BlockShape, TimesAndCountersOutsideTheStreamRangeAreRefused) {
  sample_block_t b = two_channel_block();
  b.t0_mono_ns = -1;
  EXPECT_NE(block_shape_error(b).find("t0_mono_ns"), std::string::npos);
  b.t0_mono_ns = kMaxStreamCount - 1;   // starts in range, ends past it
  EXPECT_NE(block_shape_error(b).find("ends past"), std::string::npos);
  b = two_channel_block();
  b.channel_seq[1] = std::numeric_limits<std::int64_t>::min();
  EXPECT_NE(block_shape_error(b).find("channel_seq"), std::string::npos);
  b.channel_seq[1] = kMaxStreamCount - 5;   // its last sample's counter past 2^62
  EXPECT_NE(block_shape_error(b).find("channel_seq"), std::string::npos);
  b.channel_seq[1] = 123456789;
  EXPECT_EQ(block_shape_error(b), "");
}

}  // namespace
}  // namespace inertia
