#include "hal/socketcan/can_device.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <utility>

namespace inertia::hal::socketcan {
namespace {

static_assert(sizeof(can_frame) == CAN_MTU && CAN_MTU == 16);
static_assert(sizeof(canfd_frame) == CANFD_MTU && CANFD_MTU == 72);

std::string errno_text(const char* what, int err) { return std::string(what) + ": " + std::strerror(err); }

std::int64_t clock_ns(clockid_t clock) noexcept {
  timespec ts{};
  ::clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

ReceiveControl read_receive_control(const msghdr& msg) noexcept {
  ReceiveControl out;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(const_cast<msghdr*>(&msg), c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      out.realtime_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
      std::memcpy(&out.drops, CMSG_DATA(c), sizeof out.drops);
      out.has_drops = true;
    }
  }
  return out;
}

const char* to_string(BusState state) noexcept {
  switch (state) {
    case BusState::ErrorActive: return "error-active";
    case BusState::ErrorWarning: return "error-warning";
    case BusState::ErrorPassive: return "error-passive";
    case BusState::BusOff: return "bus-off";
  }
  return "?";
}

bool CanDeviceConfig::is_valid(std::string* why) const {
  if (name.empty()) {
    if (why) *why = "CAN device: empty name";
    return false;
  }
  if (max_records_per_read < 1 || max_records_per_read > CanDevice::kMaxRecordsPerReadLimit) {
    if (why) *why = "CAN device '" + name + "': max_records_per_read " + std::to_string(max_records_per_read) +
                    " is outside 1.." + std::to_string(CanDevice::kMaxRecordsPerReadLimit);
    return false;
  }
  std::string inner;
  if (!map.is_valid(&inner)) {
    if (why) *why = "CAN device '" + name + "': " + inner;
    return false;
  }
  if (!std::isfinite(frame_rate_hz) || frame_rate_hz < 0.0 || !std::isfinite(receive_buffer_s) || receive_buffer_s < 0.0) {
    if (why) *why = "CAN device '" + name + "': frame_rate_hz and receive_buffer_s must be finite and >= 0";
    return false;
  }
  return true;
}

UniqueFd open_can_raw(const std::string& interface, std::string* why) {
  UniqueFd fd(::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW));
  if (!fd.valid()) {
    const int err = errno;
    if (why) {
      *why = errno_text("socket(PF_CAN, SOCK_RAW, CAN_RAW)", err);
      if (err == EAFNOSUPPORT) *why += ": this kernel has no SocketCAN (CONFIG_CAN), so '" + interface + "' cannot be opened";
    }
    return UniqueFd();
  }
  const unsigned index = ::if_nametoindex(interface.c_str());
  if (index == 0) {
    if (why) *why = errno_text(("CAN interface '" + interface + "'").c_str(), errno);
    return UniqueFd();
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    if (why) *why = errno_text(("bind to CAN interface '" + interface + "'").c_str(), errno);
    return UniqueFd();
  }
  return fd;
}

std::unique_ptr<CanDevice> CanDevice::open_interface(const CanDeviceConfig& config, std::string* why) {
  if (!config.is_valid(why)) return nullptr;
  UniqueFd fd = open_can_raw(config.interface, why);
  if (!fd.valid()) return nullptr;
  return from_fd(std::move(fd), config, why);
}

std::unique_ptr<CanDevice> CanDevice::from_fd(UniqueFd fd, const CanDeviceConfig& config, std::string* why) {
  if (!config.is_valid(why)) return nullptr;
  int type = 0;
  int domain = 0;
  socklen_t len = sizeof type;
  if (::getsockopt(fd.get(), SOL_SOCKET, SO_TYPE, &type, &len) != 0) {
    if (why) *why = errno_text("CAN device: descriptor is not a record socket (SO_TYPE)", errno);
    return nullptr;
  }
  len = sizeof domain;
  if (::getsockopt(fd.get(), SOL_SOCKET, SO_DOMAIN, &domain, &len) != 0) domain = AF_UNSPEC;
  if (type != SOCK_RAW && type != SOCK_SEQPACKET && type != SOCK_DGRAM) {
    if (why) *why = "CAN device: the descriptor is a stream socket; CAN records need record boundaries "
                    "(CAN_RAW, SOCK_SEQPACKET or SOCK_DGRAM)";
    return nullptr;
  }
  return std::unique_ptr<CanDevice>(new CanDevice(std::move(fd), config, domain == AF_CAN));
}

CanDevice::CanDevice(UniqueFd fd, CanDeviceConfig config, bool is_can_socket)
    : fd_(std::move(fd)),
      config_(std::move(config)),
      is_can_socket_(is_can_socket),
      map_(config_.map),
      batch_receive_(config_.batch_receive) {
  channels_.reserve(config_.map.signals.size());
  wraps_.resize(config_.map.signals.size());
  const double period_ns = config_.frame_rate_hz > 0.0 ? 1e9 / config_.frame_rate_hz : 0.0;
  for (const CanSignal& s : config_.map.signals) {
    channels_.push_back(config_.name + "." + s.name);
    if (s.counter) counters_.push_back(CounterState{frame_key(s.id, s.extended), FrameCounter(s.bit_length, period_ns)});
  }
  for (std::size_t i = 0; i < kReceiveBatch; ++i) {
    iov_[i] = iovec{batch_[i].record.data(), batch_[i].record.size()};
    headers_[i].msg_hdr.msg_iov = &iov_[i];
    headers_[i].msg_hdr.msg_iovlen = 1;
    headers_[i].msg_hdr.msg_control = batch_[i].control.data();
  }
}

bool CanDevice::prepare(int fd, bool can_socket, std::string* why) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) != 0) {
    if (why) *why = errno_text("fcntl(O_NONBLOCK)", errno);
    return false;
  }
  const int on = 1;
  // Without the stamp the device still works: frames get CLOCK_MONOTONIC at reception.
  (void)::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  // The kernel's count of frames it dropped on a full receive buffer, with every record.
  (void)::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
  size_receive_buffer(fd);
  if (!can_socket) return true;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0) {
    if (why) *why = errno_text("setsockopt(CAN_RAW_FD_FRAMES)", errno);
    return false;
  }
  std::vector<can_filter> filters;
  for (std::uint32_t key : map_.keys()) {
    const bool eff = (key & CAN_EFF_FLAG) != 0;
    // RTR in the mask: only data frames pass; the EFF flag keeps 0x123 and 0x00000123 apart.
    filters.push_back(can_filter{key, CAN_EFF_FLAG | CAN_RTR_FLAG | (eff ? CAN_EFF_MASK : CAN_SFF_MASK)});
  }
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(), static_cast<socklen_t>(filters.size() * sizeof(can_filter))) !=
      0) {
    if (why) *why = errno_text("setsockopt(CAN_RAW_FILTER)", errno);
    return false;
  }
  // Bus errors (CAN_ERR_BUSERROR, CAN_ERR_PROT) may flood; state changes are what we track.
  const can_err_mask_t mask = CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED | CAN_ERR_CNT;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) != 0) {
    if (why) *why = errno_text("setsockopt(CAN_RAW_ERR_FILTER)", errno);
    return false;
  }
  return true;
}

