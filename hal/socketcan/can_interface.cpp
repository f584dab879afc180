#include "hal/socketcan/can_interface.hpp"

#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <functional>

#include "hal/unique_fd.hpp"

namespace inertia::hal::socketcan {
namespace {

// Netlink attributes are (len, type) headers followed by the payload, each padded to 4 bytes
// (NLA_ALIGN). Read with memcpy: a buffer handed in by a caller need not be aligned.
template <class T>
T read_as(std::span<const std::uint8_t> bytes) {
  T value{};
  std::memcpy(&value, bytes.data(), std::min(sizeof(T), bytes.size()));
  return value;
}

/// Calls visit(type, payload) for every attribute in `bytes`; false when one is malformed.
bool for_each_attribute(std::span<const std::uint8_t> bytes,
                        const std::function<void(unsigned, std::span<const std::uint8_t>)>& visit) {
  std::size_t at = 0;
  while (at + sizeof(nlattr) <= bytes.size()) {
    const auto header = read_as<nlattr>(bytes.subspan(at));
    if (header.nla_len < sizeof(nlattr) || at + header.nla_len > bytes.size()) return false;
    visit(header.nla_type & NLA_TYPE_MASK, bytes.subspan(at + NLA_HDRLEN, header.nla_len - NLA_HDRLEN));
    at += NLA_ALIGN(header.nla_len);
  }
  return true;
}

ControllerState state_from_kernel(std::uint32_t s) {
  switch (s) {
    case CAN_STATE_ERROR_ACTIVE: return ControllerState::ErrorActive;
    case CAN_STATE_ERROR_WARNING: return ControllerState::ErrorWarning;
    case CAN_STATE_ERROR_PASSIVE: return ControllerState::ErrorPassive;
    case CAN_STATE_BUS_OFF: return ControllerState::BusOff;
    case CAN_STATE_STOPPED: return ControllerState::Stopped;
    case CAN_STATE_SLEEPING: return ControllerState::Sleeping;
    default: return ControllerState::Unknown;
  }
}

void read_can_data(std::span<const std::uint8_t> data, CanInterfaceInfo* info) {
  for_each_attribute(data, [info](unsigned type, std::span<const std::uint8_t> p) {
    switch (type) {
      case IFLA_CAN_BITTIMING:
        if (p.size() >= sizeof(can_bittiming)) info->bitrate = read_as<can_bittiming>(p).bitrate;
        break;
      case IFLA_CAN_DATA_BITTIMING:
        if (p.size() >= sizeof(can_bittiming)) info->data_bitrate = read_as<can_bittiming>(p).bitrate;
        break;
      case IFLA_CAN_CTRLMODE:
        if (p.size() >= sizeof(can_ctrlmode)) info->fd_mode = (read_as<can_ctrlmode>(p).flags & CAN_CTRLMODE_FD) != 0;
        break;
      case IFLA_CAN_STATE:
        if (p.size() >= sizeof(std::uint32_t)) info->state = state_from_kernel(read_as<std::uint32_t>(p));
        break;
      case IFLA_CAN_RESTART_MS:
        if (p.size() >= sizeof(std::uint32_t)) info->restart_ms = read_as<std::uint32_t>(p);
        break;
      case IFLA_CAN_BERR_COUNTER:
        if (p.size() >= sizeof(can_berr_counter)) {
          const auto c = read_as<can_berr_counter>(p);
          info->tx_errors = c.txerr;
          info->rx_errors = c.rxerr;
          info->berr_counter = true;
        }
        break;
      default: break;
    }
  });
}

}  // namespace

const char* to_string(ControllerState state) noexcept {
  switch (state) {
    case ControllerState::Unknown: return "unknown";
    case ControllerState::ErrorActive: return "ERROR-ACTIVE";
    case ControllerState::ErrorWarning: return "ERROR-WARNING";
    case ControllerState::ErrorPassive: return "ERROR-PASSIVE";
    case ControllerState::BusOff: return "BUS-OFF";
    case ControllerState::Stopped: return "STOPPED";
    case ControllerState::Sleeping: return "SLEEPING";
  }
  return "?";
}

bool parse_link_message(std::span<const std::uint8_t> message, CanInterfaceInfo* info) {
  if (message.size() < NLMSG_LENGTH(sizeof(ifinfomsg))) return false;
  const auto header = read_as<nlmsghdr>(message);
  if (header.nlmsg_type != RTM_NEWLINK || header.nlmsg_len > message.size() ||
      header.nlmsg_len < NLMSG_LENGTH(sizeof(ifinfomsg)))
    return false;
  const auto ifi = read_as<ifinfomsg>(message.subspan(NLMSG_HDRLEN));
  *info = CanInterfaceInfo{};
  info->present = true;
  info->up = (ifi.ifi_flags & IFF_UP) != 0;
  info->running = (ifi.ifi_flags & IFF_RUNNING) != 0;
  const std::size_t attributes_at = NLMSG_HDRLEN + NLMSG_ALIGN(sizeof(ifinfomsg));
  const auto text = [](std::span<const std::uint8_t> p) {
    const auto* c = reinterpret_cast<const char*>(p.data());
    return std::string(c, ::strnlen(c, p.size()));
  };
  const auto link_info = [&](unsigned type, std::span<const std::uint8_t> p) {
    if (type == IFLA_INFO_KIND) info->kind = text(p);
    if (type == IFLA_INFO_DATA) read_can_data(p, info);
  };
  return for_each_attribute(message.subspan(attributes_at, header.nlmsg_len - attributes_at),
                            [&](unsigned type, std::span<const std::uint8_t> p) {
                              if (type == IFLA_IFNAME) info->name = text(p);
                              if (type == IFLA_MTU && p.size() >= 4) info->mtu = read_as<std::uint32_t>(p);
                              if (type == IFLA_LINKINFO) for_each_attribute(p, link_info);
                            });
}

bool query_can_interface(const std::string& name, CanInterfaceInfo* info, std::string* why) {
  *info = CanInterfaceInfo{};
  info->name = name;
  const unsigned index = ::if_nametoindex(name.c_str());
  if (index == 0) return true;  // ENODEV: no such interface (present stays false)
  UniqueFd fd(::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE));
  if (!fd.valid()) {
    if (why) *why = std::string("socket(AF_NETLINK, NETLINK_ROUTE): ") + std::strerror(errno);
    return false;
  }
  struct {
    nlmsghdr header;
    ifinfomsg ifi;
  } request{};
  request.header.nlmsg_len = NLMSG_LENGTH(sizeof(ifinfomsg));
  request.header.nlmsg_type = RTM_GETLINK;
  request.header.nlmsg_flags = NLM_F_REQUEST;
  request.header.nlmsg_seq = 1;
  request.ifi.ifi_family = AF_UNSPEC;
  request.ifi.ifi_index = static_cast<int>(index);
  if (::send(fd.get(), &request, request.header.nlmsg_len, 0) < 0) {
    if (why) *why = std::string("netlink RTM_GETLINK: ") + std::strerror(errno);
    return false;
  }
  // One link's answer is a few hundred bytes to a few KiB (statistics, VF lists); 32 KiB is ample.
  std::array<std::uint8_t, 32768> buffer{};
  const ssize_t got = ::recv(fd.get(), buffer.data(), buffer.size(), 0);
  if (got < 0) {
    if (why) *why = std::string("netlink recv: ") + std::strerror(errno);
    return false;
  }
  const std::span<const std::uint8_t> reply(buffer.data(), static_cast<std::size_t>(got));
  const auto header = read_as<nlmsghdr>(reply);
  if (header.nlmsg_type == NLMSG_ERROR) {
    const auto error = read_as<nlmsgerr>(reply.subspan(NLMSG_HDRLEN));
    if (error.error == -ENODEV) return true;  // gone between the lookup and the request
    if (why) *why = std::string("netlink RTM_GETLINK ") + name + ": " + std::strerror(-error.error);
    return false;
  }
  if (!parse_link_message(reply, info)) {
    if (why) *why = "netlink RTM_GETLINK " + name + ": malformed answer";
    return false;
  }
  return true;
}

}  // namespace inertia::hal::socketcan
