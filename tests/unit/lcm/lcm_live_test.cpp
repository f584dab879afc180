// Publish and receive over real UDP multicast (lcm udpm), C++ to C++, on a private port so
// parallel tests do not hear each other. Needs a multicast route; without one LCM refuses to
// start and the test is skipped with the fix (the CI script adds the route).

#include <gtest/gtest.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <string>
#include <vector>

#include "tests/unit/lcm/known_messages.hpp"
#include "tests/support/skip_or_fail.hpp"

namespace inertia {
namespace {

class Receiver {
 public:
  void on_block(const lcm::ReceiveBuffer*, const std::string& channel, const sample_block_t* msg) {
    channels.push_back(channel);
    blocks.push_back(*msg);
  }
  void on_status(const lcm::ReceiveBuffer*, const std::string&, const daq_status_t* msg) { statuses.push_back(*msg); }
  std::vector<std::string> channels;
  std::vector<sample_block_t> blocks;
  std::vector<daq_status_t> statuses;
};

std::string private_url() {
  // One port per process: ctest -j runs several test processes at once.
  const int port = 20000 + static_cast<int>(::getpid() % 20000);
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

TEST(LcmLive, SampleBlocksAndStatusArriveDecodedOverUdpMulticast) {
  lcm::LCM lcm(private_url());
  if (!lcm.good()) {
    INERTIA_SKIP_OR_FAIL_IN_CI("LCM could not open " + private_url() +
                               " (no multicast route?). Fix: ip link set lo multicast on; "
                               "ip route add 224.0.0.0/4 dev lo");
  }
  Receiver receiver;
  lcm::Subscription* raw = lcm.subscribe("INERTIA_RAW_.*", &Receiver::on_block, &receiver);
  raw->setQueueCapacity(100);
  lcm.subscribe("INERTIA_STATUS", &Receiver::on_status, &receiver);

  constexpr int kBlocks = 20;
  sample_block_t block = test::known_sample_block();
  for (int i = 0; i < kBlocks; ++i) {
    block.seq = 100 + i;
    ASSERT_EQ(lcm.publish("INERTIA_RAW_SIM_REF_1", &block), 0);
  }
  const daq_status_t status = test::known_daq_status();
  ASSERT_EQ(lcm.publish("INERTIA_STATUS", &status), 0);

  // Our own publications loop back to us; handle until all arrived or 2 s passed.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while ((receiver.blocks.size() < kBlocks || receiver.statuses.empty()) &&
         std::chrono::steady_clock::now() < deadline) {
    ASSERT_GE(lcm.handleTimeout(100), 0);
  }
  ASSERT_EQ(receiver.blocks.size(), static_cast<std::size_t>(kBlocks));
  for (int i = 0; i < kBlocks; ++i) {
    EXPECT_EQ(receiver.channels[static_cast<std::size_t>(i)], "INERTIA_RAW_SIM_REF_1");
    block.seq = 100 + i;
    SCOPED_TRACE("block " + std::to_string(i));
    test::expect_equal(receiver.blocks[static_cast<std::size_t>(i)], block);
  }
  ASSERT_EQ(receiver.statuses.size(), 1U);
  test::expect_equal(receiver.statuses[0], status);
}

}  // namespace
}  // namespace inertia
