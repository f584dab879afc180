#include "daq/sampler.hpp"

#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <iostream>

namespace inertia::daq {
namespace {

/// The ring writer every device pushes into. Real-time: try_stage only; a full ring is a
/// counted drop, never a wait. Samples become visible to the publisher at
/// flush(), once per read_into() call rather than once per sample, and the counters are the
/// sampling thread's own (plain increments, stored to the slot's atomics at flush): per-sample
/// atomic read-modify-writes and index stores were most of the sink's cost at 10^6 samples/s.
class RingSink final : public hal::SampleSink {
 public:
  explicit RingSink(DeviceSlot& slot) : slot_(slot) {}
  bool push(std::uint32_t channel, std::int64_t t_ns, double value, bool valid, std::int64_t sample_index) noexcept override {
    const bool sample = channel != hal::kSegmentStart;   // a segment mark travels with the samples, uncounted
    if (sample && !valid) ++invalid_;
    if (!slot_.ring.try_stage(RingSample{t_ns, value, channel, valid ? 1u : 0u, sample_index})) {
      if (sample) ++drops_;
      return false;
    }
    if (sample) ++samples_;
    return true;
  }
  /// Publishes the staged samples, then the counters (so a reader that sees a count finds the
  /// samples in the ring). Sampling thread.
  void flush() noexcept {
    slot_.ring.publish();
    // Only this thread writes these counters: a relaxed store of our own total is exact.
    slot_.samples.store(samples_, std::memory_order_relaxed);
    slot_.ring_drops.store(drops_, std::memory_order_relaxed);
    slot_.invalid_samples.store(invalid_, std::memory_order_relaxed);
  }

 private:
  DeviceSlot& slot_;
  std::uint64_t samples_ = 0, drops_ = 0, invalid_ = 0;
};

/// Encoder on the sample clock: latches count and position from every edge and pushes one row
/// (count, position) at each trigger edge, stamped with the trigger's kernel time. The device
/// merges all lines in timestamp order, so the row holds every edge before the trigger.
class TriggerRowSink final : public hal::SampleSink {
 public:
  TriggerRowSink(hal::SampleSink& inner, int trigger_channel) : inner_(inner), trigger_(trigger_channel) {}
  bool push(std::uint32_t channel, std::int64_t t_ns, double value, bool valid, std::int64_t sample_index) noexcept override {
    if (channel == hal::gpiod::GpiodEncoderDevice::kCountChannel) {
      count_ = value;
      return true;
    }
    if (channel == hal::gpiod::GpiodEncoderDevice::kPositionChannel) {
      position_ = value;
      return true;
    }
    if (static_cast<int>(channel) != trigger_) return true;  // marker: counted by the device
    const bool a = inner_.push(0, t_ns, count_, valid, sample_index);
    const bool b = inner_.push(1, t_ns, position_, valid, sample_index);
    return a && b;
  }

 private:
  hal::SampleSink& inner_;
  int trigger_;
  double count_ = 0.0, position_ = 0.0;
};

void store_max(std::atomic<std::uint64_t>& target, std::uint64_t value) noexcept {
  std::uint64_t seen = target.load(std::memory_order_relaxed);
  while (value > seen && !target.compare_exchange_weak(seen, value, std::memory_order_relaxed)) {
  }
}

}  // namespace

std::vector<std::string> fault_names(std::uint32_t bits) {
  static constexpr std::pair<std::uint32_t, const char*> kNames[] = {
      {kFaultBusOff, "bus-off"},        {kFaultBusPassive, "bus-passive"},   {kFaultModbusGone, "modbus-gone"},
      {kFaultPeerClosed, "peer-closed"}, {kFaultGlitches, "encoder-glitch"}, {kFaultMisaligned, "misaligned"},
      {kFaultInvalidSamples, "invalid-samples"},
      {kFaultStuck, "stuck"},           {kFaultSilent, "silent"},         {kFaultRealtimeRefused, "realtime-refused"},
      {kFaultOutOfRange, "out-of-range"}, {kFaultLinkDown, "link-down"}, {kFaultEncoderOverflow, "encoder-overflow"}};
  std::vector<std::string> out;
  for (const auto& [bit, name] : kNames)
    if ((bits & bit) != 0) out.emplace_back(name);
  return out;
}

bool apply_realtime(const RealtimeOptions& rt, std::string* why) {
  bool ok = true;
  if (rt.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(rt.cpu, &set);
    if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set); rc != 0) {
      if (why) *why += std::string("affinity to CPU ") + std::to_string(rt.cpu) + ": " + std::strerror(rc) + "; ";
      ok = false;
    }
  }
  if (rt.fifo_priority > 0) {
    sched_param param{};
    param.sched_priority = rt.fifo_priority;
    if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param); rc != 0) {
      if (why) *why += std::string("SCHED_FIFO ") + std::to_string(rt.fifo_priority) + ": " + std::strerror(rc) + "; ";
      ok = false;
    }
  }
  return ok;
}

