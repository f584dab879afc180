#pragma once
// Quadrature encoder device: both-edge events of lines A and B (plus optional marker and
// trigger lines) decoded x4 into count and position samples.
//
// Events come through an EdgeSource: a descriptor per line that yields the kernel's
// struct gpioevent_data records (gpio uAPI v1). The device reads every descriptor itself, many
// records per read(2), so production (GpiodEdgeSource: libgpiod line requests) and tests (pipes
// fed with gpioevent_data, hal/wire_sim/encoder_wire.hpp) share the whole decoding path; only
// the line request differs.
#include <gpiod.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hal/device.hpp"
#include "hal/gpiod/quadrature_decoder.hpp"
#include "hal/unique_fd.hpp"

namespace inertia::hal::gpiod {

struct QuadratureConfig {
  std::string name = "encoder";          // channels "<name>.count", ".position", ".marker", ".trigger"
  std::string chip = "gpiochip0";        // gpiod_chip_open_lookup(): name, path, label or number
  unsigned line_a = 0;
  unsigned line_b = 1;
  int line_marker = -1;                  // index/reference mark; -1: none
  int line_trigger = -1;                 // external trigger input; -1: none
  bool active_low = false;
  double resolution = 1e-6;              // SI per x4 count: m/count (linear) or rad/count (rotary)
  std::int64_t min_edge_interval_ns = 0; // shorter pulses on one line are glitches (0: off)
  std::int64_t simultaneous_ns = 0;      // A and B edges this close count as a skipped state
  // Without a trigger line: count and position are sampled at this rate on CLOCK_MONOTONIC
  // (ticks at whole multiples of the period) by zero-order hold of the count between edges.
  // 0: a count/position sample at every edge instead. Ignored when line_trigger is set.
  double sample_rate_hz = 0.0;
  // gpiolib stamps an edge in its hard IRQ handler but queues it from the IRQ thread; an edge
  // stamped less than this before a read may not be readable yet. Every merge and every
  // sample tick waits this long behind the clock (libgpiod source only).
  std::int64_t edge_latency_ns = 1'000'000;
  bool is_valid(std::string* why) const;
};

/// The levels of lines A and B and the time (the events' clock) they hold at: every edge
/// stamped at or before t_ns is in them.
struct LineLevels {
  bool a = false, b = false;
  std::int64_t t_ns = 0;
};

/// Where edge events come from. Thread: configure/activate on the control thread; event_fd()
/// is then read by the sampling thread.
class EdgeSource {
 public:
  virtual ~EdgeSource() = default;
  /// Descriptor yielding gpioevent_data records for `line`, or -1 when the line is not used.
  [[nodiscard]] virtual int event_fd(EdgeLine line) const noexcept = 0;
  /// Present level of `line` (seeds the decoder). Real-time safe (one ioctl on a chip).
  [[nodiscard]] virtual bool level(EdgeLine line) const noexcept = 0;
  /// Levels of A and B with their time, for resynchronizing the decoder after lost edges.
  /// Default: the present levels, stamped CLOCK_MONOTONIC before they are read (an edge between
  /// the stamp and the read is in the levels already; the decoder then sees it as a glitch).
  [[nodiscard]] virtual LineLevels levels() const noexcept {
    const std::int64_t t = monotonic_now_ns();
    return LineLevels{level(EdgeLine::A), level(EdgeLine::B), t};
  }
  /// Every event of `line` stamped at or before this time (the events' clock) is already in its
  /// descriptor, or was read from it. The device asks right before it reads the line, so after
  /// a read that emptied the descriptor nothing older can still come. Real-time safe.
  [[nodiscard]] virtual std::int64_t complete_through_ns(EdgeLine line) const noexcept = 0;
};

/// libgpiod v1: one both-edge event request per line on one chip. Non-RT.
class GpiodEdgeSource final : public EdgeSource {
 public:
  /// nullptr with the reason when the chip or a line cannot be opened (on a machine without
  /// /dev/gpiochip*: "cannot open GPIO chip 'gpiochip0': No such file or directory ...").
  static std::unique_ptr<GpiodEdgeSource> open(const QuadratureConfig& config, std::string* why);
  ~GpiodEdgeSource() override;
  [[nodiscard]] int event_fd(EdgeLine line) const noexcept override;
  [[nodiscard]] bool level(EdgeLine line) const noexcept override;
  /// CLOCK_MONOTONIC now minus QuadratureConfig::edge_latency_ns.
  [[nodiscard]] std::int64_t complete_through_ns(EdgeLine line) const noexcept override;

