#pragma once
// A device that decodes CAN frames into samples by a signal map (docs/design.md: CAN-attached ADC
// modules, kernel receive timestamps). It reads from ANY descriptor that carries one
// struct can_frame (16 bytes) or struct canfd_frame (72 bytes) per record: in production a
// CAN_RAW socket; in tests and the simulator one end of a socketpair(AF_UNIX, SOCK_SEQPACKET).
#include <sys/socket.h>
#include <sys/uio.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hal/device.hpp"
#include "hal/socketcan/frame_counter.hpp"
#include "hal/socketcan/frame_map.hpp"
#include "hal/unique_fd.hpp"

namespace inertia::hal::socketcan {

struct CanDeviceConfig {
  std::string name = "can";               // device name; channels are "<name>.<signal>"
  std::string interface = "can0";         // for open_interface()
  CanFrameMap map;
  std::size_t max_records_per_read = 64;  // bound on the work of one read_into() call
  // Receive up to kReceiveBatch records per system call (recvmmsg). Off: one recvmsg per record,
  // the path taken anyway when the kernel refuses recvmmsg (ENOSYS, e.g. under a seccomp filter).
  bool batch_receive = true;
  // The adapter's frame rate: one frame of each id per sample. It times the frame counters
  // (frame_counter.hpp: roll-overs across a silence, resets) and sizes the receive buffer.
  // 0: unknown (counters by value alone, the kernel's default buffer).
  double frame_rate_hz = 0.0;
  // The socket's receive buffer is asked to hold this long of frames (SO_RCVBUF; the kernel caps
  // it at net.core.rmem_max unless the process has CAP_NET_ADMIN; receive_buffer() says what it gave).
  double receive_buffer_s = 1.0;
  // CLOCK_REALTIME, to map the receive stamps to CLOCK_MONOTONIC (tests step it); null: the clock.
  std::int64_t (*realtime_ns)() noexcept = nullptr;
  bool is_valid(std::string* why) const;
};

/// Controller state from error frames (linux/can/error.h; kernel doc networking/can.rst 3.4).
enum class BusState { ErrorActive, ErrorWarning, ErrorPassive, BusOff };

/// CAN-specific health, beside DeviceHealth. Thread: the sampling thread.
struct CanStatus {
  BusState bus_state = BusState::ErrorActive;
  std::uint64_t classic_frames = 0, fd_frames = 0;
  std::uint64_t unknown_ids = 0;          // data frames whose id is not in the map (ignored)
  std::uint64_t remote_frames = 0;        // RTR frames (ignored)
  std::uint64_t error_frames = 0;
  std::uint64_t bus_off_events = 0, restarts = 0;
  std::uint64_t controller_overflows = 0; // CAN_ERR_CRTL_{RX,TX}_OVERFLOW
  std::uint64_t protocol_errors = 0;      // CAN_ERR_PROT / CAN_ERR_BUSERROR / CAN_ERR_ACK
  std::uint8_t tx_error_count = 0, rx_error_count = 0;  // from CAN_ERR_CNT error frames
  std::uint64_t kernel_timestamps = 0;    // frames stamped from the SCM_TIMESTAMPNS cmsg
  std::uint64_t receive_calls = 0;        // recvmmsg/recvmsg system calls that returned records
  bool peer_closed = false;               // a stream end (socketpair peer gone; never on CAN_RAW)
  bool link_down = false;                 // the interface went away or down (ENODEV, ENETDOWN): see CanLinkWatch
  std::uint64_t link_losses = 0;          // times it did
  std::uint64_t link_reopens = 0;         // times a new socket took the old one's place (adopt())
  // Frames refused so that no sample number is given twice (frame_counter.hpp), and resets.
  std::uint64_t counter_resets = 0;       // a frame counter restarted: a new segment, marked to the sink
  std::uint64_t short_frames = 0;         // too short to hold their frame's counter
  std::uint64_t duplicate_frames = 0;     // the newest counter again
  std::uint64_t out_of_order_frames = 0;  // a counter behind the newest
  std::uint64_t range_faults = 0;         // readings outside their signal's [min, max]: pushed invalid
  std::uint64_t kernel_drops = 0;         // frames the kernel dropped on a full receive buffer (SO_RXQ_OVFL)
  std::uint64_t clock_steps = 0;          // CLOCK_REALTIME stepped since the previous read (see read_into)
};

/// What the receive buffer was asked to hold and what the kernel gave (bytes, as SO_RCVBUF
/// reports them: twice the payload the kernel lets in, for its bookkeeping). 0: left as it was.
struct ReceiveBuffer {
  std::size_t wanted = 0;
  std::size_t granted = 0;
};

/// What a received record's control messages carry: the SCM_TIMESTAMPNS receive stamp
/// (CLOCK_REALTIME ns; 0 when absent) and the socket's SO_RXQ_OVFL count (frames the kernel
/// dropped since the socket opened; absent on sockets that do not report it). Real-time safe.
struct ReceiveControl {
  std::int64_t realtime_ns = 0;
  bool has_drops = false;
  std::uint32_t drops = 0;
};
ReceiveControl read_receive_control(const msghdr& msg) noexcept;

const char* to_string(BusState state) noexcept;

/// A CAN_RAW socket bound to `interface` by name (its index looked up now, so a re-plugged
/// adapter's new index is found). An invalid descriptor with the reason otherwise. Non-RT.
UniqueFd open_can_raw(const std::string& interface, std::string* why);

class CanDevice final : public Device {
 public:
  static constexpr std::size_t kMaxRecordsPerReadLimit = 1024;
  /// Records one recvmmsg() call takes at most. One system call per CAN frame costs more than
  /// decoding the frame (perf on the simulated 10 kHz bench; docs/validation.md, 'Evidence behind
  /// choices in the code'); 64 records bound the buffers to a few KiB.
  static constexpr std::size_t kReceiveBatch = 64;

