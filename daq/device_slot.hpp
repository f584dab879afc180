#pragma once
// What a sampling thread and the publisher share for one device: the SPSC ring of samples and
// the device's health counters, published as relaxed atomics so that the status thread can read
// them without a lock (DeviceHealth itself is plain data owned by the sampling thread).
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/spsc_ring.hpp"
#include "daq/doorbell.hpp"

namespace inertia::daq {

/// One sample of one channel in a device's ring. Trivially copyable (SpscRing requirement).
struct RingSample {
  std::int64_t t_ns = 0;        // CLOCK_MONOTONIC
  double value = 0.0;
  std::uint32_t channel = 0;    // index into DeviceSlot::channels
  std::uint32_t valid = 0;      // 1 valid, 0 invalid
  std::int64_t index = -1;      // the sample's number on the device's clock; -1: not numbered
};

/// Faults a device can report (bits), published as short kebab-case codes in device_status_t.
enum FaultBit : std::uint32_t {
  kFaultBusOff = 1u << 0,
  kFaultBusPassive = 1u << 1,
  kFaultModbusGone = 1u << 2,
  kFaultPeerClosed = 1u << 3,
  kFaultGlitches = 1u << 4,
  kFaultMisaligned = 1u << 5,
  kFaultInvalidSamples = 1u << 6,
  kFaultStuck = 1u << 7,
  kFaultSilent = 1u << 8,
  kFaultRealtimeRefused = 1u << 9,   // the sampling thread runs without its SCHED_FIFO or CPU pin
  kFaultOutOfRange = 1u << 10,       // readings outside their plausible range arrived in the last status period
  kFaultLinkDown = 1u << 11,         // the CAN interface is gone or down; reopened when it is back
  kFaultEncoderOverflow = 1u << 12,  // edge events were lost in the last status period (decoder resynchronized)
};
std::vector<std::string> fault_names(std::uint32_t bits);

/// Lifecycle states as in device_status_t.
enum class SlotState : std::int8_t { Unconfigured = 0, Inactive = 1, Active = 2, Finalized = 3, Failed = 4 };

struct ChannelInfo {
  std::string name;   // short name within the device, e.g. "acc-a", "count"
  std::string unit;   // SI unit of the values
  std::int32_t id = 0;
};

/// Thread: built on the control thread before any thread starts; afterwards the sampling thread
/// pushes and stores counters, the publisher pops and loads them.
struct DeviceSlot {
  DeviceSlot(std::string device_name, std::vector<ChannelInfo> channel_info, double rate_hz, std::size_t ring_capacity)
      : name(std::move(device_name)), channels(std::move(channel_info)), nominal_rate_hz(rate_hz), ring(ring_capacity) {}

  const std::string name;                  // device name from the bench config
  const std::vector<ChannelInfo> channels;
  const double nominal_rate_hz;            // samples per second per channel
  bool sim_time_base = false;              // block times from the simulated clock (see publisher)
  int time_index_channel = -1;             // with sim_time_base: a channel holding the sample number
  // Per channel: repeating exactly the same value this many samples in a row is stuck: from then
  // on its samples are marked invalid until the value moves (0 or no entry: off; only for
  // channels that always carry noise, e.g. accelerometers digitised below their noise floor).
  std::vector<std::uint32_t> stuck_samples;
  // The device's fixed receive latency (bench file latency_floor_ns): subtracted from its stamps
  // before its clock fit, which cannot observe a constant delay (clock_fit.hpp).
  std::int64_t latency_floor_ns = 0;
  // No sample for this long is the fault "silent" (the publisher watches; 0: not watched).
  std::int64_t silent_timeout_ns = 0;
  // Fast simulated runs only: the sampling thread waits for room in the ring instead of dropping,
  // which backs up into the wire and paces the simulator (a bench that waits for the reader).
  // Never on real devices: their hot path counts a full ring as a drop and never waits.
  bool backpressure = false;
  SpscRing<RingSample> ring;
  // Rung by the sampling thread after it pushed samples (set by the publisher; null: nobody waits).
  std::shared_ptr<Doorbell> doorbell;

  // Written by the sampling thread (relaxed: counters, read for status only).
  std::atomic<std::uint64_t> samples{0};
  std::atomic<std::uint64_t> ring_drops{0};
  std::atomic<std::uint64_t> decode_errors{0};
  std::atomic<std::uint64_t> resyncs{0};
  std::atomic<std::uint64_t> invalid_samples{0};
  std::atomic<std::uint64_t> glitches{0};
  std::atomic<std::uint64_t> read_time_max_ns{0};
  // Real hardware's failure modes, as device_status_t names them (the backends' own counters).
  std::atomic<std::uint64_t> counter_resets{0};
  std::atomic<std::uint64_t> short_frames{0};
  std::atomic<std::uint64_t> duplicate_frames{0};
  std::atomic<std::uint64_t> out_of_order_frames{0};
  std::atomic<std::uint64_t> kernel_drops{0};
  std::atomic<std::uint64_t> link_reopens{0};
  std::atomic<std::uint64_t> clock_steps{0};
  std::atomic<std::uint64_t> range_faults{0};
  std::atomic<std::uint64_t> encoder_overflows{0};
  std::atomic<std::uint32_t> faults{0};
  std::atomic<std::uint64_t> heartbeat{0};  // +1 per loop: the supervisor's proof of life
  std::atomic<std::int8_t> state{static_cast<std::int8_t>(SlotState::Unconfigured)};
  std::atomic<bool> finished{false};        // the sampling thread drained and left
  // Set while the sampling thread waits in poll() with nothing pending (read by the simulator's
  // encoder handshake, see sim_bench.cpp).
  std::atomic<bool> idle{false};
  // Fault injection (sim fault sampler-hang): the sampling thread sleeps until this CLOCK_MONOTONIC
  // time, as a thread stuck in a driver would, so the watchdog logic can be tested. 0: none.
  std::atomic<std::int64_t> hang_until_ns{0};

  // Written by the publisher only.
  std::uint64_t blocks = 0;
  std::uint64_t misaligned = 0;             // samples a channel got ahead of its siblings by > buffer
  std::uint32_t ring_high_water = 0;
  std::uint64_t stuck_invalid = 0;          // samples marked invalid as stuck
};

}  // namespace inertia::daq
