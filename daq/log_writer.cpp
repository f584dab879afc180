#include "daq/log_writer.hpp"

#include <pthread.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <system_error>

#include "daq/journal.hpp"
#include "hal/device.hpp"

namespace inertia::daq {

LogWriter::LogWriter(LogWriterOptions options)
    : options_(std::move(options)),
      pool_(options_.queue_slots),
      free_(options_.queue_slots),
      full_(options_.queue_slots) {
  // Every slot starts free. Touch the pool now so page faults happen here, not in a stall.
  for (std::uint32_t i = 0; i < pool_.size(); ++i) {
    std::memset(&pool_[i], 0, sizeof(Slot));
    (void)free_.try_push(i);
  }
}

LogWriter::~LogWriter() {
  stop();
  close_file();
}

void LogWriter::set_file_header(std::string channel, std::vector<std::uint8_t> data) {
  header_channel_ = std::move(channel);
  header_data_ = std::move(data);
}

bool LogWriter::open(std::string* why) {
  std::error_code ec;
  std::filesystem::create_directories(options_.dir, ec);
  if (ec) {
    if (why) *why = "log directory " + options_.dir.string() + ": " + ec.message();
    return false;
  }
  char buf[32];
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  ::localtime_r(&now, &tm);
  std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", &tm);
  stamp_ = buf;
  return open_next(why);
}

bool LogWriter::open_next(std::string* why) {
  char name[64];
  std::snprintf(name, sizeof name, "-%s-%03d.lcmlog", stamp_.c_str(), file_index_++);
  const std::filesystem::path path = options_.dir / (options_.base_name + name);
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "w");
  if (log == nullptr) {
    if (why) *why = "log file " + path.string() + ": " + std::strerror(errno);
    return false;
  }
  {
    std::lock_guard lock(file_mutex_);   // the syncer reads log_
    log_ = log;
  }
  file_bytes_ = 0;
  direct_ = false;
  if (!header_channel_.empty()) {
    timespec wall{};
    ::clock_gettime(CLOCK_REALTIME, &wall);
    lcm_eventlog_event_t event{};
    event.timestamp = static_cast<std::int64_t>(wall.tv_sec) * 1'000'000 + wall.tv_nsec / 1000;
    event.channellen = static_cast<std::int32_t>(header_channel_.size());
    event.datalen = static_cast<std::int32_t>(header_data_.size());
    event.channel = header_channel_.data();
    event.data = header_data_.data();
    if (lcm_eventlog_write_event(log_, &event) == 0) {
      const std::uint64_t n = 28u + header_channel_.size() + header_data_.size();
      file_bytes_ += n;
      bytes_.fetch_add(n, std::memory_order_relaxed);
      headers_.fetch_add(1, std::memory_order_relaxed);
    } else {
      write_errors_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  std::lock_guard lock(path_mutex_);
  files_.push_back(path);
  return true;
}

void LogWriter::close_file() noexcept {
  std::lock_guard lock(file_mutex_);
  if (log_ == nullptr) return;
  sync_locked();
  lcm_eventlog_destroy(log_);
  log_ = nullptr;
}

void LogWriter::sync() noexcept {
  std::lock_guard lock(file_mutex_);
  sync_locked();
}

void LogWriter::sync_loop() noexcept {
  ::pthread_setname_np(::pthread_self(), "log-sync");
  std::unique_lock lock(syncer_mutex_);
  while (!syncer_wake_.wait_for(lock, std::chrono::milliseconds(options_.fsync_interval_ms), [this] { return syncer_stop_; })) {
    lock.unlock();
    sync();
    lock.lock();
  }
}

void LogWriter::sync_locked() noexcept {
  if (log_ == nullptr) return;
  const std::int64_t t0 = hal::monotonic_now_ns();
  if (std::fflush(log_->f) != 0 || ::fsync(::fileno(log_->f)) != 0) write_errors_.fetch_add(1, std::memory_order_relaxed);
  const auto us = static_cast<std::uint64_t>((hal::monotonic_now_ns() - t0) / 1000);
  fsync_last_us_.store(us, std::memory_order_relaxed);
  if (us > fsync_max_us_.load(std::memory_order_relaxed)) fsync_max_us_.store(us, std::memory_order_relaxed);
}

std::string LogWriter::current_path() const {
  std::lock_guard lock(path_mutex_);
  return files_.empty() ? std::string() : files_.back().string();
}

std::vector<std::filesystem::path> LogWriter::files() const {
  std::lock_guard lock(path_mutex_);
  return files_;
}

void LogWriter::start() {
  thread_ = std::thread([this] { run(); });
  syncer_ = std::thread([this] { sync_loop(); });
}

void LogWriter::stop() {
  {
    std::lock_guard lock(syncer_mutex_);
    syncer_stop_ = true;
  }
  syncer_wake_.notify_all();
  if (syncer_.joinable()) syncer_.join();
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();   // drains the queue, then syncs once more
}

bool LogWriter::enqueue(std::string_view channel, const void* data, std::size_t size, std::int64_t utime) noexcept {
  std::uint32_t* index = free_.front();
  if (index == nullptr || channel.size() >= kMaxChannel || size > kMaxData) {
    lost_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const std::uint32_t i = *index;
  free_.pop();
  Slot& slot = pool_[i];
  slot.utime = utime;
  slot.channel_len = static_cast<std::uint32_t>(channel.size());
  std::memcpy(slot.channel, channel.data(), channel.size());
  slot.channel[channel.size()] = '\0';
  slot.data_len = static_cast<std::uint32_t>(size);
  std::memcpy(slot.data, data, size);
  (void)full_.try_push(i);  // cannot fail: as many indices as slots circulate
  const std::size_t depth = full_.size_approx();
  if (depth > queue_high_water_.load(std::memory_order_relaxed)) queue_high_water_.store(depth, std::memory_order_relaxed);
  return true;
}

bool LogWriter::enqueue_waiting(std::string_view channel, const void* data, std::size_t size, std::int64_t utime,
                                std::int64_t max_wait_ns) noexcept {
  const std::int64_t deadline = hal::monotonic_now_ns() + max_wait_ns;
  while (free_.front() == nullptr && hal::monotonic_now_ns() < deadline) {
    const timespec nap{0, 100'000};   // the writer frees a slot per record it writes
    ::nanosleep(&nap, nullptr);
  }
  return enqueue(channel, data, size, utime);
}

namespace {

void put_be(std::uint8_t* p, std::uint64_t v, int bytes) noexcept {
  for (int i = bytes - 1; i >= 0; --i, v >>= 8) p[i] = static_cast<std::uint8_t>(v);
}

}  // namespace

int LogWriter::append(const Slot& slot) noexcept {
  const int fd = ::fileno(log_->f);
  if (!direct_) {
    // Whatever went through stdio (a file header) must be on disk before records bypass it.
    direct_ = true;
    if (std::fflush(log_->f) != 0) {
      const int err = errno;
      (void)::ftruncate(fd, 0);  // glibc drops the unwritten buffer: keep no partial record
      (void)::lseek(fd, 0, SEEK_SET);
      file_bytes_ = 0;
      std::clearerr(log_->f);
      write_errors_.fetch_add(1, std::memory_order_relaxed);
      if (err == ENOSPC || err == EDQUOT) direct_ = false;  // try the header's flush again later
      return err;
    }
  }
  // LCM log record (lcm/eventlog.c): sync word, event number, utime, channel length, data
  // length (big-endian), channel, data. One writev per record: a failure can be cut back exactly.
  std::uint8_t header[28];
  put_be(header, 0xEDA1DA01u, 4);
  put_be(header + 4, static_cast<std::uint64_t>(log_->eventcount), 8);
  put_be(header + 12, static_cast<std::uint64_t>(slot.utime), 8);
  put_be(header + 20, slot.channel_len, 4);
  put_be(header + 24, slot.data_len, 4);
  iovec iov[3] = {{header, sizeof header},
                  {const_cast<char*>(slot.channel), slot.channel_len},
                  {const_cast<std::uint8_t*>(slot.data), slot.data_len}};
  const std::size_t total = sizeof header + slot.channel_len + slot.data_len;
  std::size_t done = 0;
  iovec* first = iov;
  int count = 3;
  while (done < total) {
    const ssize_t n = ::writev(fd, first, count);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      // Cut the partial record off: the file ends with the last whole one.
      if (done > 0 && ::ftruncate(fd, static_cast<off_t>(file_bytes_)) != 0) write_errors_.fetch_add(1, std::memory_order_relaxed);
      (void)::lseek(fd, static_cast<off_t>(file_bytes_), SEEK_SET);
      return err;
    }
    done += static_cast<std::size_t>(n);
    auto skip = static_cast<std::size_t>(n);  // a short write: go on after what went out
    while (count > 0 && skip >= first->iov_len) {
      skip -= first->iov_len;
      ++first;
      --count;
    }
    if (count > 0) {
      first->iov_base = static_cast<std::uint8_t*>(first->iov_base) + skip;
      first->iov_len -= skip;
    }
  }
  ++log_->eventcount;
  file_bytes_ += total;
  return 0;
}

void LogWriter::rotate() noexcept {
  close_file();
  std::string why;
  if (open_next(&why)) {
    rotations_.fetch_add(1, std::memory_order_relaxed);
  } else {
    write_errors_.fetch_add(1, std::memory_order_relaxed);  // messages now count as lost until a later rotate works
  }
}

void LogWriter::run() noexcept {
  ::pthread_setname_np(::pthread_self(), "log-writer");
  const std::int64_t start_ns = hal::monotonic_now_ns();
  bool stalled_once = false;
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    if (options_.stall_after_s >= 0.0 && !stalled_once &&
        hal::monotonic_now_ns() - start_ns >= static_cast<std::int64_t>(options_.stall_after_s * 1e9)) {
      // Injected disk stall: the writer is stuck as in a write() to a dead disk.
      stalled_once = true;
      in_write_.store(true, std::memory_order_relaxed);
      std::this_thread::sleep_for(std::chrono::milliseconds(options_.stall_ms));
      in_write_.store(false, std::memory_order_relaxed);
    }
    if (rotate_requested_.exchange(false, std::memory_order_relaxed)) rotate();
    std::size_t done = 0;
    while (std::uint32_t* index = full_.front()) {
      Slot& slot = pool_[*index];
      if (log_ != nullptr && file_bytes_ > 0 && file_bytes_ + 28 + slot.channel_len + slot.data_len > options_.rotate_bytes)
        rotate();  // a file never grows past the limit (unless one message alone exceeds it)
      if (log_ != nullptr) {
        in_write_.store(true, std::memory_order_relaxed);
        const int err = append(slot);
        in_write_.store(false, std::memory_order_relaxed);
        if (err == 0) {
          written_.fetch_add(1, std::memory_order_relaxed);
          bytes_.fetch_add(28u + slot.channel_len + slot.data_len, std::memory_order_relaxed);
          if (disk_full_.load(std::memory_order_relaxed)) {
            disk_full_.store(false, std::memory_order_relaxed);
            const std::uint64_t n = disk_full_lost_.load(std::memory_order_relaxed) - full_since_lost_;
            journal_fault({"log", "disk-full", "cleared",
                           "log: writing again to " + current_path() + " after " + std::to_string(n) +
                               " messages lost to the full disk",
                           6, std::nullopt, n});
          }
        } else if (err == ENOSPC || err == EDQUOT) {
          lost_.fetch_add(1, std::memory_order_relaxed);
          disk_full_lost_.fetch_add(1, std::memory_order_relaxed);
          if (!disk_full_.load(std::memory_order_relaxed)) {
            disk_full_.store(true, std::memory_order_relaxed);
            full_since_lost_ = disk_full_lost_.load(std::memory_order_relaxed) - 1;
            journal_fault({"log", "disk-full", "raised",
                           "log: disk full writing " + current_path() + " (" + std::strerror(err) +
                               "); sampling and publishing go on, messages that cannot be written are counted until space is back",
                           3, std::nullopt, std::nullopt});
          }
        } else {
          write_errors_.fetch_add(1, std::memory_order_relaxed);
          lost_.fetch_add(1, std::memory_order_relaxed);
        }
      } else {
        lost_.fetch_add(1, std::memory_order_relaxed);
      }
      const std::uint32_t i = *index;
      full_.pop();
      (void)free_.try_push(i);
      if (++done >= 64) break;  // look at rotation/sync requests between batches
    }
    if (done == 0) {
      if (stopping) break;  // queue empty after stop: the publisher has finished, all written
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  sync();
}

}  // namespace inertia::daq
