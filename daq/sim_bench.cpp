#include "daq/sim_bench.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/gpio.h>
#include <limits.h>
#include <pthread.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <string>

#include "common/config/link_capacity.hpp"
#include "daq/clock_fit.hpp"
#include "hal/sim/bench_motion.hpp"
#include "hal/sim/random_streams.hpp"

namespace inertia::daq {
namespace {

namespace gp = hal::gpiod;

/// The simulated controllers' Modbus TCP server on a port below the kernel's ephemeral range.
/// While the server is gone (--fault modbus-gone) its port is free, and a port of that range can
/// meanwhile become some connection's source port on a busy host (other test processes), which
/// the server could then never bind again; below it only a listener asks for a port by number.
std::unique_ptr<hal::wire_sim::BenchControllerServer> start_controllers(const hal::wire_sim::BenchControllerState& initial,
                                                                        std::string* why) {
  int ephemeral_low = 32768;
  std::ifstream range("/proc/sys/net/ipv4/ip_local_port_range");
  range >> ephemeral_low;
  if (ephemeral_low > 2048) {
    std::mt19937 draw(std::random_device{}());
    std::uniform_int_distribution<int> port(std::max(1024, ephemeral_low - 8192), ephemeral_low - 1);
    for (int attempt = 0; attempt < 32; ++attempt) {
      std::string taken;
      if (auto server = hal::wire_sim::BenchControllerServer::start(port(draw), &taken, initial)) return server;
    }
  }
  return hal::wire_sim::BenchControllerServer::start(0, why, initial);   // a range too low to stay below
}

constexpr std::size_t kSignalsPerFrame = 16;  // int32 signals in a 64-byte CAN FD payload

int mod4(std::int64_t v) { return static_cast<int>(((v % 4) + 4) % 4); }
void levels_of_state(int s, bool& a, bool& b) {
  a = (s == 1 || s == 2);
  b = (s == 2 || s == 3);
}

void sleep_until_ns(std::int64_t t_ns) {
  timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

/// A simulated CAN bus: a socketpair whose far end the real CanDevice reads; `near` gets the
/// simulator's end. nullptr + why when the pair or the device cannot be made.
std::unique_ptr<hal::socketcan::CanDevice> open_sim_can_bus(const hal::socketcan::CanDeviceConfig& cfg,
                                                            hal::UniqueFd& near, std::string* why) {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0) {
    if (why) *why = std::string("socketpair: ") + std::strerror(errno);
    return nullptr;
  }
  const int buf = 4 << 20;  // slack for scheduling hiccups of the reader in paced mode
  (void)::setsockopt(sv[0], SOL_SOCKET, SO_SNDBUF, &buf, sizeof buf);
  (void)::setsockopt(sv[1], SOL_SOCKET, SO_RCVBUF, &buf, sizeof buf);
  near = hal::UniqueFd(sv[0]);
  return hal::socketcan::CanDevice::from_fd(hal::UniqueFd(sv[1]), cfg, why);
}

// A CAN encoder's frame: the count (int64, little-endian) latched on the sample tick, then the
// tick's number (uint32), 12 bytes of a CAN FD frame.
constexpr std::size_t kCounterFrameBytes = 12;
constexpr std::uint32_t kSimEncoderCanId = 0x180;  // + node: a CANopen device's first transmit PDO

}  // namespace

SimBench::SimBench(const config::BenchConfig& bench, SimOptions options)
    : bench_(bench), options_(std::move(options)), rate_hz_(bench.sample_rate_hz) {}

SimBench::~SimBench() {
  stop();
  stop_servers();
  // The samplers may still hold devices reading our wires; the daemon stops them first.
}

std::unique_ptr<SimBench> SimBench::create(const config::BenchConfig& bench, const SimOptions& options,
                                           std::size_t ring_capacity, std::string* why) {
  std::unique_ptr<SimBench> s(new SimBench(bench, options));
  s->sim_ = sim::simulate_bench(bench);  // throws InputError for bad truth parameters
  s->case_begin_.push_back(0);
  for (const auto& c : s->sim_.cases) s->case_begin_.push_back(s->case_begin_.back() + c.motion.size());
  if (s->plan_samples() == 0) {
    if (why) *why = bench.file.string() + ": the test plan has no samples (no [[case]] with phases)";
    return nullptr;
  }
  s->run_samples_ = options.duration_s > 0
                        ? static_cast<std::size_t>(std::llround(options.duration_s * s->rate_hz_))
                        : s->plan_samples();
  std::int32_t next_id = 1;
  s->real_timing_ = bench.sim_timing.enabled && !options.fast;
  if (bench.sim_timing.enabled && options.fast)
    std::cerr << "inertia-daqd: note: [bench.sim_timing] needs a paced run (receive stamps of a run as fast as possible "
                 "mean nothing): the simulator's exact clock is used with --fast\n";

  // --- CAN: every accelerometer channel on one bus ---
  for (std::size_t i = 0; i < bench.sensors.size(); ++i)
    s->can_channels_.push_back({bench.sensors[i].name, bench.sensors[i].output_unit, 0, i});
  for (std::size_t i = 0; i < bench.monitors.size(); ++i)
    s->can_channels_.push_back({bench.monitors[i].name, "m/s^2", 1, i});
  if (bench.control_accelerometer) s->can_channels_.push_back({"control", "m/s^2", 2, 0});
  {
    hal::socketcan::CanDeviceConfig cfg;
    cfg.name = "accel";
    std::vector<ChannelInfo> info;
    const std::size_t n = s->can_channels_.size();
    for (std::size_t i = 0; i <= n; ++i) {  // the last signal: sample_index
      hal::socketcan::CanSignal sig;
      sig.name = i < n ? s->can_channels_[i].name : "sample_index";
      sig.id = kSimCanBaseId + static_cast<std::uint32_t>(i / kSignalsPerFrame);
      sig.byte_offset = static_cast<std::uint8_t>(4 * (i % kSignalsPerFrame));
      sig.bit_length = static_cast<std::uint8_t>(i == n && s->real_timing_ ? bench.sim_timing.counter_bits : 32);
      sig.is_signed = i < n;
      sig.scale = i < n ? kSimCanScale : 1.0;
      if (i < n) sig.invalid_raw = kSimCanNoReading;
      // Real timing: the sample number is the frame's counter (one frame carries every signal).
      sig.counter = i == n && s->real_timing_;
      cfg.map.signals.push_back(sig);
      info.push_back({sig.name, i < n ? s->can_channels_[i].unit : "1", next_id++});
    }
    cfg.max_records_per_read = 256;
    cfg.frame_rate_hz = s->rate_hz_;
    auto device = open_sim_can_bus(cfg, s->can_bus_.fd, why);
    if (!device) return nullptr;
    const int fd = device->wait_fd();
    if (s->real_timing_ && n + 1 > kSignalsPerFrame) {
      if (why) *why = "[bench.sim_timing]: the simulated CAN device numbers its samples with one counter per frame; more "
                      "than " + std::to_string(kSignalsPerFrame - 1) + " channels need a second frame";
      return nullptr;
    }
    const SimFaults& f = options.faults;
    if (!s->real_timing_ && (f.can_reset_at_s >= 0 || f.short_frame_at_s >= 0 || f.duplicate_frame_at_s >= 0 ||
                             f.swapped_frames_at_s >= 0)) {
      if (why) *why = "--fault can-reset, short-frame, duplicate-frame and swapped-frames act on the frame counter: they need "
                      "[bench.sim_timing] in the bench file and a paced run (no --fast)";
      return nullptr;
    }
    auto slot = std::make_shared<DeviceSlot>("accel", std::move(info), s->rate_hz_, ring_capacity);
    slot->sim_time_base = !s->real_timing_;
    slot->backpressure = options.fast;
    slot->time_index_channel = static_cast<int>(n);
    slot->stuck_samples.assign(n + 1, kSimStuckSamples);
    slot->stuck_samples[n] = 0;   // sample_index counts, never stuck
    s->can_slot_ = slot;
    s->samplers_.push_back(std::make_unique<DeviceSampler>(std::move(device), std::vector<int>{fd}, slot, false));
  }

  // --- encoders: quadrature + sample-clock trigger through pipes, or counts on a CAN bus ---
  auto add_encoder = [&](const config::Encoder& enc, bool table, const char* name) -> bool {
    if (!enc.present) return true;
    if (enc.wire == config::EncoderWire::Gpio) {
      // The simulator's GPIO wire is a pipe and carries any edge rate; a real GPIO line does not
      // (config/link_capacity.hpp, which refuses such a real bench). Said, so that a bench file
      // copied from this one is not taken for a wiring that works.
      const config::GpiodEncoder real_line;
      const double edges = config::quadrature_edges_per_line(config::motion_peak_speed(s->bench_, table), enc.resolution);
      const double capacity = config::gpio_line_edge_capacity(real_line);
      if (edges > capacity)
        std::cerr << "inertia-daqd: note: simulated bench: the " << name << "'s fastest motion makes " << std::llround(edges)
                  << " edges/s on each GPIO line, above the " << std::llround(capacity)
                  << " a real line carries (gpiolib's " << config::kGpioLineEventQueue << "-event queue, edge_latency_ns = "
                  << real_line.edge_latency_ns << "); the simulator's wire carries them all, a real bench would read this "
                  << "encoder through a counter (wire = \"can\" here; config/bench-template.toml)\n";
    }
    EncoderSim e;
    e.resolution = enc.resolution;
    e.table = table;
    const double x0 = table ? s->sim_.cases[0].motion.table_angle_rad[0] : s->sim_.cases[0].motion.shaker_x_m[0];
    e.count = static_cast<std::int64_t>(std::floor(x0 / e.resolution));
    if (enc.wire == config::EncoderWire::Can) {
      e.can_id = kSimEncoderCanId + 1 + static_cast<std::uint32_t>(s->encoders_.size());
      hal::socketcan::CanDeviceConfig cfg;
      cfg.name = name;
      const auto signal = [&](const char* channel, std::uint8_t offset, std::uint8_t bits, bool is_signed,
                              double scale) {
        hal::socketcan::CanSignal sig;
        sig.name = channel;
        sig.id = e.can_id;
        sig.byte_offset = offset;
        sig.bit_length = bits;
        sig.is_signed = is_signed;
        sig.scale = scale;
        return sig;
      };
      cfg.map.signals = {signal("count", 0, 64, true, 1.0), signal("position", 0, 64, true, e.resolution),
                         signal("sample_index", 8, 32, false, 1.0)};
      cfg.map.signals.back().counter = s->real_timing_;  // as the accelerometers' bus (above)
      cfg.max_records_per_read = 256;
      cfg.frame_rate_hz = s->rate_hz_;
      auto device = open_sim_can_bus(cfg, e.bus.fd, why);
      if (!device) return false;
      const int fd = device->wait_fd();
      std::vector<ChannelInfo> info{
          {"count", "1", next_id}, {"position", table ? "rad" : "m", next_id + 1}, {"sample_index", "1", next_id + 2}};
      next_id += 3;
      auto slot = std::make_shared<DeviceSlot>(name, std::move(info), s->rate_hz_, ring_capacity);
      slot->sim_time_base = !s->real_timing_;
      slot->backpressure = options.fast;
      slot->time_index_channel = 2;
      s->samplers_.push_back(std::make_unique<DeviceSampler>(std::move(device), std::vector<int>{fd}, slot, false));
      s->encoders_.push_back(std::move(e));
      return true;
    }
    hal::wire_sim::EncoderWire::Lines lines;
    lines.trigger = true;
    levels_of_state(mod4(e.count), lines.a0, lines.b0);
    e.wire = hal::wire_sim::EncoderWire::create(lines, why);
    if (!e.wire) return false;
    gp::QuadratureConfig qc;
    qc.name = name;
    qc.line_a = 0;
    qc.line_b = 1;
    qc.line_trigger = 3;
    qc.resolution = enc.resolution;
    auto device = gp::GpiodEncoderDevice::from_source(e.wire->take_source(), qc, why);
    if (!device) return false;
    // Woken by the trigger line only: the simulator writes a tick's A/B edges before its trigger
    // edge, so when the trigger is readable the whole tick is in the pipes (see run()).
    std::vector<int> fds{device->event_fds()[static_cast<std::size_t>(gp::EdgeLine::Trigger)]};
    std::vector<ChannelInfo> info{{"count", "1", next_id}, {"position", table ? "rad" : "m", next_id + 1}};
    next_id += 2;
    auto slot = std::make_shared<DeviceSlot>(name, std::move(info), s->rate_hz_, ring_capacity);
    slot->sim_time_base = !s->real_timing_;   // real timing: the edges' stamps, through its clock fit
    slot->backpressure = options.fast;
    s->samplers_.push_back(std::make_unique<DeviceSampler>(std::move(device), std::move(fds), slot, true));
    s->encoders_.push_back(std::move(e));
    return true;
  };
  if (!add_encoder(bench.linear_encoder, false, "linear_encoder")) return nullptr;
  if (!add_encoder(bench.table_encoder, true, "table_encoder")) return nullptr;

  // --- bench controllers over Modbus TCP on loopback ---
  hal::wire_sim::BenchControllerState initial;
  initial.frozen = true;  // the bench simulation drives the registers, not the server's own physics
  initial.temperature_degC = bench.thermal.initial_c;
  initial.temperature_setpoint_degC = bench.thermal.initial_c;
  s->controllers_ = start_controllers(initial, why);
  if (!s->controllers_) return nullptr;
  hal::modbus::ModbusConfig mc;
  mc.name = "controller";
  mc.host = "127.0.0.1";
  mc.port = s->controllers_->port();
  mc.response_timeout_s = 0.5;
  mc.reconnect_initial_s = 0.2;
  mc.reconnect_max_s = 1.0;
  mc.timeouts_before_reconnect = 2;
  mc.map = hal::wire_sim::bench_controller_register_map();
  auto controller = hal::modbus::ModbusController::connect(mc, why);
  if (!controller) return nullptr;
  std::vector<ChannelInfo> info;
  for (const auto& r : mc.map.registers) {
    std::string unit = "1";
    if (r.name.find("temperature") != std::string::npos) unit = "degC";
    else if (r.name.find("rate") != std::string::npos) unit = "rad/s";
    else if (r.name.find("angle") != std::string::npos) unit = "rad";
    else if (r.name.find("power") != std::string::npos) unit = "W";
    else if (r.name.find("frequency") != std::string::npos) unit = "Hz";
    info.push_back({r.name, unit, next_id++});
  }
  auto slot = std::make_shared<DeviceSlot>("controller", std::move(info), 1000.0 / options.modbus_poll_ms, ring_capacity);
  if (options.fast) s->controller_clock_ = std::make_shared<SimulatedClock>();
  s->samplers_.push_back(
      std::make_unique<ModbusSampler>(std::move(controller), options.modbus_poll_ms, slot, nullptr, s->controller_clock_));
  return s;
}

void SimBench::start(std::int64_t t0_ns, SpscRing<PlanMark>* marks) {
  t0_ns_ = t0_ns;
  marks_ = marks;
  thread_ = std::thread([this] { run(); });
}

void SimBench::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SimBench::stop_servers() {
  if (controllers_) controllers_->stop();
}

double SimBench::can_value(const CanChannel& ch, std::size_t c, std::size_t k) const {
  const auto& sc = sim_.cases[c];
  const auto kk = static_cast<Eigen::Index>(k);
  switch (ch.kind) {
    case 0: return sc.sensors[ch.index].y[kk];
    case 1: return sc.references.monitors(kk, static_cast<Eigen::Index>(ch.index));
    default: return sc.references.control[kk];
  }
}

double SimBench::position(const EncoderSim& e, std::size_t c, std::size_t k) const {
  const auto& m = sim_.cases[c].motion;
  const auto kk = static_cast<Eigen::Index>(k);
  return e.offset + (e.table ? m.table_angle_rad[kk] : m.shaker_x_m[kk]);
}

void SimBench::queue_edge(EncoderSim& e, gp::EdgeLine line, bool rising, std::int64_t t_ns) {
  gpioevent_data record{};
  record.timestamp = static_cast<__u64>(t_ns);
  record.id = rising ? GPIOEVENT_EVENT_RISING_EDGE : GPIOEVENT_EVENT_FALLING_EDGE;
  e.pending[static_cast<std::size_t>(line)].push_back(record);
}

bool SimBench::flush_edges(EncoderSim& e, std::int64_t through_ns) {
  // A/B first, then their clock, the trigger last: when the trigger wakes the sampler, the
  // device already knows A and B are complete through the batch and merges all of it.
  for (std::size_t l = 0; l < gp::kEdgeLineCount; ++l) {
    if (l == static_cast<std::size_t>(gp::EdgeLine::Trigger)) {
      // The lines' levels as a chip would read them now, whatever events reached the reader.
      bool a = false, b = false;
      levels_of_state(mod4(e.count), a, b);
      e.wire->set_levels(a, b, through_ns);
      e.wire->advance(gp::EdgeLine::A, through_ns);
      e.wire->advance(gp::EdgeLine::B, through_ns);
    }
    auto& buf = e.pending[l];
    std::size_t done = 0;
    while (done < buf.size()) {
      const std::size_t chunk = std::min<std::size_t>(buf.size() - done, PIPE_BUF / sizeof(gpioevent_data));
      // The pipe is non-blocking: full means the reader is behind; wait for it (the sim is the
      // bench, it cannot drop edges), but never past stop().
      if (e.wire->write_raw(static_cast<gp::EdgeLine>(l), buf.data() + done, chunk * sizeof(gpioevent_data))) {
        done += chunk;
      } else {
        if (stop_.load(std::memory_order_relaxed)) return false;
        timespec ts{0, 20'000};
        ::nanosleep(&ts, nullptr);
      }
    }
    buf.clear();
  }
  return true;
}

void SimBench::CanWire::queue(std::uint32_t can_id, const std::uint8_t* data, std::size_t len, bool fd_frame) {
  canfd_frame f{};
  f.can_id = can_id;
  f.len = static_cast<std::uint8_t>(len);
  std::memcpy(f.data, data, len);
  pending.push_back(PendingFrame{f, fd_frame ? sizeof(canfd_frame) : sizeof(can_frame)});
}

void SimBench::CanWire::flush() { send(pending); }

void SimBench::CanWire::hold_until(std::int64_t release_ns) {
  if (pending.empty()) return;
  if (!held_.empty()) release_ns = std::max(release_ns, held_.back().release_ns);
  std::vector<PendingFrame> frames;
  if (!spare_.empty()) {
    frames = std::move(spare_.back());
    spare_.pop_back();
  }
  frames.swap(pending);   // pending takes the spare's (empty) storage
  held_.push_back(HeldBatch{release_ns, std::move(frames)});
}

void SimBench::CanWire::send_due(std::int64_t now_ns) {
  while (!held_.empty() && held_.front().release_ns <= now_ns) {
    send(held_.front().frames);
    spare_.push_back(std::move(held_.front().frames));
    held_.pop_front();
  }
}

std::int64_t SimBench::CanWire::next_release_ns() const noexcept {
  return held_.empty() ? std::numeric_limits<std::int64_t>::max() : held_.front().release_ns;
}

void SimBench::CanWire::send_held_until(std::int64_t deadline_ns) {
  for (;;) {
    const std::int64_t next = std::min(deadline_ns, next_release_ns());
    sleep_until_ns(next);
    send_due(hal::monotonic_now_ns());
    if (next == deadline_ns) return;
  }
}

void SimBench::CanWire::send_all_held() {
  if (!held_.empty()) send_held_until(held_.back().release_ns);
}

void SimBench::CanWire::send(std::vector<PendingFrame>& frames) {
  // A classic frame is the first CAN_MTU bytes of the canfd_frame (same id/len/data layout).
  constexpr std::size_t kChunk = 256;
  std::array<mmsghdr, kChunk> msgs{};
  std::array<iovec, kChunk> iov{};
  std::size_t done = 0;
  while (done < frames.size()) {
    const std::size_t n = std::min(kChunk, frames.size() - done);
    for (std::size_t i = 0; i < n; ++i) {
      iov[i] = iovec{&frames[done + i].frame, frames[done + i].size};
      msgs[i] = mmsghdr{};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    // Blocking: a full socket is the reader's back-pressure (fast runs), as write() was.
    const int sent = ::sendmmsg(fd.get(), msgs.data(), static_cast<unsigned>(n), 0);
    if (sent > 0) {
      done += static_cast<std::size_t>(sent);
    } else if (sent < 0 && errno != EINTR) {
      break;  // the reader is gone (daemon stopping): nothing left to deliver to
    }
  }
  frames.clear();
}

void SimBench::update_controllers(std::size_t c, std::size_t k) {
  const auto& sc = sim_.cases[c];
  const auto& m = sc.motion;
  const auto kk = static_cast<Eigen::Index>(k);
  const auto& tc = bench_.cases[c];
  double frequency = 0.0;
  bool shaking = false;
  for (std::size_t i = 0; i < m.spans.size(); ++i) {
    if (k >= m.spans[i].begin && k < m.spans[i].end) {
      const auto kind = m.spans[i].kind;
      shaking = kind == config::PhaseKind::Sine || kind == config::PhaseKind::Random || kind == config::PhaseKind::Shock;
      if (kind == config::PhaseKind::Sine && i < tc.phases.size()) frequency = tc.phases[i].frequency_hz;
    }
  }
  const double temp = sc.references.temp_measured_c.size() > kk ? sc.references.temp_measured_c[kk] : m.temp_c[kk];
  const double angle = m.table_angle_rad[kk];
  const double rate = m.w_e.row(kk).norm();
  controllers_->update([&](hal::wire_sim::BenchControllerState& s) {
    s.temperature_degC = temp;
    constexpr double kTwoPi = 6.283185307179586;
    s.table_turns = static_cast<std::int32_t>(std::floor(angle / kTwoPi));
    s.table_angle_rad = angle - kTwoPi * s.table_turns;
    s.table_rate_rad_s = rate;
    s.shaker_status = shaking ? 1 : 0;
    s.shaker_frequency_hz = frequency;
  });
}

void SimBench::wait_for_readings_before(std::int64_t t_ns) {
  SimulatedClock& clock = *controller_clock_;
  if (clock.reached_ns.load(std::memory_order_relaxed) == SimulatedClock::kNotYet) return;   // the first update
  // The registers hold their state until t_ns: readings due before it may be taken now.
  clock.reached_ns.store(t_ns - 1, std::memory_order_release);
  std::int64_t last = clock.polled_ns.load(std::memory_order_acquire);
  std::int64_t since = hal::monotonic_now_ns();
  for (;;) {
    const std::int64_t polled = clock.polled_ns.load(std::memory_order_acquire);
    if (polled != SimulatedClock::kNotYet && polled + static_cast<std::int64_t>(options_.modbus_poll_ms) * 1'000'000 >= t_ns) return;
    if (clock.poller_gone.load(std::memory_order_acquire) || stop_.load(std::memory_order_relaxed)) return;
    const std::int64_t now = hal::monotonic_now_ns();
    if (polled != last) {
      last = polled;
      since = now;
    } else if (now - since > 2'000'000'000) {
      return;   // no reading for 2 s: the run goes on without waiting for the controllers
    }
    timespec ts{0, 20'000};
    ::nanosleep(&ts, nullptr);
  }
}

void SimBench::run() noexcept {
  ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);  // paced sleeps and pipe-full waits to the us
  ::pthread_setname_np(::pthread_self(), "sim-bench");  // the simulator, not the daemon (CPU accounting)
  if (!options_.fast && options_.fifo_priority > 0) {
    std::string why;
    if (!apply_realtime(RealtimeOptions{std::min(options_.fifo_priority + 1, 99), -1}, &why))
      std::cerr << "inertia-daqd: warning: simulated bench: " << why << "paced without it\n";
  }
  const double period_ns = 1e9 / rate_hz_;
  // Paced: wake every 1 ms of simulated time. Fast: 10 ms at a time (fewer, larger writes).
  const std::size_t batch = std::max<std::size_t>(1, static_cast<std::size_t>(rate_hz_ / (options_.fast ? 100.0 : 1000.0)));
  const std::size_t ctrl_every = std::max<std::size_t>(1, static_cast<std::size_t>(rate_hz_ / 100.0));  // 10 ms
  const std::size_t nch = can_channels_.size();
  const std::size_t frames = nch / kSignalsPerFrame + 1;  // + sample_index
  std::vector<std::uint8_t> payload(frames * 64);
  const std::size_t plan = plan_samples();
  bool bus_off = false, modbus_gone = false, restart_refused = false;
  std::int64_t stuck_raw = 0;
  bool stuck = false;
  // Real timing: the bench's sample clock runs clock_ppm fast against CLOCK_MONOTONIC.
  const double host_period_ns = real_timing_ ? period_ns * (1.0 + 1e-6 * bench_.sim_timing.clock_ppm) : period_ns;
  // The frame counter: counter_bits wide; after an adapter reset it counts from 0 again.
  const std::uint64_t counter_mask = real_timing_ ? (std::uint64_t{1} << bench_.sim_timing.counter_bits) - 1 : 0xffffffffu;
  const auto sample_at = [this](double t_s) { return t_s >= 0 ? static_cast<std::size_t>(std::llround(t_s * rate_hz_)) : run_samples_; };
  const SimFaults& faults = options_.faults;
  const std::size_t reset_at = sample_at(faults.can_reset_at_s);
  const std::size_t reset_back = faults.can_reset_at_s >= 0 ? sample_at(faults.can_reset_at_s + faults.can_reset_s) : run_samples_;
  const std::size_t short_at = sample_at(faults.short_frame_at_s), duplicate_at = sample_at(faults.duplicate_frame_at_s);
  const std::size_t swap_at = sample_at(faults.swapped_frames_at_s);
  std::vector<CanWire::PendingFrame> held;   // swapped-frames: a sample's frames, sent after the next sample's
  auto time_of = [&](std::size_t n) { return t0_ns_ + static_cast<std::int64_t>(std::llround(n * host_period_ns)); };
  sim::RandomSource timing_draws(sim::derive_seed(bench_.seed, {0x71AE5ull}));
  auto mark = [&](std::int64_t t, std::size_t c, std::int32_t phase, std::int8_t what, std::int64_t b, std::int64_t e) {
    if (marks_) (void)marks_->try_push(PlanMark{t, b, e, static_cast<std::int32_t>(c), phase, what});
  };

  // Paced: the least lateness of a batch in the current ClockFit-sized window (behind_schedule_s).
  constexpr auto kWindowNs = static_cast<std::int64_t>(kClockFitWindowS * 1e9);
  std::int64_t window_start = t0_ns_, window_least_late = std::numeric_limits<std::int64_t>::max();
  for (std::size_t n = 0; n < run_samples_ && !stop_.load(std::memory_order_relaxed); ++n) {
    const std::size_t pn = n % plan;
    std::size_t c = 0;
    while (pn >= case_begin_[c + 1]) ++c;
    const std::size_t k = pn - case_begin_[c];
    const std::size_t case_len = case_begin_[c + 1] - case_begin_[c];
    const std::int64_t t_n = time_of(n);
    // Paced: a batch goes out when its newest sample is due, as an ADC delivers samples only
    // after taking them (never early, at most one batch late).
    if (!options_.fast && n % batch == 0) {
      const std::int64_t due = time_of(std::min(n + batch, run_samples_) - 1);
      // Meanwhile the frames the receive chain held back go out when they are due.
      can_bus_.send_held_until(due);
      window_least_late = std::min(window_least_late, hal::monotonic_now_ns() - due);
      if (t_n - window_start >= kWindowNs) {
        behind_schedule_ns_ = std::max(behind_schedule_ns_, window_least_late);
        window_least_late = std::numeric_limits<std::int64_t>::max();
        window_start = t_n;
      }
    }

    // Plan markers at the sample they refer to.
    const auto& spans = sim_.cases[c].motion.spans;
    const std::size_t case_first = n - k;
    if (k == 0) {
      mark(t_n, c, -1, plan_event_t::MARK_CASE_START, t_n, time_of(case_first + case_len));
      // Encoders continue where the previous case (or plan pass) left them.
      for (auto& e : encoders_) {
        const auto& m = sim_.cases[c].motion;
        const double x_start = e.table ? m.table_angle_rad[0] : m.shaker_x_m[0];
        const double x_prev = n == 0 ? x_start : e.offset;  // offset holds the last position (below)
        e.offset = x_prev - x_start;
      }
    }
    for (std::size_t i = 0; i < spans.size(); ++i)
      if (spans[i].begin == k)
        mark(t_n, c, static_cast<std::int32_t>(i), plan_event_t::MARK_PHASE_START, t_n,
             time_of(case_first + spans[i].end));

    // Faults (simulated time).
    const double t_s = static_cast<double>(n) / rate_hz_;
    const auto& f = options_.faults;
    if (f.bus_off_at_s >= 0) {
      const bool want = t_s >= f.bus_off_at_s && t_s < f.bus_off_at_s + f.bus_off_s;
      if (want != bus_off) {
        std::uint8_t err[8]{};
        if (want) {
          can_bus_.queue(CAN_ERR_FLAG | CAN_ERR_BUSOFF, err, 8, false);
        } else {
          err[1] = CAN_ERR_CRTL_ACTIVE;
          can_bus_.queue(CAN_ERR_FLAG | CAN_ERR_RESTARTED | CAN_ERR_CRTL, err, 8, false);
        }
        bus_off = want;
      }
    }
    if (f.modbus_gone_at_s >= 0 && controllers_) {
      const bool want = t_s >= f.modbus_gone_at_s && t_s < f.modbus_gone_at_s + f.modbus_gone_s;
      if (want && !modbus_gone) {
        controllers_->stop();
        modbus_gone = true;
      } else if (!want && modbus_gone && n % ctrl_every == 0) {
        // Back on the same port, as a real controller comes back; until it binds, tried again
        // every 10 ms, and said once.
        std::string why;
        if (controllers_->restart(&why)) {
          modbus_gone = false;
        } else if (!restart_refused) {
          std::cerr << "inertia-daqd: warning: simulated bench: the controller server cannot come back yet (" << why
                    << "); trying again\n";
          restart_refused = true;
        }
      }
    }

    if (f.hang_at_s >= 0 && n == static_cast<std::size_t>(std::llround(f.hang_at_s * rate_hz_)))
      can_slot_->hang_until_ns.store(hal::monotonic_now_ns() + static_cast<std::int64_t>(f.hang_s * 1e9),
                                     std::memory_order_relaxed);

    // CAN: one FD frame per 16 channels, sample_index last. Nothing goes out while bus-off, nor
    // while the adapter reboots.
    if (!bus_off && !(n >= reset_at && n < reset_back)) {
      std::fill(payload.begin(), payload.end(), std::uint8_t{0});
      for (std::size_t i = 0; i <= nch; ++i) {
        std::int64_t raw;
        if (i < nch) {
          raw = std::llround(can_value(can_channels_[i], c, k) / kSimCanScale);
          raw = std::clamp<std::int64_t>(raw, std::numeric_limits<std::int32_t>::min() + 1,  // min: kSimCanNoReading
                                         std::numeric_limits<std::int32_t>::max());
          if (i == 0 && f.stuck_at_s >= 0) {  // a sensor whose output freezes (stuck ADC or cable)
            const bool want = t_s >= f.stuck_at_s && t_s < f.stuck_at_s + f.stuck_s;
            if (want && !stuck) stuck_raw = raw;
            stuck = want;
            if (stuck) raw = stuck_raw;
          }
          if (i == 0 && f.nan_at_s >= 0 && t_s >= f.nan_at_s && t_s < f.nan_at_s + f.nan_s)
            raw = static_cast<std::int32_t>(kSimCanNoReading);  // the sensor's output is NaN
        } else {
          raw = static_cast<std::int64_t>((n >= reset_back ? n - reset_back : n) & counter_mask);
        }
        const auto u = static_cast<std::uint32_t>(raw);
        std::uint8_t* p = payload.data() + 64 * (i / kSignalsPerFrame) + 4 * (i % kSignalsPerFrame);
        p[0] = static_cast<std::uint8_t>(u);
        p[1] = static_cast<std::uint8_t>(u >> 8);
        p[2] = static_cast<std::uint8_t>(u >> 16);
        p[3] = static_cast<std::uint8_t>(u >> 24);
      }
      const std::size_t before = can_bus_.pending.size();
      for (std::size_t g = 0; g < frames; ++g) {
        if (real_timing_ && timing_draws.uniform() < bench_.sim_timing.frame_loss) {
          ++frames_lost_;   // lost on the bus: its samples never arrive
          continue;
        }
        // A frame cut short: its payload ends where the counter (the last frame's last signal) starts.
        const bool cut = n == short_at && g + 1 == frames;
        can_bus_.queue(kSimCanBaseId + static_cast<std::uint32_t>(g), payload.data() + 64 * g,
                       cut ? 4 * (nch % kSignalsPerFrame) : 64, true);
        if (n == duplicate_at && g + 1 == frames) can_bus_.pending.push_back(can_bus_.pending.back());
      }
      if (n == swap_at) {
        held.assign(can_bus_.pending.begin() + static_cast<std::ptrdiff_t>(before), can_bus_.pending.end());
        can_bus_.pending.resize(before);
      } else if (!held.empty()) {
        can_bus_.pending.insert(can_bus_.pending.end(), held.begin(), held.end());
        held.clear();
      }
    }
    // Paced: the batch's newest sample is due now (the sleep above), so the whole batch goes out
    // together, in one call.
    if ((n + 1) % batch == 0 || n + 1 == run_samples_) {
      if (real_timing_ && bench_.sim_timing.jitter_s > 0.0 && !can_bus_.pending.empty()) {
        // The batch arrives a while after it was due (an ADC's transfer, a driver, a busy host):
        // its software receive stamps carry that, as real ones do. Exponential: one-sided, a long
        // tail.
        const double u = std::max(timing_draws.uniform(), 1e-12);
        can_bus_.hold_until(t_n + static_cast<std::int64_t>(-std::log(u) * bench_.sim_timing.jitter_s * 1e9));
      }
      can_bus_.flush();
    }

    // Encoders: the edges since the previous sample, then the sample clock's trigger edge,
    // queued and written a batch at a time (about 1 ms, at most ~2000 edges a line). The wire's
    // clock (EncoderWire::advance) tells the device how far each line is complete, so it merges
    // the lines in time order however its reads interleave with these writes.
    for (auto& e : encoders_) {
      const double x = position(e, c, k);
      const auto target = static_cast<std::int64_t>(std::floor(x / e.resolution));
      if (e.bus.fd.get() >= 0) {  // a CAN encoder: the count latched on this tick, one frame
        std::array<std::uint8_t, kCounterFrameBytes> frame{};
        // An incremental counter counts from where it started, as the GPIO decoder does.
        const auto count = static_cast<std::uint64_t>(target - e.count);
        for (std::size_t b = 0; b < 8; ++b) frame[b] = static_cast<std::uint8_t>(count >> (8 * b));
        for (std::size_t b = 0; b < 4; ++b) frame[8 + b] = static_cast<std::uint8_t>(n >> (8 * b));
        e.bus.queue(e.can_id, frame.data(), frame.size(), true);
        if ((n + 1) % batch == 0 || n + 1 == run_samples_) e.bus.flush();
        continue;
      }
      const std::int64_t steps = target - e.count;
      const std::int64_t m = steps < 0 ? -steps : steps;
      const std::int64_t t_prev = n == 0 ? t_n - static_cast<std::int64_t>(period_ns) : time_of(n - 1);
      for (std::int64_t j = 0; j < m; ++j) {
        const int s = mod4(e.count);
        gp::EdgeLine line;
        bool rising;
        if (steps > 0) {  // forward: 0->1 A up, 1->2 B up, 2->3 A down, 3->0 B down
          line = (s == 0 || s == 2) ? gp::EdgeLine::A : gp::EdgeLine::B;
          rising = s <= 1;
          ++e.count;
        } else {          // backward: 1->0 A down, 2->1 B down, 3->2 A up, 0->3 B up
          line = (s == 1 || s == 3) ? gp::EdgeLine::A : gp::EdgeLine::B;
          rising = s == 3 || s == 0;
          --e.count;
        }
        const std::int64_t t_edge = t_prev + (t_n - t_prev) * (j + 1) / (m + 1);
        if (line == gp::EdgeLine::A && f.gpio_overflow_at_s >= 0 && t_s >= f.gpio_overflow_at_s &&
            e.overflowed < f.gpio_overflow_edges) {
          ++e.overflowed;   // the full FIFO drops it: the line moved, its event never comes
          continue;
        }
        queue_edge(e, line, rising, t_edge);
        if (f.glitch_every > 0 && ++e.edges % f.glitch_every == 0)
          queue_edge(e, line, rising, t_edge + 1);  // the same edge again: no level change, a glitch
      }
      e.trigger_level = !e.trigger_level;
      queue_edge(e, gp::EdgeLine::Trigger, e.trigger_level, t_n);
      const std::size_t ab = std::max(e.pending[0].size(), e.pending[1].size());
      if ((n + 1) % batch == 0 || ab >= 2048 || n + 1 == run_samples_) (void)flush_edges(e, t_n);
    }
    if (k == case_len - 1)
      for (auto& e : encoders_) e.offset = position(e, c, k);  // continuity into the next case

    if (controllers_ && !modbus_gone && n % ctrl_every == 0) {
      if (controller_clock_) wait_for_readings_before(t_n);
      update_controllers(c, k);
      if (controller_clock_) controller_clock_->reached_ns.store(t_n, std::memory_order_release);
    }

    for (std::size_t i = 0; i < spans.size(); ++i)
      if (spans[i].end == k + 1)
        mark(t_n, c, static_cast<std::int32_t>(i), plan_event_t::MARK_PHASE_END, time_of(case_first + spans[i].begin),
             t_n);
    if (k == case_len - 1) mark(t_n, c, -1, plan_event_t::MARK_CASE_END, time_of(case_first), t_n);
    written_.store(n + 1, std::memory_order_relaxed);
  }
  // What was simulated still goes out: the held frames when they are due, then (stopped early)
  // the batch in hand.
  can_bus_.send_all_held();
  can_bus_.flush();
  for (auto& e : encoders_) e.bus.flush();
  finished_.store(true, std::memory_order_release);
}

}  // namespace inertia::daq
