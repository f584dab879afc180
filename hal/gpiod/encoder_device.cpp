#include "hal/gpiod/encoder_device.hpp"

#include <fcntl.h>
#include <glob.h>
#include <linux/gpio.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

namespace inertia::hal::gpiod {
namespace {

constexpr const char* kConsumer = "inertia-daqd";

/// Up to `max` (<= GpiodEncoderDevice::kEventsPerRead) line events from a v1 line-event
/// descriptor in one read(2), with libgpiod's reading of a record (id RISING_EDGE: rising, any
/// other: falling) but the stamp kept in ns: libgpiod's timespec would be split here and joined
/// again for every edge. -1 with errno as read(2) set it, or EIO when the bytes are not whole
/// records (libgpiod's check).
int read_line_events(int fd, EdgeLine line, EdgeEvent* out, std::size_t max) noexcept {
  std::array<gpioevent_data, GpiodEncoderDevice::kEventsPerRead> raw;
  const std::size_t want = std::min(max, raw.size());
  const ssize_t got = ::read(fd, raw.data(), want * sizeof(gpioevent_data));
  if (got < 0) return -1;
  if (got % static_cast<ssize_t>(sizeof(gpioevent_data)) != 0) {
    errno = EIO;
    return -1;
  }
  const auto n = static_cast<std::size_t>(got) / sizeof(gpioevent_data);
  for (std::size_t i = 0; i < n; ++i) {
    out[i].line = line;
    out[i].rising = raw[i].id == GPIOEVENT_EVENT_RISING_EDGE;
    out[i].t_ns = static_cast<std::int64_t>(raw[i].timestamp);
  }
  return static_cast<int>(n);
}

bool any_gpiochip() {
  glob_t g{};
  const bool found = ::glob("/dev/gpiochip*", 0, nullptr, &g) == 0 && g.gl_pathc > 0;
  ::globfree(&g);
  return found;
}

}  // namespace

bool QuadratureConfig::is_valid(std::string* why) const {
  auto fail = [&](const std::string& what) {
    if (why) *why = "encoder '" + name + "': " + what;
    return false;
  };
  if (name.empty()) return fail("empty name");
  if (line_a == line_b) return fail("line_a and line_b are the same line");
  if (line_marker >= 0 && (static_cast<unsigned>(line_marker) == line_a || static_cast<unsigned>(line_marker) == line_b))
    return fail("line_marker repeats an A/B line");
  if (line_trigger >= 0 && (static_cast<unsigned>(line_trigger) == line_a ||
                            static_cast<unsigned>(line_trigger) == line_b || line_trigger == line_marker))
    return fail("line_trigger repeats another line");
  if (!std::isfinite(resolution) || resolution <= 0.0) return fail("resolution must be positive (SI per count)");
  if (min_edge_interval_ns < 0 || simultaneous_ns < 0 || edge_latency_ns < 0) return fail("intervals must not be negative");
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz < 0.0) return fail("sample_rate_hz must be >= 0");
  return true;
}

// --- libgpiod v1 source ---------------------------------------------------------------------

std::unique_ptr<GpiodEdgeSource> GpiodEdgeSource::open(const QuadratureConfig& config, std::string* why) {
  if (!config.is_valid(why)) return nullptr;
  gpiod_chip* chip = ::gpiod_chip_open_lookup(config.chip.c_str());
  if (chip == nullptr) {
    if (why) {
      *why = "cannot open GPIO chip '" + config.chip + "': " + std::strerror(errno);
      if (!any_gpiochip()) *why += " (no /dev/gpiochip* on this machine: the kernel has no GPIO support)";
    }
    return nullptr;
  }
  std::unique_ptr<GpiodEdgeSource> source(new GpiodEdgeSource(chip, config.edge_latency_ns));
  const int offsets[kEdgeLineCount] = {static_cast<int>(config.line_a), static_cast<int>(config.line_b),
                                       config.line_marker, config.line_trigger};
  const int flags = config.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
    if (offsets[i] < 0) continue;
    gpiod_line* line = ::gpiod_chip_get_line(chip, static_cast<unsigned>(offsets[i]));
    if (line == nullptr || ::gpiod_line_request_both_edges_events_flags(line, kConsumer, flags) != 0) {
      if (why) *why = "GPIO chip '" + config.chip + "' line " + std::to_string(offsets[i]) +
                      ": cannot request both-edge events: " + std::strerror(errno);
      return nullptr;
    }
    source->lines_[i] = line;
  }
  return source;
}

