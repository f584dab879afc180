#pragma once
// A simulated bench (backend = "sim") standing behind the real wires (docs/design.md):
// the bench physics of hal/sim is computed for the whole test plan, then a driver thread plays
// it in simulated time into
//   * one CAN bus "accel": every accelerometer channel (sensors under test, monitors, the
//     control accelerometer) as int32 signals in CAN FD frames (16 per frame, little-endian,
//     signed, scale 1e-6 SI/count), plus "sample_index" (uint32, the simulated sample number,
//     as ADC modules carry a frame counter), through a SOCK_SEQPACKET socketpair into the real
//     CanDevice;
//   * one encoder device per [linear_encoder]/[table_encoder], by its `wire`:
//     - gpio: x4 quadrature edges of the simulated position and a trigger-line edge on every
//       sample tick (the bench's sample clock), as gpioevent_data records through pipes into
//       the real GpiodEncoderDevice;
//     - can: the count latched on every sample tick, as a CAN encoder's process data object
//       sends it (frame id 0x180 + node, int64 count and uint32 sample_index), on a bus of its
//       own (a socketpair) into a real CanDevice with channels count, position, sample_index;
//   * the bench controllers (thermal fixture, table, shaker status) on a loopback Modbus TCP
//     server, polled by the real ModbusController/ModbusLink.
// Paced (sample n written at t0 + n / rate) or as fast as the readers take it (blocking CAN
// writes give back-pressure); the timestamps in the published blocks are the same either way.
#include <linux/can.h>
#include <linux/gpio.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/config/bench_config.hpp"
#include "daq/publisher.hpp"
#include "daq/sampler.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/unique_fd.hpp"
#include "hal/wire_sim/bench_controllers.hpp"
#include "hal/wire_sim/encoder_wire.hpp"

namespace inertia::daq {

/// Faults the simulator injects (from --fault on the command line; times in simulated seconds).
struct SimFaults {
  double bus_off_at_s = -1.0, bus_off_s = 0.0;         // CAN: error frame BUSOFF, silence, RESTARTED
  double modbus_gone_at_s = -1.0, modbus_gone_s = 0.0; // Modbus server stopped, then restarted
  std::size_t glitch_every = 0;                        // encoder: a duplicate edge after every n-th edge
  double stuck_at_s = -1.0, stuck_s = 0.0;             // CAN: the first sensor's value frozen
  double nan_at_s = -1.0, nan_s = 0.0;                 // CAN: the first sensor sends "no valid reading"
  double hang_at_s = -1.0, hang_s = 0.0;               // the CAN sampling thread hangs (watchdog test)
  // Real hardware's failure modes, on the CAN bus's frames (they need [bench.sim_timing]: the
  // frames then carry a counter). One each at the sample due at that time.
  double can_reset_at_s = -1.0, can_reset_s = 0.0;     // the adapter resets: silent, then counts from 0
  double short_frame_at_s = -1.0;                      // a frame cut short before its counter
  double duplicate_frame_at_s = -1.0;                  // a frame sent twice
  double swapped_frames_at_s = -1.0;                   // a frame sent after the next one
  // GPIO encoders: line A's kernel FIFO overflows, so many of its edges from that time on never
  // reach the reader (the line itself, and so its level, moves on).
  double gpio_overflow_at_s = -1.0;
  std::size_t gpio_overflow_edges = 0;
};

struct SimOptions {
  bool fast = false;            // as fast as possible instead of paced in real time
  double duration_s = 0.0;      // simulated seconds; <= 0: the plan once. Longer: the plan repeats.
  SimFaults faults;
  int modbus_poll_ms = 100;
  // > 0: a paced driver thread runs SCHED_FIFO one above the sampling threads, as the bench's
  // hardware keeps its clock whatever the PC does (the daemon's --fifo-priority).
  int fifo_priority = 0;
};

/// Identical values in a row that mark a simulated accelerometer channel stuck (10 ms at 10 kHz;
/// with noise far above the 1e-6 ADC step, a repeat of even 3 happens with negligible chance).
inline constexpr std::uint32_t kSimStuckSamples = 100;
/// Scale of the simulated CAN ADC (SI per count): the decoded value is within half of it.
inline constexpr double kSimCanScale = 1e-6;
/// What the simulated ADC sends for a reading it does not have (a sensor output of NaN): the
/// most negative int32, as CAN ADC modules mark "not available"; real readings never use it.
inline constexpr std::uint32_t kSimCanNoReading = 0x80000000u;
/// Frame id of the first simulated CAN FD frame (the next ones follow).
inline constexpr std::uint32_t kSimCanBaseId = 0x100;

class SimBench {
 public:
  /// Simulates the plan and builds the wires and the devices (not yet configured). Throws
  /// InputError for bad truth parameters; nullptr + why when a wire cannot be built.
  static std::unique_ptr<SimBench> create(const config::BenchConfig& bench, const SimOptions& options,
                                          std::size_t ring_capacity, std::string* why);
  ~SimBench();