Step CanDevice::configure() {
  std::string why;
  if (!prepare(fd_.get(), is_can_socket_, &why)) return fail(Step::Fatal, why);
  configured_ = true;
  return ok();
}

bool CanDevice::adopt(UniqueFd fd, BusState state, std::string* why) {
  int domain = AF_UNSPEC;
  socklen_t len = sizeof domain;
  if (::getsockopt(fd.get(), SOL_SOCKET, SO_DOMAIN, &domain, &len) != 0) domain = AF_UNSPEC;
  if (!prepare(fd.get(), domain == AF_CAN, why)) return false;
  // In the old descriptor's place: the sampling thread's next receive, and its poll, use it.
  if (::dup3(fd.get(), fd_.get(), O_CLOEXEC) < 0) {
    if (why) *why = errno_text("dup3 onto the device's descriptor", errno);
    return false;
  }
  restored_state_.store(static_cast<int>(state), std::memory_order_relaxed);
  link_restored_.store(true, std::memory_order_release);
  link_down_.store(false, std::memory_order_release);   // the next read takes the new socket
  return true;
}

void CanDevice::set_bus_state(BusState state) noexcept {
  restored_state_.store(static_cast<int>(state), std::memory_order_relaxed);
  state_posted_.store(true, std::memory_order_release);
}

void CanDevice::size_receive_buffer(int fd) noexcept {
  receive_buffer_ = ReceiveBuffer{};
  if (config_.frame_rate_hz <= 0.0 || config_.receive_buffer_s <= 0.0) return;
  // One frame of every id per sample period.
  const double frames = config_.frame_rate_hz * static_cast<double>(map_.keys().size()) * config_.receive_buffer_s;
  const double wanted = std::min(frames * static_cast<double>(kBufferBytesPerFrame), static_cast<double>(INT_MAX));
  int have = 0;
  socklen_t len = sizeof have;
  if (::getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &have, &len) != 0) return;
  receive_buffer_.wanted = static_cast<std::size_t>(wanted);
  receive_buffer_.granted = static_cast<std::size_t>(have);
  if (static_cast<double>(have) >= wanted) return;   // never shrink a buffer someone made larger
  // The kernel doubles what it is given (its bookkeeping) and reports the double. Beyond
  // net.core.rmem_max only with CAP_NET_ADMIN (SO_RCVBUFFORCE); otherwise capped there.
  const int ask = static_cast<int>(wanted / 2.0);
  if (::setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &ask, sizeof ask) != 0)
    (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &ask, sizeof ask);
  len = sizeof have;
  if (::getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &have, &len) == 0) receive_buffer_.granted = static_cast<std::size_t>(have);
}

