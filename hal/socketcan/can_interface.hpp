#pragma once
// What the kernel says about a network interface that should carry CAN: present, up, its link
// type, bit rates, FD mode and controller state, read over rtnetlink (RTM_GETLINK), the source
// `ip -details link show can0` prints from. Netlink works on every Linux kernel, also on one
// without SocketCAN, so an absent or miswired interface is reported the same way everywhere.
// Kernel doc networking/can.rst section 6.6 ("The CAN netlink interface").
// Not real-time: used by inertia-daqd --check and at start-up, never in a sampling thread.
#include <cstdint>
#include <span>
#include <string>

namespace inertia::hal::socketcan {

/// enum can_state of linux/can/netlink.h, as ip(8) prints it.
enum class ControllerState { Unknown, ErrorActive, ErrorWarning, ErrorPassive, BusOff, Stopped, Sleeping };
const char* to_string(ControllerState state) noexcept;

struct CanInterfaceInfo {
  bool present = false;
  std::string name;
  bool up = false;               // IFF_UP: set administratively (ip link set can0 up)
  bool running = false;          // IFF_RUNNING: the controller started (carrier)
  std::string kind;              // IFLA_INFO_KIND: "can" (a controller), "vcan", "vxcan"; "" e.g. loopback
  std::uint32_t mtu = 0;         // 16 (CAN_MTU, classic) or 72 (CANFD_MTU: FD frames pass)
  // Only a real controller ("can") has these: virtual CAN has no bit timing.
  std::uint32_t bitrate = 0;     // IFLA_CAN_BITTIMING.bitrate, bit/s (0: not reported)
  std::uint32_t data_bitrate = 0;  // IFLA_CAN_DATA_BITTIMING.bitrate (CAN FD data phase)
  bool fd_mode = false;          // CAN_CTRLMODE_FD among IFLA_CAN_CTRLMODE's flags
  std::uint32_t restart_ms = 0;  // IFLA_CAN_RESTART_MS: automatic restart after bus-off (0: off)
  ControllerState state = ControllerState::Unknown;
  std::uint16_t tx_errors = 0, rx_errors = 0;   // IFLA_CAN_BERR_COUNTER
  bool berr_counter = false;

  [[nodiscard]] bool is_can() const noexcept { return kind == "can" || kind == "vcan" || kind == "vxcan"; }
  /// Whether CAN FD frames can pass: FD mode on a controller, MTU 72 on a virtual bus.
  [[nodiscard]] bool carries_fd() const noexcept { return fd_mode || mtu == 72; }
};

/// Asks the kernel about interface `name`. An absent interface is not an error (present =
/// false); false with the reason only when netlink itself fails.
bool query_can_interface(const std::string& name, CanInterfaceInfo* info, std::string* why);

/// Reads one RTM_NEWLINK message (from its struct nlmsghdr on) into `info`; false when it is not
/// one or is truncated. query_can_interface() uses it; tests feed it messages built byte by byte
/// as the kernel lays them out (this machine's kernel has no CAN to answer).
bool parse_link_message(std::span<const std::uint8_t> message, CanInterfaceInfo* info);

}  // namespace inertia::hal::socketcan
