#pragma once
// Keeps a CAN device's socket on its interface across what a bench does to interfaces:
//   * a re-plugged USB adapter: its interface is unregistered (the socket gets ENODEV and is
//     unbound for good) and registered again, under the same name, with a new index;
//   * `ip link set can0 down` and `up`: the socket gets ENETDOWN; the controller restarts
//     error-active, but sends no CAN_ERR_RESTARTED, so a bus-off seen before would never clear.
// While the device's link is down, or it is bus-off, the watch asks the interface's state
// (rtnetlink, can_interface.hpp) at a back-off (0.1 s, doubling to 5 s): once the interface is
// up and running, a socket is opened on it again by name and takes the old one's place
// (CanDevice::adopt), with the controller's state as the interface reports it; a bus-off is
// cleared when the interface reports the controller active again.
// Thread: its own (DeviceSampler runs it beside the sampling thread); not real-time (netlink,
// socket(), allocation): the sampling thread only reads flags it leaves.
#include <cstdint>
#include <functional>
#include <string>

#include "hal/socketcan/can_device.hpp"
#include "hal/socketcan/can_interface.hpp"
#include "hal/unique_fd.hpp"

namespace inertia::hal::socketcan {

/// How the watch reaches the kernel; tests give their own (this machine has no AF_CAN).
struct CanLinkOps {
  /// The interface's state; default query_can_interface().
  std::function<bool(const std::string& interface, CanInterfaceInfo* info, std::string* why)> query;
  /// A new socket on the interface; default open_can_raw().
  std::function<UniqueFd(const std::string& interface, std::string* why)> open;
};

class CanLinkWatch {
 public:
  static constexpr std::int64_t kFirstBackoffNs = 100'000'000;
  static constexpr std::int64_t kMaxBackoffNs = 5'000'000'000;

  CanLinkWatch(CanDevice& device, std::string interface, CanLinkOps ops = {});

  /// Call it often (every kFirstBackoffNs or so); it acts at most once per back-off, and only
  /// while the link is down or the controller bus-off. True when it restored the link or
  /// cleared a bus-off this time.
  bool check(std::int64_t now_ns);

  /// What the last attempt found (empty after a success): for the journal.
  [[nodiscard]] const std::string& last_error() const noexcept { return last_error_; }
  [[nodiscard]] std::uint64_t attempts() const noexcept { return attempts_; }

 private:
  CanDevice& device_;
  std::string interface_;
  CanLinkOps ops_;
  std::int64_t next_ns_ = 0;
  std::int64_t backoff_ns_ = kFirstBackoffNs;
  std::uint64_t attempts_ = 0;
  std::string last_error_;
};

/// The device's bus state from the interface's controller state (a stopped or sleeping
/// controller is not on the bus: bus-off).
BusState bus_state_of(ControllerState state) noexcept;

}  // namespace inertia::hal::socketcan