std::int64_t CanDevice::realtime_now_ns() const noexcept {
  return config_.realtime_ns != nullptr ? config_.realtime_ns() : clock_ns(CLOCK_REALTIME);
}

bool CanDevice::drain() noexcept {
  // Bounded so a peer that writes forever cannot hold the control thread here.
  for (int i = 0; i < 100000; ++i) {
    const ssize_t n = ::recv(fd_.get(), batch_[0].record.data(), batch_[0].record.size(), MSG_DONTWAIT);
    if (n > 0) continue;
    if (n < 0 && errno == EINTR) continue;
    return true;
  }
  return false;
}

Step CanDevice::activate() {
  if (!configured_) return fail(Step::Fatal, "activate() before configure()");
  drain();
  active_ = true;
  return ok();
}

Step CanDevice::deactivate() {
  active_ = false;
  return ok();
}

int CanDevice::receive(std::size_t want) noexcept {
  for (std::size_t i = 0; i < want; ++i) {  // the kernel shrinks these per record
    headers_[i].msg_hdr.msg_controllen = batch_[i].control.size();
    headers_[i].msg_hdr.msg_flags = 0;
    headers_[i].msg_len = 0;
  }
  while (batch_receive_) {
    const int got = ::recvmmsg(fd_.get(), headers_.data(), static_cast<unsigned>(want), MSG_DONTWAIT, nullptr);
    if (got >= 0) {
      if (got > 0) ++status_.receive_calls;
      return got;
    }
    if (errno == EINTR) continue;
    if (errno == ENOSYS) {
      batch_receive_ = false;  // for good (an old kernel or a seccomp filter): one by one below
      break;
    }
    if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
    if (gone(errno)) return -1;
    ++health_.io_errors;
    return -1;
  }
  std::size_t n = 0;
  while (n < want) {
    const ssize_t len = ::recvmsg(fd_.get(), &headers_[n].msg_hdr, MSG_DONTWAIT);
    if (len < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) {
        if (!gone(errno)) ++health_.io_errors;
        if (n == 0) return -1;
      }
      break;
    }
    ++status_.receive_calls;
    headers_[n++].msg_len = static_cast<unsigned>(len);
    if (len == 0) break;  // end of file: nothing follows it
  }
  return static_cast<int>(n);
}

bool CanDevice::gone(int err) noexcept {
  // The interface was unregistered (a USB adapter pulled: ENODEV, the socket is unbound) or set
  // down (ENETDOWN): nothing more comes on this socket until it is opened again.
  if (err != ENODEV && err != ENETDOWN && err != ENXIO) return false;
  ++status_.link_losses;
  status_.link_down = true;
  link_down_.store(true, std::memory_order_release);
  return true;
}