DeviceSampler::DeviceSampler(std::unique_ptr<hal::Device> device, std::vector<int> wait_fds,
                             std::shared_ptr<DeviceSlot> slot, bool trigger_rows)
    : device_(std::move(device)),
      can_(dynamic_cast<hal::socketcan::CanDevice*>(device_.get())),
      encoder_(dynamic_cast<hal::gpiod::GpiodEncoderDevice*>(device_.get())),
      wait_fds_(std::move(wait_fds)),
      slot_(std::move(slot)),
      trigger_rows_(trigger_rows) {}

bool DeviceSampler::bring_up(std::string* why) {
  auto set = [this](SlotState st) { slot_->state.store(static_cast<std::int8_t>(st), std::memory_order_relaxed); };
  if (device_->configure() != hal::Step::Ok) {
    set(SlotState::Failed);
    if (why) *why = "device " + slot_->name + ": configure: " + device_->last_error();
    return false;
  }
  set(SlotState::Inactive);
  if (can_ != nullptr && can_->is_can_socket()) {
    // The kernel caps a receive buffer at net.core.rmem_max (without CAP_NET_ADMIN): said on
    // the journal with how long of frames it holds, so a bench whose reader may stall knows.
    const hal::socketcan::ReceiveBuffer& b = can_->receive_buffer();
    if (b.granted < b.wanted)
      std::cerr << "inertia-daqd: warning: " << slot_->name << ": the kernel gave CAN interface " << can_->interface()
                << " a receive buffer of " << b.granted << " bytes, " << std::llround(1000.0 * static_cast<double>(b.granted) /
                                                                                      static_cast<double>(b.wanted))
                << " ms of its frames, not the 1000 ms asked; to give it more: sysctl -w net.core.rmem_max=" << b.wanted / 2
                << " (and a file in /etc/sysctl.d/ to keep it)\n";
  }
  if (device_->activate() != hal::Step::Ok) {
    set(SlotState::Failed);
    if (why) *why = "device " + slot_->name + ": activate: " + device_->last_error();
    return false;
  }
  set(SlotState::Active);
  return true;
}

void DeviceSampler::start(const RealtimeOptions& rt) {
  thread_ = std::thread([this, rt] { run(rt); });
  if (can_ != nullptr && can_->is_can_socket()) {
    link_watch_ = std::make_unique<hal::socketcan::CanLinkWatch>(*can_, can_->interface());
    link_thread_ = std::thread([this] { watch_link(); });
  }
}

void DeviceSampler::stop() {
  stop_.store(true, std::memory_order_release);
  if (link_thread_.joinable()) link_thread_.join();
  if (thread_.joinable()) thread_.join();
}

void DeviceSampler::watch_link() noexcept {
  ::pthread_setname_np(::pthread_self(), ("link-" + slot_->name).substr(0, 15).c_str());
  while (!stop_.load(std::memory_order_acquire)) {
    if (link_watch_->check(hal::monotonic_now_ns()))
      std::cerr << "inertia-daqd: " << slot_->name << ": CAN interface " << can_->interface() << " is back, reopened\n";
    timespec ts{0, 50'000'000};
    ::nanosleep(&ts, nullptr);
  }
}

