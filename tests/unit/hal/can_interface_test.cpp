// The interface query behind inertia-daqd --check: real rtnetlink answers for the interfaces this
// machine has (loopback; an absent name), and RTM_NEWLINK messages laid out byte by byte as the
// kernel's CAN driver sends them (this kernel has no CAN to answer: no AF_CAN, no vcan).
#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>

#include <cstddef>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hal/socketcan/can_interface.hpp"

namespace inertia::hal::socketcan {
namespace {

/// Builds netlink attributes as the kernel does: header, payload, padding to 4 bytes; nested
/// attributes are closed with end() once their content is in.
class Attributes {
 public:
  template <class T>
  void put(unsigned type, const T& value) {
    put_bytes(type, &value, sizeof value);
  }
  void put_string(unsigned type, const std::string& s) { put_bytes(type, s.c_str(), s.size() + 1); }
  std::size_t begin(unsigned type) {
    const std::size_t at = bytes_.size();
    put_bytes(type | NLA_F_NESTED, nullptr, 0);
    return at;
  }
  void end(std::size_t at) {
    const auto len = static_cast<std::uint16_t>(bytes_.size() - at);
    std::memcpy(bytes_.data() + at, &len, sizeof len);
  }
  [[nodiscard]] const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  void put_bytes(unsigned type, const void* data, std::size_t size) {
    nlattr header{};
    header.nla_len = static_cast<std::uint16_t>(NLA_HDRLEN + size);
    header.nla_type = static_cast<std::uint16_t>(type);
    const auto* h = reinterpret_cast<const std::uint8_t*>(&header);
    bytes_.insert(bytes_.end(), h, h + sizeof header);
    if (size > 0) bytes_.insert(bytes_.end(), static_cast<const std::uint8_t*>(data), static_cast<const std::uint8_t*>(data) + size);
    bytes_.resize(NLA_ALIGN(bytes_.size()), 0);
  }
  std::vector<std::uint8_t> bytes_;
};

std::vector<std::uint8_t> new_link(unsigned flags, const Attributes& attributes) {
  nlmsghdr header{};
  ifinfomsg ifi{};
  ifi.ifi_family = AF_UNSPEC;
  ifi.ifi_index = 7;
  ifi.ifi_flags = flags;
  header.nlmsg_type = RTM_NEWLINK;
  header.nlmsg_len = static_cast<std::uint32_t>(NLMSG_LENGTH(sizeof ifi) + attributes.bytes().size());
  std::vector<std::uint8_t> m(header.nlmsg_len, 0);
  std::memcpy(m.data(), &header, sizeof header);
  std::memcpy(m.data() + NLMSG_HDRLEN, &ifi, sizeof ifi);
  std::memcpy(m.data() + NLMSG_LENGTH(sizeof ifi), attributes.bytes().data(), attributes.bytes().size());
  return m;
}

TEST(CanInterface, ReadsAControllersBitRatesFdModeStateAndErrorCounters) {
  // What `ip link set can0 up type can bitrate 1000000 dbitrate 5000000 fd on restart-ms 100`
  // leaves for RTM_GETLINK, on a controller that went error-passive.
  Attributes a;
  a.put_string(IFLA_IFNAME, "can0");
  a.put<std::uint32_t>(IFLA_MTU, 72);
  const auto info = a.begin(IFLA_LINKINFO);
  a.put_string(IFLA_INFO_KIND, "can");
  const auto data = a.begin(IFLA_INFO_DATA);
  can_bittiming bt{};
  bt.bitrate = 1'000'000;
  bt.sample_point = 875;
  a.put(IFLA_CAN_BITTIMING, bt);
  can_bittiming dbt{};
  dbt.bitrate = 5'000'000;
  a.put(IFLA_CAN_DATA_BITTIMING, dbt);
  a.put(IFLA_CAN_CTRLMODE, can_ctrlmode{CAN_CTRLMODE_FD | CAN_CTRLMODE_LOOPBACK, CAN_CTRLMODE_FD});
  a.put<std::uint32_t>(IFLA_CAN_STATE, CAN_STATE_ERROR_PASSIVE);
  a.put<std::uint32_t>(IFLA_CAN_RESTART_MS, 100);
  a.put(IFLA_CAN_BERR_COUNTER, can_berr_counter{130, 5});
  a.end(data);
  a.end(info);
  CanInterfaceInfo out;
  ASSERT_TRUE(parse_link_message(new_link(IFF_UP | IFF_RUNNING, a), &out));
  EXPECT_TRUE(out.present);
  EXPECT_EQ(out.name, "can0");
  EXPECT_TRUE(out.up);
  EXPECT_TRUE(out.running);
  EXPECT_EQ(out.kind, "can");
  EXPECT_TRUE(out.is_can());
  EXPECT_EQ(out.mtu, 72u);
  EXPECT_EQ(out.bitrate, 1'000'000u);
  EXPECT_EQ(out.data_bitrate, 5'000'000u);
  EXPECT_TRUE(out.fd_mode);
  EXPECT_TRUE(out.carries_fd());
  EXPECT_EQ(out.state, ControllerState::ErrorPassive);
  EXPECT_STREQ(to_string(out.state), "ERROR-PASSIVE");
  EXPECT_EQ(out.restart_ms, 100u);
  EXPECT_TRUE(out.berr_counter);
  EXPECT_EQ(out.tx_errors, 130);
  EXPECT_EQ(out.rx_errors, 5);
}

TEST(CanInterface, AClassicControllerDownAndAVirtualBus) {
  Attributes a;
  a.put_string(IFLA_IFNAME, "can1");
  a.put<std::uint32_t>(IFLA_MTU, 16);
  const auto info = a.begin(IFLA_LINKINFO);
  a.put_string(IFLA_INFO_KIND, "can");
  const auto data = a.begin(IFLA_INFO_DATA);
  a.put(IFLA_CAN_CTRLMODE, can_ctrlmode{CAN_CTRLMODE_FD, 0});
  a.put<std::uint32_t>(IFLA_CAN_STATE, CAN_STATE_STOPPED);
  a.end(data);
  a.end(info);
  CanInterfaceInfo down;
  ASSERT_TRUE(parse_link_message(new_link(0, a), &down));
  EXPECT_FALSE(down.up);
  EXPECT_FALSE(down.fd_mode);
  EXPECT_FALSE(down.carries_fd());
  EXPECT_EQ(down.bitrate, 0u);  // a stopped controller reports no bit timing until it is set
  EXPECT_EQ(down.state, ControllerState::Stopped);

  // `ip link add dev vcan0 type vcan && ip link set vcan0 mtu 72 up`: no controller data at all.
  Attributes v;
  v.put_string(IFLA_IFNAME, "vcan0");
  v.put<std::uint32_t>(IFLA_MTU, 72);
  const auto vinfo = v.begin(IFLA_LINKINFO);
  v.put_string(IFLA_INFO_KIND, "vcan");
  v.end(vinfo);
  CanInterfaceInfo virt;
  ASSERT_TRUE(parse_link_message(new_link(IFF_UP | IFF_RUNNING, v), &virt));
  EXPECT_EQ(virt.kind, "vcan");
  EXPECT_TRUE(virt.is_can());
  EXPECT_TRUE(virt.carries_fd());
  EXPECT_FALSE(virt.fd_mode);
  EXPECT_EQ(virt.state, ControllerState::Unknown);
}

TEST(CanInterface, RefusesWhatIsNotAWholeNewLinkMessage) {
  Attributes a;
  a.put_string(IFLA_IFNAME, "can0");
  std::vector<std::uint8_t> m = new_link(IFF_UP, a);
  CanInterfaceInfo out;
  EXPECT_FALSE(parse_link_message(std::span<const std::uint8_t>(m.data(), m.size() - 4), &out));  // cut short
  std::vector<std::uint8_t> bad = m;
  const std::uint16_t too_long = 200;
  std::memcpy(bad.data() + NLMSG_LENGTH(sizeof(ifinfomsg)), &too_long, sizeof too_long);  // attribute past the end
  EXPECT_FALSE(parse_link_message(bad, &out));
  std::vector<std::uint8_t> other = m;
  const std::uint16_t del = RTM_DELLINK;
  std::memcpy(other.data() + offsetof(nlmsghdr, nlmsg_type), &del, sizeof del);
  EXPECT_FALSE(parse_link_message(other, &out));
}

TEST(CanInterface, AsksTheKernelAboutRealInterfaces) {
  CanInterfaceInfo lo;
  std::string why;
  ASSERT_TRUE(query_can_interface("lo", &lo, &why)) << why;
  EXPECT_TRUE(lo.present);
  EXPECT_EQ(lo.name, "lo");
  EXPECT_TRUE(lo.up);
  EXPECT_FALSE(lo.is_can()) << lo.kind;  // loopback has no link kind
  EXPECT_GT(lo.mtu, 0u);
  CanInterfaceInfo absent;
  ASSERT_TRUE(query_can_interface("inertia-none0", &absent, &why)) << why;
  EXPECT_FALSE(absent.present);
  EXPECT_EQ(absent.name, "inertia-none0");
}

}  // namespace
}  // namespace inertia::hal::socketcan