  /// The samplers of the simulated devices, with their (unconfigured) devices. Once.
  std::vector<std::unique_ptr<Sampler>> take_samplers() { return std::move(samplers_); }
  /// Configures and activates every device; false + why naming the device.
  /// (Called by the daemon through the samplers it owns; kept here because the sim owns the wires.)

  /// Starts the driver at simulated time 0 = t0_ns (CLOCK_MONOTONIC). Marks go to `marks`.
  void start(std::int64_t t0_ns, SpscRing<PlanMark>* marks);
  /// Stops the driver: no sample, edge or controller state is written after it. The simulated
  /// Modbus servers keep answering until stop_servers(), so a controller's sampler stopped after
  /// the driver sees its server as a real bench's would be, not gone.
  void stop();
  /// Stops the simulated Modbus servers (after the samplers that poll them).
  void stop_servers();
  [[nodiscard]] bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }
  [[nodiscard]] std::uint64_t samples_written() const noexcept { return written_.load(std::memory_order_relaxed); }

  /// Samples in one pass of the plan / in this run.
  [[nodiscard]] std::size_t plan_samples() const noexcept { return case_begin_.back(); }
  [[nodiscard]] std::size_t run_samples() const noexcept { return run_samples_; }
  /// CAN frames the simulated bus lost on purpose ([bench.sim_timing] frame_loss), after stop().
  [[nodiscard]] std::uint64_t frames_lost() const noexcept { return frames_lost_; }
  [[nodiscard]] bool real_timing() const noexcept { return real_timing_; }
  /// Paced runs, after stop(): how far behind its schedule the simulator stayed for a whole
  /// ClockFit window (0.1 s) at worst (s): per window, the least lateness of its batches (a
  /// batch's send against the time its newest sample was due); the largest of those. A simulated
  /// device is this process's thread, so a host too loaded to run it on time makes the device
  /// itself late. A late moment lifts a few stamps, which the clock fit's floor ignores; a
  /// lateness held through a window lifts its floor point, as a sample clock running slow would,
  /// which a real device (stamped by the kernel on arrival) never does.
  [[nodiscard]] double behind_schedule_s() const noexcept { return static_cast<double>(behind_schedule_ns_) * 1e-9; }
  /// Beyond this, behind_schedule_s() says the run did not simulate its devices' timing: the
  /// clock fit's times move by up to as much, several sample periods at a bench's rates.
  static constexpr double kScheduleToleranceS = 0.005;

 private:
  SimBench(const config::BenchConfig& bench, SimOptions options);
  struct CanChannel {
    std::string name, unit;
    int kind;           // 0 sensor y, 1 monitor, 2 control
    std::size_t index;  // sensor / monitor index
  };
  /// The simulator's end of one simulated CAN bus (a socketpair into a real CanDevice). Frames
  /// are queued and sent a batch at a time: one system call (and one wake-up of the CAN sampling
  /// thread) per batch rather than per frame, which in fast runs cost the simulator more than
  /// computing the bench. The frames keep their order and their bytes.
  struct CanWire {
    struct PendingFrame {
      canfd_frame frame;
      std::size_t size;                   // CAN_MTU or CANFD_MTU
    };
    hal::UniqueFd fd;
    std::vector<PendingFrame> pending;
    void queue(std::uint32_t can_id, const std::uint8_t* data, std::size_t len, bool fd_frame);
    void flush();
    /// The receive chain's latency ([bench.sim_timing] jitter): the pending frames go out at
    /// `release_ns` (never before an earlier batch: the chain keeps their order), sent by
    /// send_due() while the simulator goes on computing the next samples. A simulator that slept
    /// the latency itself would make the device late, as a sample clock running slow.
    void hold_until(std::int64_t release_ns);
    /// Sends the held batches due by `now_ns`; next_release_ns(): the earliest one's time, or
    /// INT64_MAX when none is held.
    void send_due(std::int64_t now_ns);
    [[nodiscard]] std::int64_t next_release_ns() const noexcept;
    /// Sleeps until `deadline_ns`, sending each held batch on the way when it is due.
    void send_held_until(std::int64_t deadline_ns);
    /// Sleeps until every held batch has gone out.
    void send_all_held();