std::size_t CanDevice::read_into(SampleSink& sink) noexcept {
  if (!active_) return 0;
  if (link_restored_.exchange(false, std::memory_order_acquire)) {
    // A new socket in the descriptor's place (adopt()): the interface is back.
    status_.bus_state = static_cast<BusState>(restored_state_.load(std::memory_order_relaxed));
    status_.link_down = false;
    status_.peer_closed = false;
    ++status_.link_reopens;
    link_down_.store(false, std::memory_order_release);
    have_offset_ = false;
  } else if (state_posted_.exchange(false, std::memory_order_acquire)) {
    status_.bus_state = static_cast<BusState>(restored_state_.load(std::memory_order_relaxed));
  }
  if (status_.link_down || status_.peer_closed) return 0;   // nothing comes on this socket until it is opened again
  const std::int64_t t_start = monotonic_now_ns();
  // SCM_TIMESTAMPNS is CLOCK_REALTIME; one offset per call maps it to CLOCK_MONOTONIC. A step of
  // CLOCK_REALTIME since the previous call may lie between a record's stamp and this offset, so
  // this call's stamps are not used (see the header).
  const std::int64_t realtime_minus_mono = realtime_now_ns() - t_start;
  bool stepped = false;
  if (have_offset_) {
    const double allowed = static_cast<double>(kOffsetScatterNs) + kSlewRate * static_cast<double>(t_start - offset_at_ns_);
    stepped = std::abs(static_cast<double>(realtime_minus_mono - offset_ns_)) > allowed;
    if (stepped) ++status_.clock_steps;
  }
  have_offset_ = true;
  offset_ns_ = realtime_minus_mono;
  offset_at_ns_ = t_start;
  std::size_t pushed = 0;
  std::size_t records = 0;
  while (records < config_.max_records_per_read) {
    const std::size_t want = std::min(kReceiveBatch, config_.max_records_per_read - records);
    const int got = receive(want);
    if (got <= 0) break;
    const std::int64_t received = monotonic_now_ns();   // every record of the batch was in by now
    for (int r = 0; r < got; ++r) {
      const msghdr& msg = headers_[static_cast<std::size_t>(r)].msg_hdr;
      const std::size_t size = headers_[static_cast<std::size_t>(r)].msg_len;
      ++records;
      if (size == 0) {
        // A CAN_RAW socket never reads 0; a socketpair does once the peer is gone (recvmmsg then
        // fills the rest of the batch with the same end of file).
        status_.peer_closed = true;
        break;
      }
      const ReceiveControl control = read_receive_control(msg);
      if (control.has_drops) status_.kernel_drops = control.drops;
      std::int64_t t_ns = received;
      if (control.realtime_ns != 0 && !stepped) {
        t_ns = std::min(control.realtime_ns - realtime_minus_mono, received);
        ++status_.kernel_timestamps;
      }
      if ((msg.msg_flags & MSG_TRUNC) != 0) {
        ++health_.malformed;
        continue;
      }
      pushed += handle_record(batch_[static_cast<std::size_t>(r)].record.data(), size, t_ns, sink);
    }
    if (static_cast<std::size_t>(got) < want) break;  // drained: spare the call that says so
  }
  // For CanLinkWatch: whether this socket has gone quiet for good, and the controller's state.
  if (status_.peer_closed) link_down_.store(true, std::memory_order_release);
  bus_off_.store(status_.bus_state == BusState::BusOff, std::memory_order_relaxed);
  const double us = static_cast<double>(monotonic_now_ns() - t_start) * 1e-3;
  if (us > health_.read_time_max_us) health_.read_time_max_us = us;
  return pushed;
}

std::size_t CanDevice::handle_record(const std::uint8_t* bytes, std::size_t size, std::int64_t t_ns,
                                     SampleSink& sink) noexcept {
  // Classic and FD records share the layout of their first 8 bytes (id, len); the size tells
  // them apart (kernel doc networking/can.rst 4.1.5).
  std::uint32_t can_id = 0;
  std::size_t len = 0;
  const std::uint8_t* data = nullptr;
  if (size == CAN_MTU) {
    const auto* f = reinterpret_cast<const can_frame*>(bytes);
    can_id = f->can_id;
    len = f->len;
    data = f->data;
    if (len > CAN_MAX_DLEN) {
      ++health_.malformed;
      return 0;
    }
    ++status_.classic_frames;
  } else if (size == CANFD_MTU) {
    const auto* f = reinterpret_cast<const canfd_frame*>(bytes);
    can_id = f->can_id;
    len = f->len;
    data = f->data;
    if (len > CANFD_MAX_DLEN) {
      ++health_.malformed;
      return 0;
    }
    ++status_.fd_frames;
  } else {
    ++health_.malformed;
    return 0;
  }
  if ((can_id & CAN_ERR_FLAG) != 0) {
    handle_error_frame(can_id, data, len);
    return 0;
  }
  if ((can_id & CAN_RTR_FLAG) != 0) {
    ++status_.remote_frames;
    return 0;
  }
  const bool eff = (can_id & CAN_EFF_FLAG) != 0;
  const auto entries = map_.find(frame_key(can_id & (eff ? CAN_EFF_MASK : CAN_SFF_MASK), eff));
  if (entries.empty()) {
    ++status_.unknown_ids;
    return 0;
  }
  const std::span<const std::uint8_t> payload(data, len);
  // The frame's sample number, when the map gives it a counter (frame_counter.hpp). A frame that
  // cannot be numbered, or whose number was given already, is refused whole: its samples would
  // take the place of others.
  std::int64_t index = kNoSampleIndex;
  for (const CompiledFrameMap::Entry& e : entries) {
    if (!e.signal.counter) continue;
    if (bytes_needed(e.signal) > len) {
      ++status_.short_frames;
      return 0;
    }
    const std::uint32_t key = e.key;
    auto state = std::find_if(counters_.begin(), counters_.end(), [key](const CounterState& c) { return c.key == key; });
    if (state == counters_.end()) break;   // built in the constructor: every counter's key is there
    const FrameCounter::Result numbered = state->counter.take(extract_raw(payload, e.signal), t_ns);
    switch (numbered.verdict) {
      case FrameCounter::Verdict::Duplicate:
        ++status_.duplicate_frames;
        return 0;
      case FrameCounter::Verdict::OutOfOrder:
        ++status_.out_of_order_frames;
        return 0;
      case FrameCounter::Verdict::Reset:
        ++status_.counter_resets;
        if (!sink.push(kSegmentStart, t_ns, 0.0, false, numbered.index)) ++health_.sink_drops;
        break;
      case FrameCounter::Verdict::First:
      case FrameCounter::Verdict::Next: break;
    }
    index = numbered.index;
    break;
  }
  std::size_t pushed = 0;
  for (const CompiledFrameMap::Entry& e : entries) {
    bool valid = true;
    double value = 0.0;
    if (bytes_needed(e.signal) > len) {
      ++health_.decode_errors;  // the frame is shorter than the map says: push the gap, marked
      valid = false;
    } else {
      const std::uint64_t raw = extract_raw(payload, e.signal);
      valid = !is_invalid_raw(raw, e.signal);  // the sender said "no reading": marked, never a number
      value = !valid ? kNoReading : e.signal.wraps ? unwrapped_count(raw, e) : to_value(raw, e.signal);
      if (valid && (value < e.signal.min || value > e.signal.max)) {
        valid = false;   // implausible: kept as read, marked, counted
        ++status_.range_faults;
      }
    }
    if (sink.push(e.channel, t_ns, value, valid, index)) {
      ++health_.samples;
      ++pushed;
    } else {
      ++health_.sink_drops;
    }
  }
  return pushed;
}

