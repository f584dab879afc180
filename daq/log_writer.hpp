#pragma once
// The durable event log (docs/design.md: "UDP can drop; the log cannot: the log is the record").
// Every message the publisher sends is copied into a slot of a preallocated pool and handed to
// the writer thread through an SPSC ring; the writer appends it in LCM's log format
// (lcm_eventlog, so lcm-logplayer replays it and lcm-spy decodes it) with one write() per
// record, and rotates the file at a size limit or on request (SIGHUP). A syncer thread fsyncs
// every fsync_interval_ms beside it.
//
// Crash bounds (docs/bench-pc.md "Crash safety"): a record is in the kernel once written, so a SIGKILL of
// the daemon loses only what waits in the queue: the writer drains it every 2 ms and never
// waits on an fsync, so about one block. A power cut loses what the last fsync did not cover:
// one fsync interval, plus the fsync in progress.
//
// A disk stall blocks only the writer thread: the publisher never waits. While the writer is
// stuck, slots fill; when none is free the message is counted in messages_lost() (reported on
// INERTIA_STATUS and at exit), never dropped silently. With the default pool (512 slots of
// 64 KiB) a nominal 10 kHz bench (~200 messages/s) rides out a stall of more than 2 s.
//
// A full disk (ENOSPC, EDQUOT): each message goes to the file in one write (the record built
// here in LCM's log layout), and a write that fails is cut back off the file, so the file holds
// whole records only and a missing block shows as a gap in `seq`. The writer keeps draining the
// queue, counts every message it could not write (messages_lost(), disk_full_lost()), reports
// disk_full() while it lasts (on INERTIA_STATUS and once on stderr, the journal) and writes
// again as soon as a write succeeds.
#include <lcm/eventlog.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "common/spsc_ring.hpp"

namespace inertia::daq {

struct LogWriterOptions {
  std::filesystem::path dir;            // where the files go; created if missing
  std::string base_name = "inertia";    // files: <base>-<YYYYmmdd-HHMMSS>-<NNN>.lcmlog
  std::uint64_t rotate_bytes = 256ull << 20;  // start a new file past this size
  int fsync_interval_ms = 1000;         // fflush + fsync this often, on a thread of its own
  std::size_t queue_slots = 512;        // messages in flight between publisher and writer
  // Fault injection (tests, --fault log-stall): the writer sleeps stall_ms once, stall_after_s
  // after start, as a disk that stops answering would hold it.
  double stall_after_s = -1.0;
  int stall_ms = 0;
};

class LogWriter {
 public:
  static constexpr std::size_t kMaxChannel = 64;      // LCM_MAX_CHANNEL_NAME_LENGTH 63 + NUL
  static constexpr std::size_t kMaxData = 65536 - 128;  // one datagram's worth (sample_block_layout.hpp)

  explicit LogWriter(LogWriterOptions options);
  ~LogWriter();
  LogWriter(const LogWriter&) = delete;
  LogWriter& operator=(const LogWriter&) = delete;

  /// A message written first into every file (the first and each rotated one), so that any
  /// one file is self-contained (INERTIA_BENCH). Set before open(); control thread.
  void set_file_header(std::string channel, std::vector<std::uint8_t> data);

  /// Creates the directory and the first file. False + why (naming the path). Control thread.
  bool open(std::string* why);
  void start();
  /// Writes everything queued, fsyncs, closes. Call after the publisher stopped. Control thread.
  void stop();

  /// Copies one message into a free slot. Thread: the publisher only (SPSC producer).
  /// Real-time: no allocation, no lock, no wait; false (and counted) when no slot is free.
  bool enqueue(std::string_view channel, const void* data, std::size_t size, std::int64_t utime) noexcept;
  /// For fast simulated runs only (no real device is behind the caller, and the simulator waits
  /// for the samplers, which wait for the publisher): waits up to max_wait_ns for a free slot,
  /// then enqueue()s (a queue still full after that is counted as lost, as always).
  bool enqueue_waiting(std::string_view channel, const void* data, std::size_t size, std::int64_t utime,
                       std::int64_t max_wait_ns) noexcept;
  /// Async-signal-safe: the writer starts a new file at its next wake-up.
  void request_rotate() noexcept { rotate_requested_.store(true, std::memory_order_relaxed); }