GpiodEdgeSource::~GpiodEdgeSource() { ::gpiod_chip_close(chip_); }

int GpiodEdgeSource::event_fd(EdgeLine line) const noexcept {
  gpiod_line* l = lines_[static_cast<std::size_t>(line)];
  return l == nullptr ? -1 : ::gpiod_line_event_get_fd(l);
}

bool GpiodEdgeSource::level(EdgeLine line) const noexcept {
  gpiod_line* l = lines_[static_cast<std::size_t>(line)];
  return l != nullptr && ::gpiod_line_get_value(l) == 1;
}

std::int64_t GpiodEdgeSource::complete_through_ns(EdgeLine) const noexcept {
  return monotonic_now_ns() - latency_ns_;
}

// --- device ---------------------------------------------------------------------------------

std::unique_ptr<GpiodEncoderDevice> GpiodEncoderDevice::open(const QuadratureConfig& config, std::string* why) {
  auto source = GpiodEdgeSource::open(config, why);
  if (!source) return nullptr;
  return from_source(std::move(source), config, why);
}

std::unique_ptr<GpiodEncoderDevice> GpiodEncoderDevice::from_source(std::unique_ptr<EdgeSource> source,
                                                                    const QuadratureConfig& config,
                                                                    std::string* why) {
  if (!config.is_valid(why)) return nullptr;
  if (!source || source->event_fd(EdgeLine::A) < 0 || source->event_fd(EdgeLine::B) < 0) {
    if (why) *why = "encoder '" + config.name + "': the edge source has no A/B event descriptors";
    return nullptr;
  }
  std::unique_ptr<GpiodEncoderDevice> device(new GpiodEncoderDevice(std::move(source), config));
  if (device->ticked()) {
    // Created here so that the poll loop can be given it before configure() arms it.
    device->tick_timer_ = UniqueFd(::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC));
    if (!device->tick_timer_.valid()) {
      if (why) *why = "encoder '" + config.name + "': timerfd_create: " + std::strerror(errno);
      return nullptr;
    }
  }
  return device;
}

GpiodEncoderDevice::GpiodEncoderDevice(std::unique_ptr<EdgeSource> source, QuadratureConfig config)
    : source_(std::move(source)),
      config_(std::move(config)),
      decoder_(config_.min_edge_interval_ns, config_.simultaneous_ns) {
  channels_ = {config_.name + ".count", config_.name + ".position"};
  if (source_->event_fd(EdgeLine::Marker) >= 0) {
    marker_channel_ = static_cast<int>(channels_.size());
    channels_.push_back(config_.name + ".marker");
  }
  if (source_->event_fd(EdgeLine::Trigger) >= 0) {
    trigger_channel_ = static_cast<int>(channels_.size());
    channels_.push_back(config_.name + ".trigger");
  }
  if (trigger_channel_ < 0 && config_.sample_rate_hz > 0.0) tick_period_ns_ = 1e9 / config_.sample_rate_hz;
}

Step GpiodEncoderDevice::configure() {
  for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
    const int fd = source_->event_fd(static_cast<EdgeLine>(i));
    if (fd < 0) continue;
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) != 0)
      return fail(Step::Fatal, std::string("fcntl(O_NONBLOCK) on a line event descriptor: ") + std::strerror(errno));
  }
  if (tick_timer_.valid()) {
    itimerspec spec{};
    spec.it_interval.tv_nsec = kTickWakeNs;
    spec.it_value.tv_nsec = kTickWakeNs;
    if (::timerfd_settime(tick_timer_.get(), 0, &spec, nullptr) != 0)
      return fail(Step::Fatal, std::string("timerfd_settime for the encoder's sample ticks: ") + std::strerror(errno));
  }
  decoder_.reset(source_->level(EdgeLine::A), source_->level(EdgeLine::B), 0);
  configured_ = true;
  return ok();
}

void GpiodEncoderDevice::discard_pending() noexcept {
  for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
    buffers_[i] = LineBuffer{};
    const int fd = source_->event_fd(static_cast<EdgeLine>(i));
    if (fd < 0) continue;
    for (int k = 0; k < 10000 && read_line_events(fd, static_cast<EdgeLine>(i), buffers_[i].events.data(), kEventsPerRead) > 0;
         ++k) {
    }
    buffers_[i] = LineBuffer{};
  }
}

