#include "daq/publisher.hpp"

#include <pthread.h>
#include <sys/prctl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>

#include <fmt/format.h>

#include "common/lcm/channels.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "hal/device.hpp"

namespace inertia::daq {

Publisher::Publisher(lcm::LCM& lcm, LogWriter* log, std::vector<std::shared_ptr<DeviceSlot>> slots,
                     PublisherOptions options)
    : lcm_(lcm), log_(log), options_(std::move(options)) {
  for (auto& s : slots) {
    Packer p;
    s->doorbell = doorbell_;
    p.slot = std::move(s);
    packers_.push_back(std::move(p));
  }
}

Publisher::~Publisher() { stop(); }

bool Publisher::configure(std::string* why) {
  std::size_t largest = 0;
  for (Packer& p : packers_) {
    DeviceSlot& slot = *p.slot;
    const auto nch = static_cast<std::int32_t>(slot.channels.size());
    p.channel = channels::raw_channel(slot.name);
    p.block.device = slot.name;
    shape_sample_block(p.block, nch, 1);
    for (std::int32_t c = 0; c < nch; ++c) {
      p.block.channel_ids[static_cast<std::size_t>(c)] = slot.channels[static_cast<std::size_t>(c)].id;
      p.block.channel_names[static_cast<std::size_t>(c)] = slot.channels[static_cast<std::size_t>(c)].name;
      p.block.units[static_cast<std::size_t>(c)] = slot.channels[static_cast<std::size_t>(c)].unit;
    }
    p.block.sample_period_s = slot.nominal_rate_hz > 0 ? 1.0 / slot.nominal_rate_hz : 0.0;
    const std::int32_t max_len = max_samples_per_block(p.block, p.channel);
    if (max_len < 1) {
      if (why) *why = "device " + slot.name + ": not even one sample fits an LCM datagram";
      return false;
    }
    const auto wanted = static_cast<std::int32_t>(std::lround(options_.block_s * slot.nominal_rate_hz));
    p.block_len = std::clamp(wanted, 1, max_len);
    shape_sample_block(p.block, nch, p.block_len);
    // Four blocks of slack per channel: channels of one device arrive interleaved, never far apart.
    p.capacity = static_cast<std::size_t>(p.block_len) * 4;
    p.values.assign(static_cast<std::size_t>(nch), std::vector<double>(p.capacity));
    p.valid.assign(static_cast<std::size_t>(nch), std::vector<std::uint8_t>(p.capacity));
    p.t_first.assign(p.capacity, 0);
    p.fill.assign(static_cast<std::size_t>(nch), 0);
    p.channel_seq.assign(static_cast<std::size_t>(nch), 0);
    p.last_value.assign(static_cast<std::size_t>(nch), std::numeric_limits<double>::quiet_NaN());
    p.run.assign(static_cast<std::size_t>(nch), 0);
    p.present.assign(static_cast<std::size_t>(nch), std::vector<std::uint8_t>(p.capacity, 0));
    p.block_present.assign(p.capacity / static_cast<std::size_t>(p.block_len), 0);
    if (!slot.sim_time_base && slot.nominal_rate_hz > 0) p.clock.emplace(1.0 / slot.nominal_rate_hz);
    largest = std::max(largest, static_cast<std::size_t>(p.block.getEncodedSize()));
  }
  buffer_.resize(std::max<std::size_t>(largest, 1 << 16) * 2);
  return true;
}

void Publisher::start(const RealtimeOptions& rt) {
  start_ns_ = hal::monotonic_now_ns();
  thread_ = std::thread([this, rt] { run(rt); });
}

void Publisher::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void Publisher::send(const std::string& channel, const void* data, std::size_t size) noexcept {
  if (lcm_.publish(channel, data, static_cast<unsigned>(size)) != 0) failures_.fetch_add(1, std::memory_order_relaxed);
  messages_.fetch_add(1, std::memory_order_relaxed);
  if (log_ != nullptr) {
    const std::int64_t utime = (hal::monotonic_now_ns() + options_.mono_to_wall_ns) / 1000;
    // A full queue is counted by the writer.
    if (options_.log_backpressure) (void)log_->enqueue_waiting(channel, data, size, utime, 2'000'000'000);
    else (void)log_->enqueue(channel, data, size, utime);
  }
}

void Publisher::emit(Packer& p, std::int32_t n) noexcept {
  DeviceSlot& slot = *p.slot;
  const auto nch = static_cast<std::int32_t>(slot.channels.size());
  if (p.block.num_samples != n) shape_sample_block(p.block, nch, n);  // only for a last, partial block
  for (std::int32_t c = 0; c < nch; ++c) {
    const auto cc = static_cast<std::size_t>(c);
    std::memcpy(p.block.values[cc].data(), p.values[cc].data(), sizeof(double) * static_cast<std::size_t>(n));
    std::fill(p.block.valid[cc].begin(), p.block.valid[cc].end(), std::uint8_t{0});
    for (std::int32_t s = 0; s < n; ++s)
      if (p.valid[cc][static_cast<std::size_t>(s)] != 0) set_sample_valid(p.block, c, s, true);
    p.block.channel_seq[cc] = p.channel_seq[cc];
    p.channel_seq[cc] += n;
    // Shift what is left (at most three blocks) to the front.
    const std::size_t rest = p.fill[cc] - static_cast<std::size_t>(n);
    std::memmove(p.values[cc].data(), p.values[cc].data() + n, sizeof(double) * rest);
    std::memmove(p.valid[cc].data(), p.valid[cc].data() + n, rest);
    if (c == 0) {
      p.block.t0_mono_ns = p.t_first[0];
      std::memmove(p.t_first.data(), p.t_first.data() + n, sizeof(std::int64_t) * rest);
    }
    p.fill[cc] = rest;
  }
  if (slot.sim_time_base && slot.nominal_rate_hz > 0) {
    // Simulated benches: sample k of the run is at sim_t0 + k / rate whether the simulator ran
    // paced or as fast as possible, so both modes log the same times.
    // A device that carries the sample number (the sim's CAN frame counter) is timed by it, so a
    // gap (bus-off) shows as a jump of time and sample_index, not as shifted samples.
    const double index = slot.time_index_channel >= 0
                             ? p.block.values[static_cast<std::size_t>(slot.time_index_channel)][0]
                             : static_cast<double>(p.block.channel_seq[0]);
    p.block.t0_mono_ns = options_.sim_t0_ns + std::llround(index * 1e9 / slot.nominal_rate_hz);
  } else if (p.clock) {
    // Its own clock: the samples' count mapped to CLOCK_MONOTONIC (clock_fit.hpp).
    const SlewedTimeBase::BlockTime bt = p.timebase.block(*p.clock, p.block.channel_seq[0], n);
    p.block.t0_mono_ns = bt.t0_ns;
    p.block.sample_period_s = bt.period_s;
  }
  send_block(p);
}

void Publisher::emit_numbered(Packer& p, std::int32_t n) noexcept {
  DeviceSlot& slot = *p.slot;
  const auto nch = static_cast<std::int32_t>(slot.channels.size());
  const auto len = static_cast<std::size_t>(p.block_len);
  // A block of which no sample arrived is not sent: the numbers jump (a gap, as for bus-off).
  const bool any = p.block_present[0] > 0;
  if (any) {
    if (p.block.num_samples != n) shape_sample_block(p.block, nch, n);
    for (std::int32_t c = 0; c < nch; ++c) {
      const auto cc = static_cast<std::size_t>(c);
      std::fill(p.block.valid[cc].begin(), p.block.valid[cc].end(), std::uint8_t{0});
      for (std::int32_t s = 0; s < n; ++s) {
        const auto ss = static_cast<std::size_t>(s);
        if (p.present[cc][ss] == 0) {
          p.block.values[cc][ss] = std::numeric_limits<double>::quiet_NaN();
          ++p.lost;
          continue;
        }
        p.block.values[cc][ss] = p.values[cc][ss];
        if (p.valid[cc][ss] != 0) set_sample_valid(p.block, c, s, true);
      }
      p.block.channel_seq[cc] = p.base;   // every channel's sample s of the block is number base + s
    }
    const SlewedTimeBase::BlockTime bt = p.timebase.block(*p.clock, p.base, n);
    p.block.t0_mono_ns = bt.t0_ns;
    p.block.sample_period_s = bt.period_s;
    send_block(p);
  } else if (p.base <= p.newest) {
    // Every sample of it is lost all the same (at 100 Hz a 10 ms block is one frame): counted.
    p.lost += static_cast<std::uint64_t>(n) * static_cast<std::uint64_t>(nch);
  }
  // The window moves on by one block.
  for (std::size_t c = 0; c < static_cast<std::size_t>(nch); ++c) {
    std::memmove(p.values[c].data(), p.values[c].data() + len, sizeof(double) * (p.capacity - len));
    std::memmove(p.valid[c].data(), p.valid[c].data() + len, p.capacity - len);
    std::memmove(p.present[c].data(), p.present[c].data() + len, p.capacity - len);
    std::fill(p.present[c].end() - static_cast<std::ptrdiff_t>(len), p.present[c].end(), std::uint8_t{0});
  }
  std::rotate(p.block_present.begin(), p.block_present.begin() + 1, p.block_present.end());
  p.block_present.back() = 0;
  p.base += p.block_len;
}

void Publisher::send_block(Packer& p) noexcept {
  DeviceSlot& slot = *p.slot;
  const auto nch = static_cast<std::int32_t>(slot.channels.size());
  p.block.t0_utime = (p.block.t0_mono_ns + options_.mono_to_wall_ns) / 1000;
  p.block.seq = p.seq++;
  const int size = p.block.getEncodedSize();
  if (static_cast<std::size_t>(size) > buffer_.size()) buffer_.resize(static_cast<std::size_t>(size));
  if (p.block.encode(buffer_.data(), 0, size) == size) send(p.channel, buffer_.data(), static_cast<std::size_t>(size));
  ++slot.blocks;
  if (p.block.num_samples != p.block_len) shape_sample_block(p.block, nch, p.block_len);
}

void Publisher::mark_stuck(Packer& p, std::size_t c, std::size_t f) noexcept {
  DeviceSlot& slot = *p.slot;
  if (c >= slot.stuck_samples.size() || slot.stuck_samples[c] == 0) return;
  const double v = p.values[c][f];
  const bool was_stuck = p.run[c] >= slot.stuck_samples[c];
  p.run[c] = (v == p.last_value[c]) ? p.run[c] + 1 : 0;
  p.last_value[c] = v;
  const bool stuck = p.run[c] >= slot.stuck_samples[c];
  if (stuck) {
    p.valid[c][f] = 0;  // the log shows exactly which samples were judged stuck
    ++slot.stuck_invalid;
  }
  if (stuck != was_stuck) {
    p.stuck_channels = stuck ? p.stuck_channels + 1 : p.stuck_channels - 1;
    if (p.stuck_channels > 0) {
      slot.faults.fetch_or(kFaultStuck, std::memory_order_relaxed);
    } else {
      slot.faults.fetch_and(~kFaultStuck, std::memory_order_relaxed);
    }
  }
}

void Publisher::start_segment(Packer& p, std::int64_t first) noexcept {
  if (!p.clock) return;
  if (p.numbered) {
    // What the old segment holds goes out now, timed by the old clock, as at the end of a run.
    while (p.base >= 0 && p.newest >= p.base)
      emit_numbered(p, static_cast<std::int32_t>(std::min<std::int64_t>(p.block_len, p.newest - p.base + 1)));
    // The new segment's blocks start at its first number (its numbers go on from the old ones').
    if (p.base >= 0) p.base = first;
    p.newest = -1;
  }
  p.clock.emplace(1.0 / p.slot->nominal_rate_hz);
  p.timebase = SlewedTimeBase{};
  p.clock_fed = first - 1;
  ++p.segments;
}

void Publisher::take(Packer& p, const RingSample& s) noexcept {
  DeviceSlot& slot = *p.slot;
  if (s.channel == hal::kSegmentStart) {
    start_segment(p, s.index);
    return;
  }
  if (s.index >= 0 && p.clock) {
    take_numbered(p, s);
    return;
  }
  const std::size_t c = s.channel;
  if (c >= p.fill.size()) return;
  std::size_t& f = p.fill[c];
  if (f < p.capacity) {
    p.values[c][f] = s.value;
    p.valid[c][f] = static_cast<std::uint8_t>(s.valid);
    mark_stuck(p, c, f);
    if (c == 0) {
      p.t_first[f] = s.t_ns - slot.latency_floor_ns;
      // Without numbers the count of a channel's samples is the device's clock.
      if (p.clock) p.clock->add(p.channel_seq[0] + static_cast<std::int64_t>(f), p.t_first[f]);
    }
    ++f;
    if (f >= static_cast<std::size_t>(p.block_len) &&
        *std::min_element(p.fill.begin(), p.fill.end()) >= static_cast<std::size_t>(p.block_len))
      emit(p, p.block_len);
  } else {
    ++slot.misaligned;
    slot.faults.fetch_or(kFaultMisaligned, std::memory_order_relaxed);
  }
}

void Publisher::take_numbered(Packer& p, const RingSample& s) noexcept {
  DeviceSlot& slot = *p.slot;
  const std::size_t c = s.channel;
  if (c >= p.present.size()) return;
  const std::int64_t len = p.block_len;
  p.numbered = true;
  if (p.base < 0) p.base = s.index - s.index % len;
  const auto window = static_cast<std::int64_t>(p.capacity);
  if (s.index < p.base - window) {
    // Numbers from the start again: the device restarted. What is held goes out; a new clock.
    for (std::size_t b = 0; b < p.block_present.size(); ++b) emit_numbered(p, p.block_len);
    p.base = s.index - s.index % len;
    p.newest = -1;
    p.clock.emplace(1.0 / slot.nominal_rate_hz);
    p.timebase = SlewedTimeBase{};
    p.clock_fed = -1;
  }
  if (s.index < p.base) {
    ++p.late;   // its block has gone out (with it invalid)
    return;
  }
  if (s.index >= p.base + 2 * window) {
    // A jump of more than the window (bus-off, a silent device): what is held goes out, and the
    // window starts at the new number (the gap shows as a jump of numbers and time).
    for (std::size_t b = 0; b < p.block_present.size(); ++b) emit_numbered(p, p.block_len);
    p.base = s.index - s.index % len;
  }
  while (s.index >= p.base + window) emit_numbered(p, p.block_len);
  const auto pos = static_cast<std::size_t>(s.index - p.base);
  if (p.present[c][pos] == 0) {
    p.present[c][pos] = 1;
    ++p.block_present[pos / static_cast<std::size_t>(len)];
  }
  p.values[c][pos] = s.value;
  p.valid[c][pos] = static_cast<std::uint8_t>(s.valid);
  mark_stuck(p, c, pos);
  if (s.index > p.clock_fed) {
    p.clock->add(s.index, s.t_ns - slot.latency_floor_ns);
    p.clock_fed = s.index;
  }
  p.newest = std::max(p.newest, s.index);
  // A block is complete when every channel has every sample, or lost what it lacks once a whole
  // block of later samples has arrived (frames of one sample arrive together, never a block apart).
  const std::uint32_t whole = static_cast<std::uint32_t>(p.present.size()) * static_cast<std::uint32_t>(len);
  while (p.block_present[0] == whole || p.newest >= p.base + 2 * len) emit_numbered(p, p.block_len);
}

std::vector<std::string> Publisher::clock_report() const {
  std::vector<std::string> lines;
  for (const Packer& p : packers_) {
    if (!p.clock || p.clock->points() == 0) continue;
    lines.push_back(fmt::format("{}: clock drift {:+.2f} +- {:.2f} ppm, floor residual {:.1f} us, largest correction slewed in "
                                "{:.1f} us, samples lost {}, late {}, clock segments {}",
                                p.slot->name, p.clock->drift_ppm(), p.clock->drift_sd_ppm(), p.clock->residual_us(),
                                p.timebase.largest_correction_us(), p.lost, p.late, p.segments + 1));
  }
  return lines;
}

std::size_t Publisher::drain(Packer& p) noexcept {
  DeviceSlot& slot = *p.slot;
  const std::size_t occupancy = slot.ring.size_approx();
  if (occupancy > slot.ring_high_water) slot.ring_high_water = static_cast<std::uint32_t>(occupancy);
  // Bounded batches give slots back to the sampler while a long backlog is packed; one ring's
  // worth per call keeps the other devices, markers and the status turning.
  constexpr std::size_t kBatch = 4096;
  std::size_t n = 0;
  while (n < slot.ring.capacity()) {
    const std::size_t got = slot.ring.consume([&](const RingSample& s) { take(p, s); }, kBatch);
    n += got;
    if (got < kBatch) break;
  }
  return n;
}

void Publisher::publish_marks() {
  while (PlanMark* m = marks_.front()) {
    plan_event_t ev{};
    ev.mono_ns = m->t_ns;
    ev.utime = (m->t_ns + options_.mono_to_wall_ns) / 1000;
    ev.mark = m->mark;
    ev.phase_index = m->phase_index;
    ev.start_mono_ns = m->start_ns;
    ev.end_mono_ns = m->end_ns;
    ev.num_setpoints = 0;
    if (options_.describe_mark) options_.describe_mark(*m, ev);
    ev.num_setpoints = static_cast<std::int32_t>(ev.setpoint_names.size());
    marks_.pop();
    const int size = ev.getEncodedSize();
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(size));
    if (ev.encode(buf.data(), 0, size) == size) send(std::string(channels::kEvent), buf.data(), buf.size());
  }
}

void Publisher::publish_operator_records() {
  while (OperatorRecord* r = operator_records_.front()) {
    send(std::string(channels::kOperator), r->bytes.data(), r->size);
    operator_records_.pop();
  }
}

// A device that stopped sending (a pulled cable, a module that hung) raises "silent" once its
// timeout has passed without a sample; the journal and the status channel carry it like any
// fault, and it clears with the next sample.
void Publisher::watch_silence(Packer& p, std::int64_t now_ns) noexcept {
  DeviceSlot& slot = *p.slot;
  if (slot.silent_timeout_ns <= 0) return;
  const std::uint64_t samples = slot.samples.load(std::memory_order_relaxed);
  if (p.heard_ns == 0 || samples != p.heard_samples) {
    p.heard_samples = samples;
    p.heard_ns = now_ns;
    if (samples != 0) slot.faults.fetch_and(~kFaultSilent, std::memory_order_relaxed);
  } else if (now_ns - p.heard_ns > slot.silent_timeout_ns) {
    slot.faults.fetch_or(kFaultSilent, std::memory_order_relaxed);
  }
}

void Publisher::raise_while_counting(DeviceSlot& slot, std::uint32_t bit, std::uint64_t count, std::uint64_t& seen) noexcept {
  if (count != seen) {
    slot.faults.fetch_or(bit, std::memory_order_relaxed);
  } else {
    slot.faults.fetch_and(~bit, std::memory_order_relaxed);
  }
  seen = count;
}

void Publisher::publish_status(double dt_s) {
  daq_status_t st{};
  const std::int64_t now = hal::monotonic_now_ns();
  st.mono_ns = now;
  st.utime = (now + options_.mono_to_wall_ns) / 1000;
  st.uptime_s = static_cast<double>(now - start_ns_) * 1e-9;
  for (Packer& p : packers_) {
    DeviceSlot& s = *p.slot;
    device_status_t d{};
    d.device = s.name;
    d.state = s.state.load(std::memory_order_relaxed);
    const std::uint64_t samples = s.samples.load(std::memory_order_relaxed);
    const double nch = static_cast<double>(std::max<std::size_t>(1, s.channels.size()));
    d.sample_rate_hz = dt_s > 0 ? static_cast<double>(samples - p.status_samples) / nch / dt_s : 0.0;
    p.status_samples = samples;
    d.nominal_rate_hz = s.nominal_rate_hz;
    d.samples = static_cast<std::int64_t>(samples);
    d.blocks = static_cast<std::int64_t>(s.blocks);
    d.ring_drops = static_cast<std::int64_t>(s.ring_drops.load(std::memory_order_relaxed) + s.misaligned);
    d.ring_high_water = static_cast<std::int32_t>(s.ring_high_water);
    d.ring_capacity = static_cast<std::int32_t>(s.ring.capacity());
    d.decode_errors = static_cast<std::int64_t>(s.decode_errors.load(std::memory_order_relaxed));
    d.resyncs = static_cast<std::int64_t>(s.resyncs.load(std::memory_order_relaxed));
    d.read_time_max_us = static_cast<double>(s.read_time_max_ns.exchange(0, std::memory_order_relaxed)) * 1e-3;
    // Faults that are events, not states: raised for the status period in which they came.
    const std::uint64_t range_faults = s.range_faults.load(std::memory_order_relaxed);
    const std::uint64_t overflows = s.encoder_overflows.load(std::memory_order_relaxed);
    raise_while_counting(s, kFaultOutOfRange, range_faults, p.status_range_faults);
    raise_while_counting(s, kFaultEncoderOverflow, overflows, p.status_overflows);
    d.faults = fault_names(s.faults.load(std::memory_order_relaxed));
    d.num_faults = static_cast<std::int32_t>(d.faults.size());
    if (p.clock && p.clock->points() > 0) {
      d.clock_drift_ppm = p.clock->drift_ppm();
      d.clock_residual_us = p.clock->residual_us();
    }
    d.lost_samples = static_cast<std::int64_t>(p.lost);
    d.late_samples = static_cast<std::int64_t>(p.late);
    d.counter_resets = static_cast<std::int64_t>(s.counter_resets.load(std::memory_order_relaxed));
    d.short_frames = static_cast<std::int64_t>(s.short_frames.load(std::memory_order_relaxed));
    d.duplicate_frames = static_cast<std::int64_t>(s.duplicate_frames.load(std::memory_order_relaxed));
    d.out_of_order_frames = static_cast<std::int64_t>(s.out_of_order_frames.load(std::memory_order_relaxed));
    d.kernel_drops = static_cast<std::int64_t>(s.kernel_drops.load(std::memory_order_relaxed));
    d.link_reopens = static_cast<std::int64_t>(s.link_reopens.load(std::memory_order_relaxed));
    d.clock_steps = static_cast<std::int64_t>(s.clock_steps.load(std::memory_order_relaxed));
    d.range_faults = static_cast<std::int64_t>(range_faults);
    d.stuck_samples = static_cast<std::int64_t>(s.stuck_invalid);
    d.encoder_overflows = static_cast<std::int64_t>(overflows);
    st.devices.push_back(std::move(d));
  }
  st.num_devices = static_cast<std::int32_t>(st.devices.size());
  st.lcm_messages = static_cast<std::int64_t>(messages_.load(std::memory_order_relaxed));
  st.lcm_publish_failures = static_cast<std::int64_t>(failures_.load(std::memory_order_relaxed));
  if (log_ != nullptr) {
    st.log_path = log_->current_path();
    st.log_bytes = static_cast<std::int64_t>(log_->bytes_written());
    st.log_rotations = static_cast<std::int32_t>(log_->rotations());
    st.log_write_errors = static_cast<std::int64_t>(log_->write_errors());
    st.log_fsync_last_ms = log_->fsync_last_ms();
    st.log_fsync_max_ms = log_->fsync_max_ms();
    if (log_->messages_lost() > 0) st.faults.emplace_back("log-lost:" + std::to_string(log_->messages_lost()));
    if (log_->stalled()) st.faults.emplace_back("disk-slow");
    if (log_->write_errors() > 0) st.faults.emplace_back("log-write");
  }
  if (failures_.load(std::memory_order_relaxed) > 0) st.faults.emplace_back("lcm-publish");
  if (realtime_refused_.load(std::memory_order_relaxed)) st.faults.emplace_back("publisher-realtime-refused");
  if (options_.daemon_faults)
    for (auto& f : options_.daemon_faults()) st.faults.push_back(std::move(f));
  if (options_.command_counts) {
    const std::array<std::int64_t, 3> c = options_.command_counts();
    st.commands_accepted = c[0];
    st.commands_refused = c[1];
    st.commands_unsigned = c[2];
  }
  st.num_faults = static_cast<std::int32_t>(st.faults.size());
  const int size = st.getEncodedSize();
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(size));
  if (st.encode(buf.data(), 0, size) == size) send(std::string(channels::kStatus), buf.data(), buf.size());
}

