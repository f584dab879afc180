// Publisher: rings in, sample_block_t out, over LCM's in-process memq:// provider (deterministic).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <lcm/lcm-cpp.hpp>
#include <thread>

#include "common/lcm/sample_block_layout.hpp"
#include "daq/publisher.hpp"

namespace inertia::daq {
namespace {

struct Collector {
  std::vector<sample_block_t> blocks;
  std::vector<daq_status_t> status;
  void on_block(const lcm::ReceiveBuffer*, const std::string&, const sample_block_t* b) { blocks.push_back(*b); }
  void on_status(const lcm::ReceiveBuffer*, const std::string&, const daq_status_t* s) { status.push_back(*s); }
};

std::shared_ptr<DeviceSlot> make_slot(std::size_t channels, double rate) {
  std::vector<ChannelInfo> info;
  for (std::size_t c = 0; c < channels; ++c) info.push_back({"ch" + std::to_string(c), "m/s^2", static_cast<std::int32_t>(c + 1)});
  return std::make_shared<DeviceSlot>("dev-1", std::move(info), rate, 4096);
}

void pump(lcm::LCM& lcm) {
  while (lcm.handleTimeout(10) > 0) {
  }
}

TEST(Publisher, ChannelNameIsUpperCaseWithUnderscores) {
  EXPECT_EQ(raw_channel("acc-a"), "INERTIA_RAW_ACC_A");
  EXPECT_EQ(raw_channel("linear_encoder"), "INERTIA_RAW_LINEAR_ENCODER");
}

TEST(Publisher, PacksInterleavedChannelsIntoContinuousBlocksAndFlushesTheRest) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Collector got;
  lcm.subscribe("INERTIA_RAW_DEV_1", &Collector::on_block, &got);
  lcm.subscribe("INERTIA_STATUS", &Collector::on_status, &got);
  auto slot = make_slot(3, 1000.0);
  slot->sim_time_base = true;
  PublisherOptions options;
  options.block_s = 0.01;  // 10 samples at 1 kHz
  options.sim_t0_ns = 1'000'000'000;
  Publisher pub(lcm, nullptr, {slot}, options);
  std::string why;
  ASSERT_TRUE(pub.configure(&why)) << why;
  EXPECT_EQ(pub.block_samples(0), 10);
  // 35 rows; sample 7 of channel 1 invalid.
  for (int k = 0; k < 35; ++k)
    for (std::uint32_t c = 0; c < 3; ++c)
      ASSERT_TRUE(slot->ring.try_push(RingSample{k * 1'000'000, 100.0 * c + k, c, (c == 1 && k == 7) ? 0u : 1u}));
  pub.start();
  pub.stop();  // drains, sends 3 full blocks and a last one of 5 samples
  pump(lcm);
  ASSERT_EQ(got.blocks.size(), 4u);
  std::int64_t expected_seq = 0;
  for (std::size_t i = 0; i < got.blocks.size(); ++i) {
    const auto& b = got.blocks[i];
    EXPECT_EQ(b.seq, static_cast<std::int64_t>(i));
    EXPECT_EQ(b.num_samples, i < 3 ? 10 : 5);
    EXPECT_EQ(b.num_channels, 3);
    EXPECT_EQ(b.channel_names[2], "ch2");
    EXPECT_EQ(b.channel_ids[2], 3);
    EXPECT_DOUBLE_EQ(b.sample_period_s, 1e-3);
    EXPECT_EQ(b.t0_mono_ns, 1'000'000'000 + expected_seq * 1'000'000) << "simulated time base";
    for (std::int32_t c = 0; c < 3; ++c) {
      EXPECT_EQ(b.channel_seq[static_cast<std::size_t>(c)], expected_seq);
      for (std::int32_t s = 0; s < b.num_samples; ++s) {
        EXPECT_DOUBLE_EQ(b.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)], 100.0 * c + expected_seq + s);
        EXPECT_EQ(sample_valid(b, c, s), !(c == 1 && expected_seq + s == 7));
      }
    }
    expected_seq += b.num_samples;
  }
  ASSERT_FALSE(got.status.empty()) << "a final status at stop";
  EXPECT_EQ(got.status.back().devices.at(0).blocks, 4);
  EXPECT_EQ(got.status.back().devices.at(0).ring_drops, 0);
  EXPECT_EQ(got.status.back().devices.at(0).ring_high_water, 105);
}

TEST(Publisher, AChannelRunningAheadBeyondTheBufferIsCountedAsMisaligned) {
  lcm::LCM lcm("memq://");
  Collector got;
  lcm.subscribe("INERTIA_STATUS", &Collector::on_status, &got);
  auto slot = make_slot(2, 1000.0);
  PublisherOptions options;
  options.block_s = 0.01;
  Publisher pub(lcm, nullptr, {slot}, options);
  std::string why;
  ASSERT_TRUE(pub.configure(&why));
  // Channel 0 only: 4 blocks of slack (40 samples) fit, the other 10 do not.
  for (int k = 0; k < 50; ++k) ASSERT_TRUE(slot->ring.try_push(RingSample{k, 1.0, 0, 1}));
  pub.start();
  pub.stop();
  pump(lcm);
  ASSERT_FALSE(got.status.empty());
  const auto& d = got.status.back().devices.at(0);
  EXPECT_EQ(d.ring_drops, 10 + 40) << "10 beyond the buffer, 40 left unequal at stop: counted, not hidden";
  EXPECT_NE(std::find(d.faults.begin(), d.faults.end(), "misaligned"), d.faults.end());
}

TEST(Publisher, BlockLengthIsCappedToOneDatagram) {
  lcm::LCM lcm("memq://");
  auto slot = make_slot(16, 10000.0);
  PublisherOptions options;
  options.block_s = 1.0;  // 10000 samples x 16 channels would be 1.3 MB
  Publisher pub(lcm, nullptr, {slot}, options);
  std::string why;
  ASSERT_TRUE(pub.configure(&why));
  EXPECT_GT(pub.block_samples(0), 400);
  EXPECT_LT(pub.block_samples(0), 512);
}

TEST(Publisher, ADeviceWithoutSamplesForItsTimeoutIsSilentUntilTheNextOne) {
  lcm::LCM lcm("memq://");
  Collector got;
  lcm.subscribe("INERTIA_STATUS", &Collector::on_status, &got);
  auto slot = make_slot(1, 1000.0);
  slot->silent_timeout_ns = 150'000'000;
  slot->samples.store(5);
  PublisherOptions options;
  options.block_s = 0.01;
  options.status_period_s = 0.02;
  Publisher pub(lcm, nullptr, {slot}, options);
  std::string why;
  ASSERT_TRUE(pub.configure(&why));
  pub.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(400));   // silent from 150 ms on
  slot->samples.store(10);                                       // it speaks again
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  pub.stop();
  pump(lcm);
  const auto silent = [](const daq_status_t& s) {
    const auto& f = s.devices.at(0).faults;
    return std::find(f.begin(), f.end(), "silent") != f.end();
  };
  const auto first = std::find_if(got.status.begin(), got.status.end(), silent);
  ASSERT_NE(first, got.status.end()) << "no status said silent in 400 ms without a sample";
  EXPECT_FALSE(silent(got.status.front())) << "not silent before its timeout";
  EXPECT_FALSE(silent(got.status.back())) << "a sample clears it";
}

}  // namespace
}  // namespace inertia::daq