  /// Opens a CAN_RAW socket on config.interface. nullptr with the reason when that is impossible,
  /// e.g. on a kernel without SocketCAN ("socket(PF_CAN, SOCK_RAW, CAN_RAW): Address family not
  /// supported by protocol: this kernel has no SocketCAN (CONFIG_CAN)"). Non-RT.
  static std::unique_ptr<CanDevice> open_interface(const CanDeviceConfig& config, std::string* why);
  /// Takes ownership of a descriptor carrying can_frame/canfd_frame records: a CAN_RAW socket or
  /// a SOCK_SEQPACKET/SOCK_DGRAM socket (record boundaries kept). Stream sockets and non-sockets
  /// are refused, since record boundaries would be lost. Non-RT.
  static std::unique_ptr<CanDevice> from_fd(UniqueFd fd, const CanDeviceConfig& config, std::string* why);

  [[nodiscard]] std::string_view name() const noexcept override { return config_.name; }
  [[nodiscard]] const std::string& interface() const noexcept { return config_.interface; }
  [[nodiscard]] std::span<const std::string> channel_names() const noexcept override { return channels_; }

  /// Non-RT. Makes the descriptor non-blocking, turns on SO_TIMESTAMPNS and SO_RXQ_OVFL and
  /// sizes the receive buffer for receive_buffer_s of frames; on a CAN_RAW socket also
  /// CAN_RAW_FD_FRAMES, receive filters from the map's ids and the error-frame mask.
  Step configure() override;
  /// Non-RT. Discards records queued before activation.
  Step activate() override;
  /// Thread: sampling thread. Real-time: recvmmsg(MSG_DONTWAIT) (or recvmsg, see
  /// CanDeviceConfig::batch_receive) into member buffers, no allocation, no lock; at most
  /// config.max_records_per_read records per call.
  /// Timestamps: the SCM_TIMESTAMPNS cmsg (CLOCK_REALTIME, software rx stamp) mapped to
  /// CLOCK_MONOTONIC with the realtime-monotonic offset read once per call; without the cmsg,
  /// CLOCK_MONOTONIC at reception. A stamp is never later than its record was received. When the
  /// offset moved since the previous call by more than a clock discipline slews in the time
  /// between (a step of CLOCK_REALTIME: NTP setting the clock at boot), the records of this call
  /// may have been stamped before or after the step; none of their stamps is used: each gets the
  /// time it was received instead, which is late but never early, so it cannot pull a device's
  /// clock fit (daq/clock_fit.hpp follows the earliest stamps). Counted in clock_steps.
  /// Frames whose counter is a duplicate, out of order or missing (a short frame) are refused
  /// and counted; a counter's restart pushes kSegmentStart before the frame's samples.
  std::size_t read_into(SampleSink& sink) noexcept override;
  Step deactivate() override;
  [[nodiscard]] int wait_fd() const noexcept override { return fd_.get(); }

  [[nodiscard]] const CanStatus& status() const noexcept { return status_; }

