#pragma once
// The device interface of the HAL (docs/design.md, "The hardware abstraction layer").
// A device produces timestamped samples for named channels. The daemon owns the lifecycle
// (Unconfigured -> Inactive -> Active -> Inactive -> Finalized, plus Failed) and applies the
// transition table; a device only answers each transition with a Step and keeps health counters.
#include <cmath>
#include <cstdint>
#include <ctime>
#include <span>
#include <string>
#include <string_view>
#include <utility>

namespace inertia::hal {

/// Answer of a lifecycle transition: Ok (done), Retry (not now, e.g. link down; state unchanged),
/// Fatal (the device cannot work; the daemon marks it Failed and carries on with the others).
enum class Step { Ok, Retry, Fatal };

/// SampleSink::push's sample_index for a device that does not number its samples.
inline constexpr std::int64_t kNoSampleIndex = -1;

/// SampleSink::push's channel for a mark, not a sample: the device's sample numbers go on in a
/// new segment from sample_index, on a clock not continuous with the one before (a CAN adapter
/// whose frame counter restarted), so a clock fit of the numbers to their stamps starts again
/// there. t_ns: the receive stamp of the segment's first frame; value and valid carry nothing.
/// Pushed before that frame's samples; not a sample (not counted as one).
inline constexpr std::uint32_t kSegmentStart = 0xFFFFFFFFu;

/// Receives samples from read_into(). Implemented by the daemon (ring writer) and by tests.
/// Thread: the device's sampling thread. Real-time: push() must not allocate, lock or block.
class SampleSink {
 public:
  /// channel: index into Device::channel_names(); t_ns: CLOCK_MONOTONIC nanoseconds (the host's
  /// receive stamp, or a kernel edge stamp); valid == false marks a value that could not be
  /// decoded (the value is then meaningless); sample_index: the sample's number on the device's
  /// own clock when the device sends one (a frame counter, unwrapped), so that a lost frame leaves
  /// exactly its samples missing; kNoSampleIndex when it does not.
  /// Returns false when the sample was dropped (full ring); the device counts it in sink_drops.
  virtual bool push(std::uint32_t channel, std::int64_t t_ns, double value, bool valid,
                    std::int64_t sample_index) noexcept = 0;

 protected:
  ~SampleSink() = default;
};

/// Health is numbers, not log lines; published per device in INERTIA_STATUS at 1 Hz.
/// Backends keep their own extra counters (CanStatus, QuadratureCounters, ModbusHealth).
/// Thread: written by the sampling thread; read it there (copy it out with the samples).
struct DeviceHealth {
  std::uint64_t samples = 0;          // pushed and accepted by the sink
  std::uint64_t sink_drops = 0;       // push() returned false (ring full)
  std::uint64_t decode_errors = 0;    // a record matched the map but its content could not be used
  std::uint64_t malformed = 0;        // a record of the wrong size or shape
  std::uint64_t io_errors = 0;        // read/recv failures other than "nothing pending"
  std::uint64_t resyncs = 0;          // the decoder threw state away to recover
  double read_time_max_us = 0.0;      // longest read_into() call
};

class Device {
 public:
  virtual ~Device() = default;
  Device() = default;
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  /// Name from config; channel names "<device>.<signal>". Thread: any. Stable after configure().
  [[nodiscard]] virtual std::string_view name() const noexcept = 0;
  [[nodiscard]] virtual std::span<const std::string> channel_names() const noexcept = 0;

  /// Non-RT (control thread): open, allocate, validate. Everything that allocates happens here.
  virtual Step configure() = 0;
  /// Non-RT: start streaming; stale queued input is discarded.
  virtual Step activate() = 0;
  /// Decodes whatever input is pending and pushes samples into `sink`; returns how many samples
  /// were pushed (0 when nothing is pending or the device is not active).
  /// Thread: this device's sampling thread. Real-time: no allocation, no lock, never blocks
  /// (non-blocking descriptors; a bounded number of records per call). Bad input is counted
  /// in health(), never thrown.
  virtual std::size_t read_into(SampleSink& sink) noexcept = 0;
  /// Non-RT: stop streaming (descriptors stay open; activate() may follow).
  virtual Step deactivate() = 0;

  /// A descriptor that becomes readable when read_into() has work (for poll/epoll), or -1.
  [[nodiscard]] virtual int wait_fd() const noexcept { return -1; }

  [[nodiscard]] const DeviceHealth& health() const noexcept { return health_; }
  /// Why the last transition answered Retry or Fatal (empty after Ok). Non-RT.
  [[nodiscard]] const std::string& last_error() const noexcept { return last_error_; }

 protected:
  Step fail(Step step, std::string why) {
    last_error_ = std::move(why);
    return step;
  }
  Step ok() {
    last_error_.clear();
    return Step::Ok;
  }

  DeviceHealth health_;
  std::string last_error_;
};

/// CLOCK_MONOTONIC now in nanoseconds. Real-time safe (vDSO, no syscall on x86-64/arm64).
/// A duration in seconds as integer nanoseconds (rounded), the unit of every stamp above.
inline std::int64_t seconds_to_ns(double s) noexcept { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

inline std::int64_t monotonic_now_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace inertia::hal