void DeviceSampler::mirror_health() noexcept {
  const hal::DeviceHealth& h = device_->health();
  slot_->decode_errors.store(h.decode_errors + h.malformed, std::memory_order_relaxed);
  slot_->resyncs.store(h.resyncs, std::memory_order_relaxed);
  store_max(slot_->read_time_max_ns, static_cast<std::uint64_t>(h.read_time_max_us * 1e3));
  // Only this thread's own bits change here, by read-modify-write: the supervisor and the
  // publisher set and clear other bits of the same word at any time.
  constexpr std::uint32_t kMine = kFaultBusOff | kFaultBusPassive | kFaultPeerClosed | kFaultGlitches | kFaultLinkDown;
  std::uint32_t faults = 0;
  if (can_ != nullptr) {
    const auto& s = can_->status();
    if (s.bus_state == hal::socketcan::BusState::BusOff) faults |= kFaultBusOff;
    if (s.bus_state == hal::socketcan::BusState::ErrorPassive) faults |= kFaultBusPassive;
    if (s.peer_closed) faults |= kFaultPeerClosed;
    if (s.link_down) faults |= kFaultLinkDown;
    slot_->link_reopens.store(s.link_reopens, std::memory_order_relaxed);
    slot_->counter_resets.store(s.counter_resets, std::memory_order_relaxed);
    slot_->short_frames.store(s.short_frames, std::memory_order_relaxed);
    slot_->duplicate_frames.store(s.duplicate_frames, std::memory_order_relaxed);
    slot_->out_of_order_frames.store(s.out_of_order_frames, std::memory_order_relaxed);
    slot_->kernel_drops.store(s.kernel_drops, std::memory_order_relaxed);
    slot_->clock_steps.store(s.clock_steps, std::memory_order_relaxed);
    slot_->range_faults.store(s.range_faults, std::memory_order_relaxed);
  } else if (encoder_ != nullptr) {
    const auto s = encoder_->status();
    const std::uint64_t glitches = s.quadrature.glitches + s.quadrature.illegal_transitions;
    if (glitches > slot_->glitches.load(std::memory_order_relaxed)) faults |= kFaultGlitches;
    slot_->glitches.store(glitches, std::memory_order_relaxed);
    slot_->encoder_overflows.store(s.overflows, std::memory_order_relaxed);
    // Glitches and illegal transitions are edges that did not decode into motion.
    slot_->decode_errors.store(h.decode_errors + h.malformed + glitches, std::memory_order_relaxed);
  }
  const std::uint32_t before = slot_->faults.load(std::memory_order_relaxed) & kMine;
  if ((before & ~faults) != 0) slot_->faults.fetch_and(~(before & ~faults), std::memory_order_relaxed);
  if ((faults & ~before) != 0) slot_->faults.fetch_or(faults & ~before, std::memory_order_relaxed);
}