Step GpiodEncoderDevice::activate() {
  if (!configured_) return fail(Step::Fatal, "activate() before configure()");
  // Taken before the discard: everything stamped up to here is thrown away with the backlog.
  std::int64_t through = std::numeric_limits<std::int64_t>::max();
  for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
    newest_[i] = kNever;
    watermark_[i] = kNever;
    if (source_->event_fd(static_cast<EdgeLine>(i)) < 0) continue;
    watermark_[i] = source_->complete_through_ns(static_cast<EdgeLine>(i));
    through = std::min(through, watermark_[i]);
  }
  // The first tick after activation: the count before it is not known.
  if (ticked()) next_tick_ = static_cast<std::int64_t>(std::floor(static_cast<double>(through) / tick_period_ns_)) + 1;
  discard_pending();
  decoder_.reset(source_->level(EdgeLine::A), source_->level(EdgeLine::B), decoder_.count());
  ++health_.resyncs;
  active_ = true;
  return ok();
}

Step GpiodEncoderDevice::deactivate() {
  active_ = false;
  return ok();
}

EncoderStatus GpiodEncoderDevice::status() const noexcept {
  EncoderStatus s;
  s.quadrature = decoder_.counters();
  s.markers = markers_;
  s.triggers = triggers_;
  s.overflows = overflows_;
  s.count = decoder_.count();
  return s;
}

bool GpiodEncoderDevice::push(std::uint32_t channel, std::int64_t t_ns, double value, SampleSink& sink) noexcept {
  // While edges are known lost and the levels not yet taken, the count is not the encoder's.
  if (sink.push(channel, t_ns, value, !unsynced_, kNoSampleIndex)) {
    ++health_.samples;
    return true;
  }
  ++health_.sink_drops;
  return false;
}

std::size_t GpiodEncoderDevice::handle(const EdgeEvent& event, SampleSink& sink) noexcept {
  const std::int64_t t_ns = event.t_ns;
  const bool rising = event.rising;
  const EdgeLine line = event.line;
  std::size_t pushed = 0;
  switch (line) {
    case EdgeLine::A:
    case EdgeLine::B: {
      const std::int64_t before = decoder_.count();
      if (decoder_.on_edge(line, rising, t_ns) == QuadratureDecoder::Outcome::Lost) {
        if (!unsynced_) ++overflows_;
        unsynced_ = true;
        want_levels();
      }
      if (decoder_.count() != before && !ticked()) {
        pushed += push(kCountChannel, t_ns, static_cast<double>(decoder_.count()), sink);
        pushed += push(kPositionChannel, t_ns, position(), sink);
      }
      break;
    }
    case EdgeLine::Marker:
      if (rising) {
        ++markers_;
        pushed += push(static_cast<std::uint32_t>(marker_channel_), t_ns, position(), sink);
      }
      break;
    case EdgeLine::Trigger:
      ++triggers_;
      pushed += push(static_cast<std::uint32_t>(trigger_channel_), t_ns, rising ? 1.0 : 0.0, sink);
      break;
  }
  return pushed;
}

void GpiodEncoderDevice::want_levels() noexcept {
  if (resync_pending_) return;
  levels_wanted_ = true;
  const LineLevels l = source_->levels();
  if (merged_ns_ != kNever && l.t_ns < merged_ns_) return;   // older than what was merged: ask again later
  resync_ = l;
  resync_pending_ = true;
  levels_wanted_ = false;
}

void GpiodEncoderDevice::resync_through(std::int64_t t_ns) noexcept {
  if (levels_wanted_) want_levels();
  if (!resync_pending_ || t_ns < resync_.t_ns) return;
  // Every edge up to the levels' time is merged: the decoder's state must be theirs.
  resync_pending_ = false;
  if (decoder_.level(EdgeLine::A) != resync_.a || decoder_.level(EdgeLine::B) != resync_.b) {
    if (!unsynced_) ++overflows_;   // lost edges that left no contradiction behind
    decoder_.resync(resync_.a, resync_.b);
    ++health_.resyncs;
  }
  unsynced_ = false;
  next_level_check_ns_ = resync_.t_ns + kLevelCheckNs;
}

bool GpiodEncoderDevice::emit_ticks(std::int64_t through, bool strict, SampleSink& sink, std::size_t& pushed,
                                    std::size_t& budget) noexcept {
  for (;;) {
    const std::int64_t t = tick_time_ns(next_tick_);
    if (strict ? t >= through : t > through) return true;
    if (budget == 0) return false;
    --budget;
    // Zero-order hold: the count after the last edge stamped at or before the tick.
    pushed += push(kCountChannel, t, static_cast<double>(decoder_.count()), sink);
    pushed += push(kPositionChannel, t, position(), sink);
    ++next_tick_;
  }
}