void Publisher::run(RealtimeOptions rt) noexcept {
  ::pthread_setname_np(::pthread_self(), "publisher");
  if (rt.fifo_priority > 0 || rt.cpu >= 0) {
    rt.fifo_priority = rt.fifo_priority > 1 ? rt.fifo_priority - 1 : rt.fifo_priority;
    std::string why;
    if (!apply_realtime(rt, &why)) {
      std::cerr << "inertia-daqd: warning: publisher: " << why << "running without it\n";
      realtime_refused_.store(true, std::memory_order_relaxed);
    }
    // The idle wait below is 1 ms; the default 50 us of timer slack would be 5 % of it.
    if (rt.fifo_priority > 0) ::prctl(PR_SET_TIMERSLACK, 1000UL, 0UL, 0UL, 0UL);
  }
  std::int64_t last_status = hal::monotonic_now_ns();
  const auto period_ns = static_cast<std::int64_t>(options_.status_period_s * 1e9);
  const auto bench_period_ns = static_cast<std::int64_t>(options_.bench_period_s * 1e9);
  std::int64_t last_bench = last_status;
  if (!options_.bench_message.empty())
    send(std::string(channels::kBench), options_.bench_message.data(), options_.bench_message.size());
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    std::size_t n = 0;
    publish_operator_records();
    publish_marks();
    for (Packer& p : packers_) n += drain(p);
    const std::int64_t now = hal::monotonic_now_ns();
    for (Packer& p : packers_) watch_silence(p, now);
    if (now - last_status >= period_ns) {
      publish_status(static_cast<double>(now - last_status) * 1e-9);
      last_status = now;
    }
    if (!options_.bench_message.empty() && now - last_bench >= bench_period_ns) {
      send(std::string(channels::kBench), options_.bench_message.data(), options_.bench_message.size());
      last_bench = now;
    }
    heartbeat_.fetch_add(1, std::memory_order_relaxed);
    if (stopping && n == 0) break;
    // Until a sampling thread has pushed samples; at most 1 ms (status, silence, markers).
    if (n == 0) (void)doorbell_->wait(1);
  }
  // Samplers have finished: send what is left as a last, shorter block per device.
  for (Packer& p : packers_) {
    if (p.numbered) {
      while (p.base >= 0 && p.newest >= p.base)
        emit_numbered(p, static_cast<std::int32_t>(std::min<std::int64_t>(p.block_len, p.newest - p.base + 1)));
      continue;
    }
    const std::size_t least = *std::min_element(p.fill.begin(), p.fill.end());
    if (least > 0) emit(p, static_cast<std::int32_t>(least));
    const std::size_t most = *std::max_element(p.fill.begin(), p.fill.end());
    if (most > 0) p.slot->misaligned += most;  // channels left unequal: counted, not hidden
  }
  publish_operator_records();
  publish_marks();
  publish_status(static_cast<double>(hal::monotonic_now_ns() - last_status) * 1e-9);
}

}  // namespace inertia::daq