void DeviceSampler::run(RealtimeOptions rt) noexcept {
  ::pthread_setname_np(::pthread_self(), ("smp-" + slot_->name).substr(0, 15).c_str());
  std::string why;
  if ((rt.fifo_priority > 0 || rt.cpu >= 0) && !apply_realtime(rt, &why)) {
    // Said once on stderr and for the whole run on INERTIA_STATUS and the journal (a fault that
    // stays raised): a bench running without its real-time settings is not the bench configured.
    std::cerr << "inertia-daqd: warning: " << slot_->name << ": " << why << "running without it\n";
    slot_->faults.fetch_or(kFaultRealtimeRefused, std::memory_order_relaxed);
  }
  RingSink ring_sink(*slot_);
  // Room for what one read_into() call can push (bounded by the device's records per call; a
  // quarter ring is well above that for the simulated devices that use backpressure).
  auto room_for_a_read = [this] { return slot_->ring.capacity() - slot_->ring.size_approx() >= slot_->ring.capacity() / 4; };
  TriggerRowSink row_sink(ring_sink, encoder_ != nullptr ? encoder_->trigger_channel() : -1);
  hal::SampleSink& sink = trigger_rows_ ? static_cast<hal::SampleSink&>(row_sink) : ring_sink;

  pollfd fds[hal::gpiod::kEdgeLineCount]{};
  nfds_t nfds = 0;
  for (int fd : wait_fds_)
    if (fd >= 0 && nfds < hal::gpiod::kEdgeLineCount) fds[nfds++] = pollfd{fd, POLLIN, 0};
  // A peer that closed its end keeps the descriptor readable (EOF) forever: stop polling it
  // once it is reported, and fall back to the idle wait.
  std::uint64_t loops = 0;
  for (;;) {
    if (const std::int64_t hang = slot_->hang_until_ns.load(std::memory_order_relaxed); hang != 0) {
      const timespec until{static_cast<time_t>(hang / 1'000'000'000), static_cast<long>(hang % 1'000'000'000)};
      while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, nullptr) == EINTR) {
      }
      slot_->hang_until_ns.store(0, std::memory_order_relaxed);
    }
    const bool stopping = stop_.load(std::memory_order_acquire);
    // Drain: read_into is bounded per call, so loop until nothing is pending.
    std::size_t got = 0;
    for (int i = 0; i < 64; ++i) {
      if (slot_->backpressure && !room_for_a_read()) {
        if (i == 0) {
          timespec ts{0, 200'000};  // the publisher frees a quarter ring in far less
          ::nanosleep(&ts, nullptr);
          slot_->heartbeat.fetch_add(1, std::memory_order_relaxed);
          i = -1;
          continue;
        }
        break;
      }
      const std::size_t n = device_->read_into(sink);
      ring_sink.flush();  // the publisher sees this call's samples now, not after the drain
      got += n;
      if (n == 0) break;
    }
    if (got != 0 && slot_->doorbell) slot_->doorbell->ring();
    if (++loops % 16 == 0 || got == 0) mirror_health();
    slot_->heartbeat.fetch_add(1, std::memory_order_relaxed);
    if (stopping && got == 0) break;  // stop requested and nothing left: every sample is in the ring
    if (got != 0) continue;
    const bool peer_gone = (slot_->faults.load(std::memory_order_relaxed) & kFaultPeerClosed) != 0;
    if (nfds > 0 && !peer_gone) {
      slot_->idle.store(true, std::memory_order_release);
      (void)::poll(fds, nfds, kIdleWaitMs);
      slot_->idle.store(false, std::memory_order_release);
    } else {
      timespec ts{0, kIdleWaitMs * 1'000'000L};
      ::nanosleep(&ts, nullptr);
    }
  }
  mirror_health();
  slot_->finished.store(true, std::memory_order_release);
}

ModbusSampler::ModbusSampler(std::unique_ptr<hal::modbus::ModbusController> controller, int poll_interval_ms,
                             std::shared_ptr<DeviceSlot> slot, std::shared_ptr<ControllerPort> port,
                             std::shared_ptr<SimulatedClock> clock)
    : controller_(std::move(controller)), poll_interval_ms_(poll_interval_ms), slot_(std::move(slot)), port_(std::move(port)),
      clock_(std::move(clock)) {}

bool ModbusSampler::bring_up(std::string*) {
  // ModbusController::connect() already connected (or the device was refused at creation).
  slot_->state.store(static_cast<std::int8_t>(SlotState::Active), std::memory_order_relaxed);
  return true;
}

void ModbusSampler::start(const RealtimeOptions&) {
  thread_ = std::thread([this] { run(); });
}