double CanDevice::unwrapped_count(std::uint64_t raw, const CompiledFrameMap::Entry& e) noexcept {
  const int bits = e.signal.bit_length;
  const std::uint64_t mask = bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
  // The raw bits as the signal's integer (two's complement when signed).
  auto as_integer = [&](std::uint64_t v) {
    if (e.signal.is_signed && bits < 64 && (v & (std::uint64_t{1} << (bits - 1))) != 0) v |= ~mask;
    return static_cast<std::int64_t>(v);
  };
  WrapState& w = wraps_[e.channel];
  if (!w.seen) {
    w.seen = true;
    w.count = as_integer(raw);
  } else {
    // The shortest step between the two readings, modulo 2^bit_length.
    std::uint64_t step = (raw - w.raw) & mask;
    if (bits < 64 && (step & (std::uint64_t{1} << (bits - 1))) != 0) step |= ~mask;
    w.count += static_cast<std::int64_t>(step);
  }
  w.raw = raw;
  return e.signal.scale * static_cast<double>(w.count) + e.signal.offset;
}

void CanDevice::handle_error_frame(std::uint32_t can_id, const std::uint8_t* data, std::size_t len) noexcept {
  ++status_.error_frames;
  const std::uint32_t cls = can_id & CAN_ERR_MASK;
  if ((cls & CAN_ERR_CRTL) != 0 && len > 1) {
    const std::uint8_t crtl = data[1];
    if ((crtl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0) ++status_.controller_overflows;
    if (status_.bus_state != BusState::BusOff) {
      if ((crtl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0)
        status_.bus_state = BusState::ErrorPassive;
      else if ((crtl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0)
        status_.bus_state = BusState::ErrorWarning;
      else if ((crtl & CAN_ERR_CRTL_ACTIVE) != 0)
        status_.bus_state = BusState::ErrorActive;
    }
  }
  if ((cls & (CAN_ERR_PROT | CAN_ERR_BUSERROR | CAN_ERR_ACK)) != 0) ++status_.protocol_errors;
  if ((cls & CAN_ERR_CNT) != 0 && len > 7) {
    status_.tx_error_count = data[6];
    status_.rx_error_count = data[7];
  }
  if ((cls & CAN_ERR_BUSOFF) != 0) {
    if (status_.bus_state != BusState::BusOff) ++status_.bus_off_events;
    status_.bus_state = BusState::BusOff;
  }
  // The controller leaves bus-off only by a restart (manual or restart-ms); the kernel then
  // sends CAN_ERR_RESTARTED.
  if ((cls & CAN_ERR_RESTARTED) != 0) {
    ++status_.restarts;
    status_.bus_state = BusState::ErrorActive;
  }
}

}  // namespace inertia::hal::socketcan
