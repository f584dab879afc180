// CanLinkWatch with the kernel's part played by the test (this machine has no AF_CAN): the
// device's socket is one end of a socketpair whose peer closing stands for the interface going
// away (a real CAN_RAW socket gets ENODEV or ENETDOWN instead, which CanDevice treats the same);
// the interface's state comes from a query the test answers, and the reopened socket is the end
// of a new socketpair. What cannot run here: ENODEV/ENETDOWN from a real CAN_RAW socket, rtnetlink's
// answer for a real adapter, and binding to a re-registered interface (KernelCan.* on a kernel
// with vcan covers the sockets; a re-plug needs the hardware).
#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <unistd.h>

#include <vector>

#include <gtest/gtest.h>

#include "hal/socketcan/can_link_watch.hpp"

namespace inertia::hal::socketcan {
namespace {

class Sink final : public SampleSink {
 public:
  bool push(std::uint32_t, std::int64_t, double value, bool, std::int64_t) noexcept override {
    values.push_back(value);
    return true;
  }
  std::vector<double> values;
};

struct Pair {
  UniqueFd writer, reader;
  Pair() {
    int sv[2];
    EXPECT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    writer = UniqueFd(sv[0]);
    reader = UniqueFd(sv[1]);
  }
  void send(std::uint32_t id, std::uint8_t value, std::uint8_t len = 1) const {
    can_frame f{};
    f.can_id = id;
    f.len = len;
    f.data[0] = value;
    ASSERT_EQ(::send(writer.get(), &f, sizeof f, 0), static_cast<ssize_t>(sizeof f));
  }
};

std::unique_ptr<CanDevice> make_device(UniqueFd fd) {
  CanDeviceConfig config;
  config.name = "adc";
  config.interface = "can0";
  CanSignal v;
  v.name = "v";
  v.id = 0x10;
  v.bit_length = 8;
  config.map.signals = {v};
  std::string why;
  auto device = CanDevice::from_fd(std::move(fd), config, &why);
  EXPECT_NE(device, nullptr) << why;
  EXPECT_EQ(device->configure(), Step::Ok);
  EXPECT_EQ(device->activate(), Step::Ok);
  return device;
}

TEST(CanLinkWatch, ARepluggedAdapterIsReopenedByNameWithBackoffAndSamplingGoesOn) {
  Pair first;
  auto device = make_device(std::move(first.reader));
  const int waited_on = device->wait_fd();
  Sink sink;
  first.send(0x10, 1);
  EXPECT_EQ(device->read_into(sink), 1u);

  // The adapter is pulled: its interface disappears, then comes back under the same name.
  first.writer.reset();
  EXPECT_EQ(device->read_into(sink), 0u);
  EXPECT_TRUE(device->link_down());
  EXPECT_EQ(device->read_into(sink), 0u) << "nothing read from a socket whose interface is gone";

  int queries = 0;
  std::vector<std::string> opened;
  Pair second;
  CanLinkOps ops;
  ops.query = [&](const std::string& name, CanInterfaceInfo* info, std::string*) {
    ++queries;
    *info = CanInterfaceInfo{};
    info->name = name;
    info->present = queries >= 3;            // unplugged for the first two looks
    info->up = info->running = queries >= 4; // then registered, and up from the fourth
    info->kind = "can";
    info->state = ControllerState::ErrorActive;
    return true;
  };
  ops.open = [&](const std::string& name, std::string*) {
    opened.push_back(name);
    return std::move(second.reader);
  };
  CanLinkWatch watch(*device, "can0", ops);
  // Looks at 0, 0.1, 0.3 and 0.7 s: the back-off doubles from 0.1 s. In between, nothing.
  const std::int64_t t0 = 1'000'000'000;
  EXPECT_FALSE(watch.check(t0));
  EXPECT_FALSE(watch.check(t0 + 50'000'000));
  EXPECT_EQ(queries, 1);
  EXPECT_NE(watch.last_error().find("not there"), std::string::npos) << watch.last_error();
  EXPECT_FALSE(watch.check(t0 + 100'000'000));
  EXPECT_FALSE(watch.check(t0 + 299'000'000));
  EXPECT_FALSE(watch.check(t0 + 300'000'000));
  EXPECT_NE(watch.last_error().find("is down"), std::string::npos) << watch.last_error();
  EXPECT_EQ(queries, 3);
  EXPECT_FALSE(watch.check(t0 + 600'000'000));
  EXPECT_TRUE(watch.check(t0 + 700'000'000));
  EXPECT_EQ(queries, 4);
  EXPECT_EQ(opened, std::vector<std::string>{"can0"}) << "reopened by name, once";
  EXPECT_FALSE(device->link_down());
  EXPECT_FALSE(watch.check(t0 + 800'000'000)) << "nothing to do once it is back";

  // Frames on the new socket, through the same descriptor number the sampler polls.
  EXPECT_EQ(device->wait_fd(), waited_on);
  second.send(0x10, 2);
  second.send(0x10, 3);
  EXPECT_EQ(device->read_into(sink), 2u);
  EXPECT_EQ(sink.values, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(device->status().link_reopens, 1u);
  EXPECT_FALSE(device->status().link_down);
}

TEST(CanLinkWatch, ABusOffClearsWhenTheInterfaceReportsTheControllerActiveAgain) {
  // ip link set can0 down; ip link set can0 up: the controller restarts error-active without the
  // CAN_ERR_RESTARTED frame that clears a bus-off on the socket.
  Pair pair;
  auto device = make_device(std::move(pair.reader));
  Sink sink;
  can_frame off{};
  off.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  off.len = CAN_ERR_DLC;
  ASSERT_EQ(::send(pair.writer.get(), &off, sizeof off, 0), static_cast<ssize_t>(sizeof off));
  device->read_into(sink);
  ASSERT_EQ(device->status().bus_state, BusState::BusOff);
  ControllerState reported = ControllerState::BusOff;
  CanLinkOps ops;
  ops.query = [&](const std::string& name, CanInterfaceInfo* info, std::string*) {
    *info = CanInterfaceInfo{};
    info->name = name;
    info->present = info->up = info->running = true;
    info->kind = "can";
    info->state = reported;
    return true;
  };
  ops.open = [](const std::string&, std::string* why) {
    *why = "no reopen expected";
    return UniqueFd();
  };
  CanLinkWatch watch(*device, "can0", ops);
  EXPECT_FALSE(watch.check(0)) << "the interface still says bus-off";
  device->read_into(sink);
  EXPECT_EQ(device->status().bus_state, BusState::BusOff);
  reported = ControllerState::ErrorActive;
  EXPECT_TRUE(watch.check(CanLinkWatch::kFirstBackoffNs));
  device->read_into(sink);
  EXPECT_EQ(device->status().bus_state, BusState::ErrorActive);
  EXPECT_FALSE(device->bus_off());
  EXPECT_EQ(device->status().link_reopens, 0u) << "the socket stayed; only the state cleared";
}

TEST(CanLinkWatch, ControllerStatesMapToBusStates) {
  EXPECT_EQ(bus_state_of(ControllerState::ErrorActive), BusState::ErrorActive);
  EXPECT_EQ(bus_state_of(ControllerState::ErrorWarning), BusState::ErrorWarning);
  EXPECT_EQ(bus_state_of(ControllerState::ErrorPassive), BusState::ErrorPassive);
  EXPECT_EQ(bus_state_of(ControllerState::BusOff), BusState::BusOff);
  EXPECT_EQ(bus_state_of(ControllerState::Stopped), BusState::BusOff);
  EXPECT_EQ(bus_state_of(ControllerState::Unknown), BusState::ErrorActive);
}

}  // namespace
}  // namespace inertia::hal::socketcan
