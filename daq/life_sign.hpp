#pragma once
// The daemon's proof of life for its controllers' heartbeats. The supervisor renews a lease
// while every sampling thread and the publisher are moving; a Modbus polling thread writes its
// controller's heartbeat register only while the lease runs. A daemon that hangs lets the lease
// lapse and the heartbeats stop, as they stop when it dies: either way the controllers' own
// communication-loss action stops the bench (common/config/machine_safety.hpp).
//
// Thread: renew() from the supervisor, alive() from any thread. Lock-free.
#include <atomic>
#include <cstdint>

namespace inertia::daq {

class LifeSign {
 public:
  /// Alive until `until_ns` (CLOCK_MONOTONIC).
  void renew(std::int64_t until_ns) noexcept { until_ns_.store(until_ns, std::memory_order_release); }
  [[nodiscard]] bool alive(std::int64_t now_ns) const noexcept { return now_ns < until_ns_.load(std::memory_order_acquire); }

 private:
  std::atomic<std::int64_t> until_ns_{0};
};

}  // namespace inertia::daq