 private:
  GpiodEdgeSource(gpiod_chip* chip, std::int64_t latency_ns) : chip_(chip), latency_ns_(latency_ns) {}
  gpiod_chip* chip_;                      // owned; closing it releases the lines
  std::int64_t latency_ns_;
  std::array<gpiod_line*, kEdgeLineCount> lines_{};
};

struct EncoderStatus {
  QuadratureCounters quadrature;
  std::uint64_t overflows = 0;            // times edges were found lost (a full line FIFO): resynchronized
  std::uint64_t markers = 0;              // marker rising edges
  std::uint64_t triggers = 0;             // trigger edges (both)
  std::int64_t count = 0;
};

class GpiodEncoderDevice final : public Device {
 public:
  /// Records asked for per read(2). A chip's v1 line FIFO holds 16, so there a read returns at
  /// most 16 whatever is asked; a simulated line (a pipe) holds more, and the read syscalls
  /// were the encoder thread's cost in a fast simulated run (libgpiod's
  /// gpiod_line_event_read_fd_multiple() caps at 16): 256 is what the simulator writes at once
  /// (one PIPE_BUF), so a busy line is emptied in one read instead of four at 64.
  static constexpr std::size_t kEventsPerRead = 256;
  static constexpr std::size_t kMaxRoundsPerRead = 8;

  /// Production: opens the chip and requests the lines. nullptr with the reason otherwise.
  static std::unique_ptr<GpiodEncoderDevice> open(const QuadratureConfig& config, std::string* why);
  /// Any edge source (tests, simulator). nullptr with the reason when config is invalid or the
  /// source lacks the A/B descriptors.
  static std::unique_ptr<GpiodEncoderDevice> from_source(std::unique_ptr<EdgeSource> source,
                                                         const QuadratureConfig& config, std::string* why);

  [[nodiscard]] std::string_view name() const noexcept override { return config_.name; }
  [[nodiscard]] std::span<const std::string> channel_names() const noexcept override { return channels_; }
  /// Non-RT: descriptors non-blocking; decoder seeded from the present levels.
  Step configure() override;
  /// Non-RT: discards queued events and re-seeds the decoder from the present levels (edges
  /// while inactive are not tracked; counted as a resync, the count is kept).
  Step activate() override;
  /// Thread: sampling thread. Real-time: no allocation, no lock, non-blocking reads of at most
  /// kEventsPerRead events per line per round, kMaxRoundsPerRead rounds.
  /// The lines are separate descriptors read one after another, so an edge may reach line A's
  /// descriptor after A was read and before a later edge of B is read. Each line therefore has
  /// a watermark, the time through which all its events are known: its newest event read, or,
  /// when a read emptied the descriptor, the source's complete_through_ns() taken before that
  /// read. Events are merged in timestamp order only up to the lowest watermark of all lines;
  /// later ones wait in the line buffers for the next read.
  /// Pushes a marker sample (value: position at the marker's rising edge) and a trigger sample
  /// (value: new level); count and position after each edge that changed the count, or, with
  /// sample_rate_hz and no trigger line, at every tick once the lowest watermark has passed it.
  /// Lost edges (a line FIFO that overflowed: QuadratureDecoder::Outcome::Lost, or line levels
  /// that disagree with the decoder's at a check every kLevelCheckNs) are counted as an overflow;
  /// the decoder takes the lines' levels (EdgeSource::levels()) at their time, merged in order with
  /// the edges, and every sample from the detection to that point is pushed invalid. The count
  /// goes on from there (the steps lost are not known: a constant offset, and a step in it there).
  std::size_t read_into(SampleSink& sink) noexcept override;
  /// How often the decoder's levels are compared with the lines' (events' clock): lost edges
  /// that leave no contradiction behind (an even number on one line) are found within this.
  static constexpr std::int64_t kLevelCheckNs = 100'000'000;
  Step deactivate() override;
  /// Line A's descriptor. Each line has its own (one request per line in libgpiod v1): a poll
  /// loop that waits for edges should wait on all of event_fds().
  [[nodiscard]] int wait_fd() const noexcept override { return source_->event_fd(EdgeLine::A); }
  [[nodiscard]] std::array<int, kEdgeLineCount> event_fds() const noexcept {
    return {source_->event_fd(EdgeLine::A), source_->event_fd(EdgeLine::B), source_->event_fd(EdgeLine::Marker),
            source_->event_fd(EdgeLine::Trigger)};
  }

