// Encode/decode round trips of every inertia LCM type, the sample block size rules, and the
// C++ half of the Java interop check (DecodeCheck.java decodes what JavaInterop writes).

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/unit/lcm/known_messages.hpp"

namespace inertia {
namespace {

template <class Msg>
std::vector<std::uint8_t> encode(const Msg& msg) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  const int n = msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  EXPECT_EQ(n, static_cast<int>(bytes.size()));
  return bytes;
}

template <class Msg>
void expect_round_trip(const Msg& original) {
  const std::vector<std::uint8_t> bytes = encode(original);
  Msg decoded;
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  test::expect_equal(decoded, original);
  EXPECT_EQ(encode(decoded), bytes) << "re-encoding the decoded message changed its bytes";
  // Decoding must refuse a cut message rather than invent the missing fields.
  Msg cut;
  EXPECT_LT(cut.decode(bytes.data(), 0, static_cast<int>(bytes.size()) - 1), 0);
}

TEST(LcmTypes, SampleBlockRoundTrips) { expect_round_trip(test::known_sample_block()); }
TEST(LcmTypes, DaqStatusRoundTrips) { expect_round_trip(test::known_daq_status()); }
TEST(LcmTypes, PlanEventRoundTrips) { expect_round_trip(test::known_plan_event()); }
TEST(LcmTypes, ModelEstimateRoundTrips) { expect_round_trip(test::known_model_estimate()); }
TEST(LcmTypes, StructureTableRoundTrips) { expect_round_trip(test::known_structure_table()); }
TEST(LcmTypes, AnalyzerStatusRoundTrips) { expect_round_trip(test::known_analyzer_status()); }

TEST(LcmTypes, DecodingAsTheWrongTypeFailsOnTheFingerprint) {
  const std::vector<std::uint8_t> bytes = encode(test::known_plan_event());
  model_estimate_t wrong;
  EXPECT_LT(wrong.decode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
}

TEST(LcmTypes, FingerprintsAreDistinct) {
  const std::vector<std::int64_t> hashes = {sample_block_t::getHash(), daq_status_t::getHash(),
                                            device_status_t::getHash(), plan_event_t::getHash(),
                                            model_estimate_t::getHash()};
  for (std::size_t i = 0; i < hashes.size(); ++i) {
    for (std::size_t j = i + 1; j < hashes.size(); ++j) EXPECT_NE(hashes[i], hashes[j]) << i << " vs " << j;
  }
}

TEST(LcmTypes, BlockLongerThanInt16LengthsRoundTrips) {
  // An int16_t length would make publish() fail at 100000 values. 40000 > INT16_MAX.
  sample_block_t block;
  shape_sample_block(block, 1, 40000);
  block.channel_names = {"y"};
  block.units = {"mA"};
  for (int s = 0; s < 40000; ++s) {
    block.values[0][static_cast<std::size_t>(s)] = s * 0.5;
    set_sample_valid(block, 0, s, s % 3 != 0);
  }
  const std::vector<std::uint8_t> bytes = encode(block);
  sample_block_t decoded;
  ASSERT_EQ(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  EXPECT_EQ(decoded.num_samples, 40000);
  EXPECT_EQ(decoded.values[0][39999], 39999 * 0.5);
  EXPECT_FALSE(sample_valid(decoded, 0, 39999));
  EXPECT_TRUE(sample_valid(decoded, 0, 39998));
}

TEST(SampleBlockLayout, ValidityBitsAreLsbFirstOneRowPerChannel) {
  const sample_block_t block = test::known_sample_block();
  ASSERT_EQ(block.valid_bytes, 2);
  EXPECT_EQ(block.valid[0], (std::vector<std::uint8_t>{0xFF, 0x03}));
  EXPECT_EQ(block.valid[1], (std::vector<std::uint8_t>{0xF7, 0x03}));   // sample 3 invalid
  EXPECT_EQ(block.valid[2], (std::vector<std::uint8_t>{0xFF, 0x01}));   // sample 9 invalid
  EXPECT_FALSE(sample_valid(block, 1, 3));
  EXPECT_TRUE(sample_valid(block, 1, 4));
}

TEST(SampleBlockLayout, ClearingAValidBitLeavesItsNeighbours) {
  sample_block_t block = test::known_sample_block();
  set_sample_valid(block, 0, 5, false);
  EXPECT_EQ(block.valid[0][0], 0xDF);
  set_sample_valid(block, 0, 5, true);
  EXPECT_EQ(block.valid[0][0], 0xFF);
}

// A realistic 16-channel device: the daemon sizes its blocks with max_samples_per_block.
sample_block_t sixteen_channel_header() {
  sample_block_t header;
  shape_sample_block(header, 16, 0);
  header.device = "ref_accel_1";
  for (int c = 0; c < 16; ++c) {
    header.channel_ids[static_cast<std::size_t>(c)] = c;
    header.channel_names[static_cast<std::size_t>(c)] = (c < 10 ? "ch0" : "ch") + std::to_string(c);
    header.units[static_cast<std::size_t>(c)] = "m/s^2";
  }
  return header;
}

TEST(SampleBlockLayout, SixteenChannelBlockFitsOneDatagram) {
  const std::string channel = "INERTIA_RAW_REF_ACCEL_1";
  const sample_block_t header = sixteen_channel_header();
  const std::int32_t max = max_samples_per_block(header, channel);
  // By hand: 24 (channel + NUL) + 564 (fingerprint and header) + 128 n + 16 ceil(n / 8) < 65499
  // holds up to n = 499 (65468 bytes); 500 needs 65596.
  EXPECT_EQ(max, 499);

  sample_block_t block = header;
  shape_sample_block(block, 16, max);
  EXPECT_LT(udp_payload_size(block, channel), kLcmShortMessageMaxSize);
  EXPECT_EQ(udp_payload_size(block, channel), 65468U);
  EXPECT_EQ(encode(block).size() + channel.size() + 1, udp_payload_size(block, channel));
  shape_sample_block(block, 16, max + 1);
  EXPECT_GE(udp_payload_size(block, channel), kLcmShortMessageMaxSize);
}

TEST(SampleBlockLayout, NothingFitsWithoutChannelsOrWithAHugeHeader) {
  sample_block_t none;
  shape_sample_block(none, 0, 0);
  EXPECT_EQ(max_samples_per_block(none, "X"), 0);
  sample_block_t huge = sixteen_channel_header();
  huge.device.assign(70000, 'd');
  EXPECT_EQ(max_samples_per_block(huge, "X"), 0);
}

// C++ half of the Java interop test (CTest lcm.java_decode_check runs DecodeCheck.java on
// these files). Writes via rename so a concurrent reader never sees half a file.
template <class Msg>
void write_encoded(const std::filesystem::path& dir, const Msg& msg) {
  const std::vector<std::uint8_t> bytes = encode(msg);
  const std::filesystem::path final_path = dir / (std::string(Msg::getTypeName()) + ".bin");
  const std::filesystem::path tmp_path = final_path.string() + ".tmp";
  {
    std::ofstream out(tmp_path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good()) << "cannot write " << tmp_path;
  }
  std::filesystem::rename(tmp_path, final_path);
}

TEST(JavaInterop, WritesEncodedMessagesForDecodeCheck) {
  const std::filesystem::path dir = std::filesystem::path(INERTIA_BINARY_DIR) / "tests" / "lcm_interop";
  std::filesystem::create_directories(dir);
  write_encoded(dir, test::known_sample_block());
  write_encoded(dir, test::known_daq_status());
  write_encoded(dir, test::known_plan_event());
  write_encoded(dir, test::known_model_estimate());
  write_encoded(dir, test::known_structure_table());
  write_encoded(dir, test::known_analyzer_status());
  EXPECT_TRUE(std::filesystem::exists(dir / "sample_block_t.bin"));
}

}  // namespace
}  // namespace inertia