std::size_t GpiodEncoderDevice::read_into(SampleSink& sink) noexcept {
  if (!active_) return 0;
  const std::int64_t t_start = monotonic_now_ns();
  std::size_t pushed = 0;
  std::size_t tick_budget = kMaxTicksPerRead;
  if (tick_timer_.valid()) {
    std::uint64_t expirations = 0;  // only the wake-up matters; the ticks come from the clock
    (void)!::read(tick_timer_.get(), &expirations, sizeof expirations);
  }
  for (std::size_t round = 0; round < kMaxRoundsPerRead; ++round) {
    bool read_any = false;
    for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
      LineBuffer& buf = buffers_[i];
      const auto line = static_cast<EdgeLine>(i);
      const int fd = source_->event_fd(line);
      if (fd < 0 || buf.head < buf.size) continue;
      const std::int64_t through = source_->complete_through_ns(line);  // before the read, see header
      const int n = read_line_events(fd, line, buf.events.data(), kEventsPerRead);
      buf.head = 0;
      buf.size = n > 0 ? static_cast<std::size_t>(n) : 0;
      if (n > 0) {
        read_any = true;
        newest_[i] = std::max(newest_[i], buf.events[buf.size - 1].t_ns);
      }
      if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        // EIO: fewer bytes than one record (libgpiod's check); anything else is the descriptor.
        if (errno == EIO) ++health_.malformed;
        else ++health_.io_errors;
      }
      // A full batch may leave later events in the descriptor: known only through its newest.
      const std::int64_t known = buf.size == kEventsPerRead ? newest_[i] : std::max(newest_[i], through);
      watermark_[i] = std::max(watermark_[i], known);
    }
    std::int64_t horizon = std::numeric_limits<std::int64_t>::max();
    for (std::size_t i = 0; i < kEdgeLineCount; ++i)
      if (source_->event_fd(static_cast<EdgeLine>(i)) >= 0) horizon = std::min(horizon, watermark_[i]);
    bool handled_any = false, out_of_ticks = false;
    for (;;) {
      std::size_t best = kEdgeLineCount;
      std::int64_t best_t = horizon;
      for (std::size_t i = 0; i < kEdgeLineCount; ++i) {
        const LineBuffer& buf = buffers_[i];
        if (buf.head >= buf.size) continue;
        const std::int64_t t = buf.events[buf.head].t_ns;
        if (t <= best_t && (best == kEdgeLineCount || t < best_t)) {
          best = i;
          best_t = t;
        }
      }
      // A level check is due, or levels asked for apply, before the next event (or by the horizon).
      const std::int64_t next_t = best == kEdgeLineCount ? horizon : best_t;
      if (next_level_check_ns_ != kNever && next_t >= next_level_check_ns_ && !resync_pending_ && !levels_wanted_) want_levels();
      // Every edge at or before the levels' time is merged once the next one is later, or, with
      // none left, once the horizon (all edges known) has reached it.
      if (resync_pending_ && (best == kEdgeLineCount ? horizon >= resync_.t_ns : best_t > resync_.t_ns)) {
        if (ticked() && !emit_ticks(resync_.t_ns, false, sink, pushed, tick_budget)) {
          out_of_ticks = true;
          break;
        }
        resync_through(resync_.t_ns);
      } else if (levels_wanted_) {
        want_levels();
      }
      if (best == kEdgeLineCount) break;
      if (ticked() && !emit_ticks(best_t, true, sink, pushed, tick_budget)) {
        out_of_ticks = true;
        break;
      }
      LineBuffer& buf = buffers_[best];
      pushed += handle(buf.events[buf.head], sink);
      merged_ns_ = buf.events[buf.head].t_ns;
      if (next_level_check_ns_ == kNever) next_level_check_ns_ = merged_ns_ + kLevelCheckNs;
      ++buf.head;
      handled_any = true;
    }
    if (ticked() && !out_of_ticks) out_of_ticks = !emit_ticks(horizon, false, sink, pushed, tick_budget);
    if (out_of_ticks || (!read_any && !handled_any)) break;
  }
  const double us = static_cast<double>(monotonic_now_ns() - t_start) * 1e-3;
  if (us > health_.read_time_max_us) health_.read_time_max_us = us;
  return pushed;
}

}  // namespace inertia::hal::gpiod