  // Counters, any thread.
  /// Messages from the queue in the log (file headers not counted: see headers_written()).
  [[nodiscard]] std::uint64_t messages_written() const noexcept { return written_.load(std::memory_order_relaxed); }
  /// File headers written (one per file opened while a header is set): the log's records are
  /// messages_written() + headers_written().
  [[nodiscard]] std::uint64_t headers_written() const noexcept { return headers_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t messages_lost() const noexcept { return lost_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t bytes_written() const noexcept { return bytes_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint32_t rotations() const noexcept { return rotations_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t write_errors() const noexcept { return write_errors_.load(std::memory_order_relaxed); }
  [[nodiscard]] double fsync_last_ms() const noexcept { return fsync_last_us_.load(std::memory_order_relaxed) * 1e-3; }
  [[nodiscard]] double fsync_max_ms() const noexcept { return fsync_max_us_.load(std::memory_order_relaxed) * 1e-3; }
  [[nodiscard]] std::size_t queue_high_water() const noexcept { return queue_high_water_.load(std::memory_order_relaxed); }
  [[nodiscard]] bool stalled() const noexcept { return in_write_.load(std::memory_order_relaxed); }
  /// The last write failed for lack of space; clears with the next write that succeeds.
  [[nodiscard]] bool disk_full() const noexcept { return disk_full_.load(std::memory_order_relaxed); }
  /// Messages lost to a full disk (also in messages_lost()).
  [[nodiscard]] std::uint64_t disk_full_lost() const noexcept { return disk_full_lost_.load(std::memory_order_relaxed); }
  /// The file being written. Non-RT (copies under a mutex).
  [[nodiscard]] std::string current_path() const;
  /// Every file this writer created, in order. Non-RT.
  [[nodiscard]] std::vector<std::filesystem::path> files() const;

 private:
  struct Slot {
    std::int64_t utime;
    std::uint32_t channel_len;
    std::uint32_t data_len;
    char channel[kMaxChannel];
    std::uint8_t data[kMaxData];
  };
  void run() noexcept;
  /// Appends one record; 0, or the errno of the write that failed (the file is cut back).
  int append(const Slot& slot) noexcept;
  bool open_next(std::string* why);
  void sync() noexcept;
  void sync_locked() noexcept;   // file_mutex_ held
  /// The syncer thread: fflush + fsync every fsync_interval_ms, beside the writer, so that a slow
  /// fsync (a busy disk can take a second) never holds records in the queue, where a SIGKILL
  /// would lose them; what reached write() survives the process.
  void sync_loop() noexcept;
  void rotate() noexcept;
  void close_file() noexcept;

  LogWriterOptions options_;
  std::vector<Slot> pool_;
  SpscRing<std::uint32_t> free_;   // writer -> publisher: empty slots
  SpscRing<std::uint32_t> full_;   // publisher -> writer: slots to write
  lcm_eventlog_t* log_ = nullptr;
  std::uint64_t file_bytes_ = 0;
  int file_index_ = 0;
  std::string stamp_;
  std::string header_channel_;
  std::vector<std::uint8_t> header_data_;
  mutable std::mutex path_mutex_;  // guards files_ (writer appends on rotation; status reads)
  std::vector<std::filesystem::path> files_;
  std::thread thread_;
  std::thread syncer_;
  // Guards log_ between the writer (which alone changes it, on open and close) and the syncer.
  std::mutex file_mutex_;
  std::mutex syncer_mutex_;
  std::condition_variable syncer_wake_;
  bool syncer_stop_ = false;   // guarded by syncer_mutex_
  std::atomic<bool> stop_{false};
  std::atomic<bool> rotate_requested_{false};
  std::atomic<bool> in_write_{false};
  std::atomic<bool> disk_full_{false};
  std::atomic<std::uint64_t> disk_full_lost_{0};
  std::uint64_t full_since_lost_ = 0;   // disk_full_lost_ when the disk filled (writer thread)
  bool direct_ = false;                 // the FILE's buffer was flushed: records go straight to its fd
  std::atomic<std::uint64_t> written_{0}, lost_{0}, bytes_{0}, write_errors_{0}, headers_{0};
  std::atomic<std::uint32_t> rotations_{0};
  std::atomic<std::uint64_t> fsync_last_us_{0}, fsync_max_us_{0};
  std::atomic<std::size_t> queue_high_water_{0};
};

}  // namespace inertia::daq
