#pragma once
// The publisher thread: drains every device's ring, packs sample_block_t blocks (fixed length,
// per-channel sequence numbers, validity bitmap) onto INERTIA_RAW_<DEVICE>, test-plan markers
// onto INERTIA_EVENT and health onto INERTIA_STATUS at 1 Hz, and hands every message it sends to
// the log writer's queue (the same bytes, so the log is exactly what went on the wire).
//
// Thread: start()/stop() on the control thread; everything else on the publisher thread.
// Not real-time itself, but it allocates nothing per block after start (blocks are shaped once
// and encoded into one reused buffer); the status message allocates once a second.
#include <lcm/lcm-cpp.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/lcm/channels.hpp"
#include "common/spsc_ring.hpp"
#include "daq/clock_fit.hpp"
#include "daq/device_slot.hpp"
#include "daq/log_writer.hpp"
#include "daq/sampler.hpp"
#include "inertia/daq_status_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::daq {

/// A test-plan marker from the simulator (or a plan runner). Trivially copyable for the ring.
struct PlanMark {
  std::int64_t t_ns = 0;          // CLOCK_MONOTONIC (simulated time base)
  std::int64_t start_ns = 0, end_ns = 0;
  std::int32_t case_index = 0;
  std::int32_t phase_index = 0;
  std::int8_t mark = 0;           // plan_event_t::MARK_*
};

struct PublisherOptions {
  double block_s = 0.01;                 // block length in time; samples = round(block_s * rate), >= 1
  double status_period_s = 1.0;
  std::int64_t sim_t0_ns = 0;            // simulated time origin for slots with sim_time_base
  std::int64_t mono_to_wall_ns = 0;      // wall - monotonic, once at start (t0_utime)
  /// Fills case/phase names and setpoints of a marker. Publisher thread.
  std::function<void(const PlanMark&, plan_event_t&)> describe_mark;
  /// An encoded bench_config_t, sent on INERTIA_BENCH at start and every bench_period_s (so a
  /// late subscriber or lcm-logger gets the bench); empty: none.
  std::vector<std::uint8_t> bench_message;
  double bench_period_s = channels::kBenchResendPeriodS;
  /// Fast simulated runs: wait for room in the log queue instead of losing messages (the
  /// samplers then wait for ring room, and the simulator for them), so "as fast as possible"
  /// means as fast as the disk, with nothing lost. Never for real devices.
  bool log_backpressure = false;
  /// Daemon-wide faults for the status (e.g. "lcm-no-route"). Publisher thread.
  std::function<std::vector<std::string>()> daemon_faults;
  /// Operator requests accepted, refused and unsigned so far (INERTIA_STATUS); none: zeros.
  std::function<std::array<std::int64_t, 3>()> command_counts;
};

/// An accepted operator request (plan_command_t, LCM-encoded) for INERTIA_OPERATOR, published and
/// logged just before the markers it causes, so a log says who marked it. Fixed size: the ring
/// holds trivially copyable slots.
struct OperatorRecord {
  std::uint16_t size = 0;
  std::array<std::uint8_t, 4096> bytes{};
};

/// The LCM channel of a device's blocks (common/lcm/channels.hpp): "acc-a" -> INERTIA_RAW_ACC_A.
using channels::raw_channel;

class Publisher {
 public:
  Publisher(lcm::LCM& lcm, LogWriter* log, std::vector<std::shared_ptr<DeviceSlot>> slots, PublisherOptions options);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  /// Shapes blocks; false + why when a device's block cannot fit one datagram. Control thread.
  bool configure(std::string* why);
  /// With rt.fifo_priority > 0 the publisher thread runs SCHED_FIFO one below the sampling
  /// threads (it is on the sample-to-LCM path; below them so it never delays a read), with rt.cpu.
  void start(const RealtimeOptions& rt = {});
  /// Drains the rings (call after every sampler has finished), sends partial last blocks and a
  /// final status, then joins. Control thread.
  void stop();

  /// Producer side for plan markers (one producer thread: the simulator, or the test executive).
  [[nodiscard]] SpscRing<PlanMark>& plan_marks() noexcept { return marks_; }
  /// Producer side for accepted operator requests (one producer thread: the test executive).
  [[nodiscard]] SpscRing<OperatorRecord>& operator_records() noexcept { return operator_records_; }