  /// The socket's interface went away or down, or its peer closed (a socketpair): nothing comes
  /// until adopt() puts a new socket in its place. Thread: any (CanLinkWatch asks).
  [[nodiscard]] bool link_down() const noexcept { return link_down_.load(std::memory_order_acquire); }
  /// The controller was bus-off at the last read. Thread: any.
  [[nodiscard]] bool bus_off() const noexcept { return bus_off_.load(std::memory_order_relaxed); }
  /// Non-RT (CanLinkWatch's thread): sets `fd` up as configure() set the first socket and puts
  /// it in the old descriptor's place (dup3, so the number waited on stays); the sampling thread's
  /// next read takes it, with the controller's state `state`, and counts a reopen.
  bool adopt(UniqueFd fd, BusState state, std::string* why);
  /// Non-RT: the controller's state as the interface reports it, for the sampling thread's next
  /// read (a bus-off the kernel's restart frame did not clear, e.g. ip link set down and up).
  void set_bus_state(BusState state) noexcept;
  [[nodiscard]] const ReceiveBuffer& receive_buffer() const noexcept { return receive_buffer_; }
  [[nodiscard]] bool is_can_socket() const noexcept { return is_can_socket_; }
  /// A CAN FD frame's share of a receive buffer (its socket buffer's true size in the kernel:
  /// the frame, the sk_buff and its shared info), for sizing SO_RCVBUF.
  static constexpr std::size_t kBufferBytesPerFrame = 1024;
  /// How far the realtime-monotonic offset may move between two reads without being a step: the
  /// scatter of reading two clocks, plus what a clock discipline slews in (at most 500 ppm).
  static constexpr std::int64_t kOffsetScatterNs = 50'000;
  static constexpr double kSlewRate = 5e-4;

 private:
  CanDevice(UniqueFd fd, CanDeviceConfig config, bool is_can_socket);
  std::size_t handle_record(const std::uint8_t* bytes, std::size_t size, std::int64_t t_ns,
                            SampleSink& sink) noexcept;
  void handle_error_frame(std::uint32_t can_id, const std::uint8_t* data, std::size_t len) noexcept;
  /// A `wraps` signal's value: its raw bits unwrapped to 64 bits, scaled. Real-time safe.
  double unwrapped_count(std::uint64_t raw, const CompiledFrameMap::Entry& e) noexcept;
  bool drain() noexcept;
  /// Receives up to `want` (<= kReceiveBatch) records into batch_; their count, 0 when nothing
  /// is pending, -1 on an error other than "nothing pending" (counted in io_errors).
  int receive(std::size_t want) noexcept;

  UniqueFd fd_;
  CanDeviceConfig config_;
  bool is_can_socket_ = false;
  bool configured_ = false;
  bool active_ = false;
  CompiledFrameMap map_;
  std::int64_t realtime_now_ns() const noexcept;
  void size_receive_buffer(int fd) noexcept;
  /// Non-blocking, timestamps, drop count, buffer; on a CAN_RAW socket FD frames, filters.
  bool prepare(int fd, bool can_socket, std::string* why);
  /// Whether a receive error means the interface is gone (counted, link_down set). Sampling thread.
  bool gone(int err) noexcept;

  // Per frame key with a counter signal: its unwrapping (sampling thread).
  struct CounterState {
    std::uint32_t key = 0;
    FrameCounter counter;
  };
  std::vector<CounterState> counters_;
  // Per channel of a `wraps` signal: its newest raw bits and the 64-bit count they unwrap to.
  struct WrapState {
    bool seen = false;
    std::uint64_t raw = 0;
    std::int64_t count = 0;
  };
  std::vector<WrapState> wraps_;
  // The realtime-monotonic offset at the previous read_into(), and when it was read.
  bool have_offset_ = false;
  std::int64_t offset_ns_ = 0, offset_at_ns_ = 0;
  ReceiveBuffer receive_buffer_;
  // Between the sampling thread and CanLinkWatch's (see adopt()).
  std::atomic<bool> link_down_{false}, bus_off_{false};
  std::atomic<bool> link_restored_{false}, state_posted_{false};
  std::atomic<int> restored_state_{0};
  std::vector<std::string> channels_;
  CanStatus status_;
  bool batch_receive_ = true;
  // One receive slot per record of a batch: one record plus one byte, so an oversized record
  // shows up as a size (MSG_TRUNC covers SEQPACKET; the extra byte covers descriptors that do
  // not report it), and room for the timestamp cmsg. The headers point into these arrays, set
  // up once in the constructor (the device is never moved).
  struct ReceiveSlot {
    alignas(8) std::array<std::uint8_t, 73> record{};
    alignas(8) std::array<std::uint8_t, 64> control{};
  };
  std::array<ReceiveSlot, kReceiveBatch> batch_{};
  std::array<iovec, kReceiveBatch> iov_{};
  std::array<mmsghdr, kReceiveBatch> headers_{};
};

}  // namespace inertia::hal::socketcan