void ModbusSampler::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void ModbusSampler::run() noexcept {
  ::pthread_setname_np(::pthread_self(), ("smp-" + slot_->name).substr(0, 15).c_str());
  RingSink sink(*slot_);
  const std::int64_t interval_ns = static_cast<std::int64_t>(poll_interval_ms_) * 1'000'000;
  // Polls on a grid of CLOCK_MONOTONIC: poll k is due at first + k * interval and carries k as its
  // sample number. After an overrun (a request timing out) the grid points it covered are skipped,
  // not polled in a burst: their numbers are missing, so the publisher's clock fit maps every poll
  // to its own time and the gap shows as lost samples, never as later rows stamped early.
  std::int64_t next_ns = hal::monotonic_now_ns();
  std::int64_t index = 0;
  std::int64_t next_simulated = SimulatedClock::kNotYet;
  while (!stop_.load(std::memory_order_acquire)) {
    std::int64_t stamp = 0;   // the poll's time: its start on CLOCK_MONOTONIC, or the simulated time it is due
    if (clock_) {
      // The next reading is due when the simulation has reached its time (the first: its start).
      bool due = false;
      while (!due && !stop_.load(std::memory_order_acquire)) {
        const std::int64_t reached = clock_->reached_ns.load(std::memory_order_acquire);
        if (reached != SimulatedClock::kNotYet) {
          if (next_simulated == SimulatedClock::kNotYet) next_simulated = reached;
          due = reached >= next_simulated;
        }
        if (!due) {
          timespec ts{0, 20'000};
          ::nanosleep(&ts, nullptr);
        }
      }
      if (!due) break;
      stamp = next_simulated;
    }
    const std::int64_t t0 = hal::monotonic_now_ns();
    if (!clock_) stamp = t0;
    const auto values = controller_->poll();
    const std::int64_t t1 = hal::monotonic_now_ns();
    store_max(slot_->read_time_max_ns, static_cast<std::uint64_t>(t1 - t0));
    bool any_answered = false;   // a reading out of its range was still an answer
    for (std::size_t i = 0; i < values.size(); ++i) {
      any_answered = any_answered || values[i].valid || values[i].out_of_range;
      // One row per poll, all stamped with the poll's start so the row stays aligned.
      // An implausible reading keeps its value, marked invalid (the log shows what came).
      (void)sink.push(static_cast<std::uint32_t>(i), stamp, values[i].valid || values[i].out_of_range ? values[i].value : 0.0,
                      values[i].valid, clock_ ? hal::kNoSampleIndex : index);
    }
    sink.flush();
    if (slot_->doorbell) slot_->doorbell->ring();
    if (port_) port_->publish(values, controller_->link().connected());
    const auto& h = controller_->link().health();
    // Every failed request (timeout, refused, exception, bad data) left its values invalid.
    slot_->decode_errors.store(h.errors, std::memory_order_relaxed);
    slot_->resyncs.store(h.reconnects, std::memory_order_relaxed);
    slot_->range_faults.store(controller_->range_faults(), std::memory_order_relaxed);
    // Read-modify-write of our bit only (the supervisor sets invalid-samples on the same word).
    if (!any_answered || !controller_->link().connected()) {
      slot_->faults.fetch_or(kFaultModbusGone, std::memory_order_relaxed);
    } else {
      slot_->faults.fetch_and(~kFaultModbusGone, std::memory_order_relaxed);
    }
    slot_->heartbeat.fetch_add(1, std::memory_order_relaxed);
    if (clock_) {
      clock_->polled_ns.store(next_simulated, std::memory_order_release);
      next_simulated += interval_ns;
      if (port_) port_->serve(*controller_);
      continue;
    }
    next_ns += interval_ns;
    ++index;
    if (const std::int64_t late = hal::monotonic_now_ns() - next_ns; late > 0) {
      const std::int64_t skipped = late / interval_ns + 1;
      next_ns += skipped * interval_ns;
      index += skipped;
    }
    // Sleep in slices so stop() is seen within 20 ms; the executive's commands wake it at once.
    for (;;) {
      if (port_) port_->serve(*controller_);
      const std::int64_t left = next_ns - hal::monotonic_now_ns();
      if (left <= 0 || stop_.load(std::memory_order_acquire)) break;
      const std::int64_t slice = std::min<std::int64_t>(left, 20'000'000);
      if (port_) {
        port_->wait_until(hal::monotonic_now_ns() + slice);
      } else {
        timespec ts{0, static_cast<long>(slice)};
        ::nanosleep(&ts, nullptr);
      }
    }
  }
  // A safe state asked for while stopping still goes out (the daemon stops the pollers only
  // after the executive has its answer, but never leave one unserved).
  if (port_) port_->serve(*controller_);
  if (clock_) clock_->poller_gone.store(true, std::memory_order_release);
  slot_->finished.store(true, std::memory_order_release);
}

}  // namespace inertia::daq