   private:
    struct HeldBatch {
      std::int64_t release_ns;
      std::vector<PendingFrame> frames;
    };
    void send(std::vector<PendingFrame>& frames);
    std::deque<HeldBatch> held_;
    std::vector<std::vector<PendingFrame>> spare_;   // emptied batches' storage, reused
  };
  struct EncoderSim {
    std::unique_ptr<hal::wire_sim::EncoderWire> wire;   // gpio: the edge pipes
    CanWire bus;                                        // can: the counter's frames
    std::uint32_t can_id = 0;
    double resolution;
    bool table;          // table angle, else shaker displacement
    std::int64_t count = 0;  // gpio: where the edges have brought the count; can: the counter's zero
    double offset = 0.0; // keeps the position continuous across cases and plan repeats
    bool trigger_level = false;
    std::size_t edges = 0;
    std::size_t overflowed = 0;   // line A edges dropped so far (gpio-overflow)
    // Records of one sample tick per line, written in PIPE_BUF-sized batches (one syscall for
    // many edges; a pipe write of at most PIPE_BUF bytes is atomic, so records never split).
    std::array<std::vector<gpioevent_data>, hal::gpiod::kEdgeLineCount> pending;
  };
  void run() noexcept;
  double can_value(const CanChannel& ch, std::size_t c, std::size_t k) const;
  double position(const EncoderSim& e, std::size_t c, std::size_t k) const;
  void queue_edge(EncoderSim& e, hal::gpiod::EdgeLine line, bool rising, std::int64_t t_ns);
  /// Writes the queued records; every line is then complete through `through_ns`.
  bool flush_edges(EncoderSim& e, std::int64_t through_ns);
  void update_controllers(std::size_t c, std::size_t k);
  /// Fast runs: before the registers move to simulated time t_ns, the readings due before it are
  /// taken (SimulatedClock). Gives up after 2 s of wall time without one (a poller that is gone).
  void wait_for_readings_before(std::int64_t t_ns);

  const config::BenchConfig& bench_;
  SimOptions options_;
  double rate_hz_;
  sim::BenchSimulation sim_;
  std::vector<std::size_t> case_begin_;   // global sample index of each case's first sample; back() = total
  std::size_t run_samples_ = 0;
  std::vector<CanChannel> can_channels_;
  CanWire can_bus_;                       // the accelerometers' bus "accel"
  // [bench.sim_timing] in a paced run: the real timing path (numbered frames, the daemon's own
  // clock fits); otherwise the simulator's exact clock.
  bool real_timing_ = false;
  std::uint64_t frames_lost_ = 0;         // CAN frames dropped on purpose (frame_loss)
  std::int64_t behind_schedule_ns_ = 0;   // paced: the largest lateness of a batch (behind_schedule_s)
  std::shared_ptr<DeviceSlot> can_slot_;
  std::vector<EncoderSim> encoders_;
  std::unique_ptr<hal::wire_sim::BenchControllerServer> controllers_;
  std::shared_ptr<SimulatedClock> controller_clock_;   // fast runs: the controllers polled on simulated time
  std::vector<std::unique_ptr<Sampler>> samplers_;
  SpscRing<PlanMark>* marks_ = nullptr;
  std::int64_t t0_ns_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false}, finished_{false};
  std::atomic<std::uint64_t> written_{0};
};

}  // namespace inertia::daq
