#include "hal/socketcan/can_link_watch.hpp"

#include <algorithm>
#include <utility>

namespace inertia::hal::socketcan {

BusState bus_state_of(ControllerState state) noexcept {
  switch (state) {
    case ControllerState::ErrorWarning: return BusState::ErrorWarning;
    case ControllerState::ErrorPassive: return BusState::ErrorPassive;
    case ControllerState::BusOff:
    case ControllerState::Stopped:
    case ControllerState::Sleeping: return BusState::BusOff;
    case ControllerState::ErrorActive:
    case ControllerState::Unknown: return BusState::ErrorActive;   // virtual CAN has no controller
  }
  return BusState::ErrorActive;
}

CanLinkWatch::CanLinkWatch(CanDevice& device, std::string interface, CanLinkOps ops)
    : device_(device), interface_(std::move(interface)), ops_(std::move(ops)) {
  if (!ops_.query) ops_.query = query_can_interface;
  if (!ops_.open) ops_.open = open_can_raw;
}

bool CanLinkWatch::check(std::int64_t now_ns) {
  const bool down = device_.link_down();
  if (!down && !device_.bus_off()) {
    backoff_ns_ = kFirstBackoffNs;
    next_ns_ = 0;
    return false;
  }
  if (now_ns < next_ns_) return false;
  ++attempts_;
  next_ns_ = now_ns + backoff_ns_;
  backoff_ns_ = std::min(2 * backoff_ns_, kMaxBackoffNs);
  CanInterfaceInfo info;
  std::string why;
  if (!ops_.query(interface_, &info, &why)) {
    last_error_ = why;
    return false;
  }
  if (!info.present) {
    last_error_ = "CAN interface '" + interface_ + "' is not there (adapter unplugged?)";
    return false;
  }
  if (!info.up || !info.running) {
    last_error_ = "CAN interface '" + interface_ + "' is down (ip link set " + interface_ + " up)";
    return false;
  }
  const BusState state = bus_state_of(info.state);
  if (down) {
    UniqueFd fd = ops_.open(interface_, &why);
    if (!fd.valid() || !device_.adopt(std::move(fd), state, &why)) {
      last_error_ = why;
      return false;
    }
  } else if (state == BusState::BusOff) {
    last_error_ = "CAN interface '" + interface_ + "' is still bus-off";
    return false;
  } else {
    device_.set_bus_state(state);
  }
  last_error_.clear();
  backoff_ns_ = kFirstBackoffNs;
  next_ns_ = 0;
  return true;
}

}  // namespace inertia::hal::socketcan