  [[nodiscard]] std::uint64_t messages() const noexcept { return messages_.load(std::memory_order_relaxed); }
  /// +1 per loop turn (at least every 1 ms while it runs): the supervisor's proof of its life.
  [[nodiscard]] std::uint64_t heartbeat() const noexcept { return heartbeat_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t publish_failures() const noexcept { return failures_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::int32_t block_samples(std::size_t device) const { return packers_.at(device).block_len; }
  /// After stop(): a line per device timed by its own clock (clock_fit.hpp): its drift, the
  /// floor's residual, the largest correction slewed in, samples lost and late.
  [[nodiscard]] std::vector<std::string> clock_report() const;

 private:
  struct Packer {
    std::shared_ptr<DeviceSlot> slot;
    std::string channel;
    std::int32_t block_len = 1;
    std::size_t capacity = 0;
    std::vector<std::vector<double>> values;
    std::vector<std::vector<std::uint8_t>> valid;
    std::vector<std::int64_t> t_first;   // channel 0's timestamps
    std::vector<std::size_t> fill;
    sample_block_t block;
    std::int64_t seq = 0;
    std::vector<std::int64_t> channel_seq;
    std::uint64_t status_samples = 0;    // for the measured rate
    std::uint64_t heard_samples = 0;     // the slot's sample count when it last moved ...
    std::int64_t heard_ns = 0;           // ... and when (the silent-device watch)
    std::vector<double> last_value;      // stuck detection: previous value and run length per channel
    std::vector<std::uint32_t> run;
    std::uint32_t stuck_channels = 0;
    // The device's time base (clock_fit.hpp), for devices not on the simulator's exact clock.
    std::optional<ClockFit> clock;
    SlewedTimeBase timebase;             // the fit's times as the blocks carry them (continuous)
    std::int64_t clock_fed = -1;         // newest sample number fed to the fit
    // Numbered samples (a frame counter): slots by sample number, `base` the number of slot 0,
    // blocks aligned to multiples of block_len. A sample whose number is missing when a block of
    // later ones has arrived is lost: its block goes out with it invalid (value NaN).
    bool numbered = false;
    std::int64_t base = -1, newest = -1;
    std::vector<std::vector<std::uint8_t>> present;
    std::vector<std::uint32_t> block_present;   // present samples (all channels) per block of the window
    std::uint64_t lost = 0, late = 0;
    std::uint64_t segments = 0;          // clock segments started after the first (hal::kSegmentStart)
    std::uint64_t status_range_faults = 0, status_overflows = 0;   // counts at the previous status
  };
  void run(RealtimeOptions rt) noexcept;
  std::size_t drain(Packer& p) noexcept;
  void take(Packer& p, const RingSample& s) noexcept;
  void take_numbered(Packer& p, const RingSample& s) noexcept;
  /// The device's numbers go on in a new segment from `first` (hal::kSegmentStart: its counter
  /// restarted): the old segment's samples go out on the old clock, and the fit starts again, so
  /// a restart neither tilts the line nor is slewed into it.
  void start_segment(Packer& p, std::int64_t first) noexcept;
  /// Raises `bit` on the slot while `count` moved since the previous status, clears it once not.
  static void raise_while_counting(DeviceSlot& slot, std::uint32_t bit, std::uint64_t count, std::uint64_t& seen) noexcept;
  void emit(Packer& p, std::int32_t n) noexcept;
  void emit_numbered(Packer& p, std::int32_t n) noexcept;
  void send_block(Packer& p) noexcept;
  void mark_stuck(Packer& p, std::size_t c, std::size_t f) noexcept;
  void publish_status(double dt_s);
  void publish_marks();
  void publish_operator_records();
  void send(const std::string& channel, const void* data, std::size_t size) noexcept;

  lcm::LCM& lcm_;
  LogWriter* log_;
  PublisherOptions options_;
  std::vector<Packer> packers_;
  SpscRing<PlanMark> marks_{1024};
  SpscRing<OperatorRecord> operator_records_{64};
  std::shared_ptr<Doorbell> doorbell_ = std::make_shared<Doorbell>();   // the samplers ring it
  std::vector<std::uint8_t> buffer_;
  std::thread thread_;
  void watch_silence(Packer& p, std::int64_t now_ns) noexcept;
  std::atomic<bool> stop_{false};
  std::atomic<bool> realtime_refused_{false};   // its SCHED_FIFO / CPU pin was refused
  std::atomic<std::uint64_t> messages_{0}, failures_{0};
  std::atomic<std::uint64_t> heartbeat_{0};
  std::int64_t start_ns_ = 0;
};

}  // namespace inertia::daq
