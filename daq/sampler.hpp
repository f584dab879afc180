#pragma once
// One sampling thread per device (docs/design.md): waits for input on the device's descriptors,
// calls Device::read_into() with a sink that writes the device's SPSC ring, and mirrors the
// device's health into the slot's atomics.
//
// Thread: start()/stop() on the control thread; the loop runs on its own thread.
// Real-time: the loop allocates nothing, takes no lock, and blocks only in poll() waiting for
// input (bounded by kIdleWaitMs so the heartbeat keeps moving); read_into() never blocks.
// Optional SCHED_FIFO and CPU affinity are applied by the thread itself (warning on failure).
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "daq/controller_port.hpp"
#include "daq/device_slot.hpp"
#include "hal/device.hpp"
#include "hal/gpiod/encoder_device.hpp"
#include "hal/modbus/modbus_controller.hpp"
#include "hal/socketcan/can_device.hpp"
#include "hal/socketcan/can_link_watch.hpp"

namespace inertia::daq {

struct RealtimeOptions {
  int fifo_priority = 0;   // 0: SCHED_OTHER
  int cpu = -1;            // -1: no affinity
};

class Sampler {
 public:
  virtual ~Sampler() = default;
  /// Lifecycle: configure, then activate. False + why naming the device
  /// (the slot's state says Failed). Control thread, before start().
  virtual bool bring_up(std::string* why) = 0;
  virtual void start(const RealtimeOptions& rt) = 0;
  /// Asks the loop to finish: it drains what is pending (read_into until 0), then leaves. Joins.
  virtual void stop() = 0;
  [[nodiscard]] virtual DeviceSlot& slot() noexcept = 0;
  /// Whether the systemd watchdog follows this sampler's heartbeat: the real-time samplers, whose
  /// stall loses samples. A Modbus poller blocks up to its response timeout by design; its stall
  /// is the device's fault (`silent`), not a reason to restart the daemon.
  [[nodiscard]] virtual bool watched() const noexcept { return true; }
};

/// CAN bus or encoder: an event-driven device with descriptors to poll. A CAN device on a real
/// interface also gets a thread that watches its link (hal/socketcan/can_link_watch.hpp): it
/// reopens the interface by name when it comes back and clears a bus-off the interface no longer
/// reports, so the sampling thread never waits on netlink or opens sockets.
class DeviceSampler final : public Sampler {
 public:
  static constexpr int kIdleWaitMs = 20;
  /// For an encoder with a trigger line: `trigger_rows` turns each trigger edge into one row
  /// (count, position latched at that edge) so the encoder is sampled on the bench's sample
  /// clock; without it every edge would be a sample at an irregular time.
  DeviceSampler(std::unique_ptr<hal::Device> device, std::vector<int> wait_fds, std::shared_ptr<DeviceSlot> slot,
                bool trigger_rows);
  ~DeviceSampler() override { stop(); }
  bool bring_up(std::string* why) override;
  void start(const RealtimeOptions& rt) override;
  void stop() override;
  [[nodiscard]] DeviceSlot& slot() noexcept override { return *slot_; }
  [[nodiscard]] hal::Device& device() noexcept { return *device_; }

 private:
  void run(RealtimeOptions rt) noexcept;
  void watch_link() noexcept;
  void mirror_health() noexcept;

  std::unique_ptr<hal::Device> device_;
  // The backend behind device_, resolved once (not per loop) for its extra status.
  hal::socketcan::CanDevice* can_ = nullptr;
  hal::gpiod::GpiodEncoderDevice* encoder_ = nullptr;
  std::vector<int> wait_fds_;
  std::shared_ptr<DeviceSlot> slot_;
  bool trigger_rows_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::unique_ptr<hal::socketcan::CanLinkWatch> link_watch_;   // real CAN interfaces only
  std::thread link_thread_;
};

/// A Modbus controller polled at its interval. Thread: its own, NOT real-time (each request may
/// block up to the response timeout, which must never hold up a sampling thread of a
/// fast device, so it has a thread of its own and a ring like every device).
/// With a ControllerPort the same thread also carries the test executive's commands to the
/// device (the only thread that talks to it), between polls and at once when posted.
/// The simulated time of a simulated bench run as fast as possible (--fast), for a poller to follow.
/// Polled in wall time, the controllers would be read a few times while the simulator runs the
/// whole plan, stamped on another clock than the samples: a thermal plan's log would carry no
/// usable temperature. Following this clock, they are read every poll interval of simulated time
/// and stamped with it, as in a paced run; the simulator waits for each reading before it moves
/// the registers past it. Thread: the simulator writes reached_ns, the poller polled_ns.
struct SimulatedClock {
  static constexpr std::int64_t kNotYet = std::numeric_limits<std::int64_t>::min();
  /// The registers hold the bench's state for every simulated time up to this one.
  std::atomic<std::int64_t> reached_ns{kNotYet};
  /// The newest simulated time a reading was stamped with (kNotYet: none yet).
  std::atomic<std::int64_t> polled_ns{kNotYet};
  /// The poller left (stopped): nobody will take the next reading.
  std::atomic<bool> poller_gone{false};
};

class ModbusSampler final : public Sampler {
 public:
  /// `clock`: a fast simulated run's clock to poll on (nullptr: wall time, every interval).
  ModbusSampler(std::unique_ptr<hal::modbus::ModbusController> controller, int poll_interval_ms,
                std::shared_ptr<DeviceSlot> slot, std::shared_ptr<ControllerPort> port = nullptr,
                std::shared_ptr<SimulatedClock> clock = nullptr);
  ~ModbusSampler() override { stop(); }
  [[nodiscard]] bool watched() const noexcept override { return false; }
  bool bring_up(std::string* why) override;
  void start(const RealtimeOptions& rt) override;
  void stop() override;
  [[nodiscard]] DeviceSlot& slot() noexcept override { return *slot_; }

 private:
  void run() noexcept;
  std::unique_ptr<hal::modbus::ModbusController> controller_;
  int poll_interval_ms_;
  std::shared_ptr<DeviceSlot> slot_;
  std::shared_ptr<ControllerPort> port_;
  std::shared_ptr<SimulatedClock> clock_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// SCHED_FIFO at `priority` and/or affinity for the calling thread; false + why when refused.
bool apply_realtime(const RealtimeOptions& rt, std::string* why);

}  // namespace inertia::daq