  [[nodiscard]] EncoderStatus status() const noexcept;
  [[nodiscard]] double position() const noexcept { return static_cast<double>(decoder_.count()) * config_.resolution; }

  static constexpr std::uint32_t kCountChannel = 0;
  static constexpr std::uint32_t kPositionChannel = 1;
  /// Channel of the marker / trigger samples, or -1 when the line is not configured.
  [[nodiscard]] int marker_channel() const noexcept { return marker_channel_; }
  [[nodiscard]] int trigger_channel() const noexcept { return trigger_channel_; }
  /// Whether count and position are sampled on ticks of sample_rate_hz (no trigger line).
  [[nodiscard]] bool ticked() const noexcept { return tick_period_ns_ > 0.0; }
  /// Ticked: a timerfd, readable every kTickWakeNs once configure() armed it (read_into() consumes it),
  /// for the poll loop to wait on with the line descriptors, so ticks go out on time while the
  /// encoder stands still. -1 otherwise.
  [[nodiscard]] int tick_fd() const noexcept { return tick_timer_.get(); }
  static constexpr std::int64_t kTickWakeNs = 1'000'000;
  /// CLOCK_MONOTONIC time of tick k: round(k / sample_rate_hz), in ns.
  [[nodiscard]] std::int64_t tick_time_ns(std::int64_t k) const noexcept {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(k) * tick_period_ns_));
  }

 private:
  GpiodEncoderDevice(std::unique_ptr<EdgeSource> source, QuadratureConfig config);
  std::size_t handle(const EdgeEvent& event, SampleSink& sink) noexcept;
  bool push(std::uint32_t channel, std::int64_t t_ns, double value, SampleSink& sink) noexcept;
  /// Asks the source for the lines' levels, unless asked already; kept once their time is not
  /// behind what was merged (an older reading would undo edges handled since).
  void want_levels() noexcept;
  /// Merged through `t_ns`: a pending resynchronization due by then is applied.
  void resync_through(std::int64_t t_ns) noexcept;
  void discard_pending() noexcept;
  /// Pushes the rows of ticks at or before `through` (before `before` when strict); false when
  /// the per-call budget ran out first.
  bool emit_ticks(std::int64_t through, bool strict, SampleSink& sink, std::size_t& pushed,
                  std::size_t& budget) noexcept;

  struct LineBuffer {
    std::array<EdgeEvent, kEventsPerRead> events{};
    std::size_t head = 0, size = 0;
  };
  static constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::min();
  // Bounds one read_into() after a long pause (e.g. 20 ms idle wait at 10 kHz is 200 ticks).
  static constexpr std::size_t kMaxTicksPerRead = 1024;

  std::unique_ptr<EdgeSource> source_;
  QuadratureConfig config_;
  QuadratureDecoder decoder_;
  std::vector<std::string> channels_;
  int marker_channel_ = -1;
  int trigger_channel_ = -1;
  bool configured_ = false;
  bool active_ = false;
  std::array<LineBuffer, kEdgeLineCount> buffers_{};
  std::array<std::int64_t, kEdgeLineCount> newest_{};     // newest stamp read per line
  std::array<std::int64_t, kEdgeLineCount> watermark_{};  // see read_into()
  double tick_period_ns_ = 0.0;                           // > 0: ticked (zero-order hold)
  UniqueFd tick_timer_;
  std::int64_t next_tick_ = 0;                            // index of the next tick to emit
  std::uint64_t markers_ = 0, triggers_ = 0;
  // Lost edges: the levels asked for and when they apply; samples are invalid until then.
  bool levels_wanted_ = false, resync_pending_ = false, unsynced_ = false;
  LineLevels resync_{};
  std::int64_t merged_ns_ = kNever;             // the newest event (or tick) handled
  std::int64_t next_level_check_ns_ = kNever;   // kNever: from the first event on
  std::uint64_t overflows_ = 0;
};

}  // namespace inertia::hal::gpiod
