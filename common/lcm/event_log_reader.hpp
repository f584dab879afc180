#pragma once
// Reading an LCM event log (the daemon's durable log, or lcm-logger's) record by record, as a
// reader of outside bytes must: the file may end inside a record (a writer killed mid-write) or
// hold anything at all.
//
// Why not lcm::LogFile: liblcm 1.3.1 (eventlog.c) allocates whatever a record's header claims
// (up to 2 GiB for one corrupt length field) before it reads, and tells neither a torn tail nor
// garbage from the end of the file. Here a record's data length is checked against the bytes the
// file still has before anything is allocated, and the reader says why it stopped.
//
// Format (lcm/eventlog.c; every integer big-endian): sync word 0xEDA1DA01, int64 event number,
// int64 timestamp (us), int32 channel length, int32 data length, the channel's bytes (no NUL),
// the data.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace inertia {

struct LogRecord {
  std::int64_t event_number = 0;
  std::int64_t utime = 0;          // the logger's receive time, us since the Unix epoch
  std::string channel;
  std::vector<std::uint8_t> data;  // the encoded message
  std::uint64_t offset = 0;        // byte offset of the record's sync word in the file
};

class EventLogReader {
 public:
  /// Longest channel name accepted (eventlog.c refuses 1000 and more as well).
  static constexpr std::int32_t kMaxChannelLength = 999;

  /// Opens `file`. Throws InputError (naming the file) when it cannot be opened or does not start
  /// with the sync word: then it is not an LCM event log at all.
  explicit EventLogReader(const std::filesystem::path& file);
  ~EventLogReader();
  EventLogReader(const EventLogReader&) = delete;
  EventLogReader& operator=(const EventLogReader&) = delete;

  /// The next whole record into `record`; false when there is none. Reading stops for good at
  /// the end of the file, at a record the file ends inside (a torn tail: its header or its data
  /// runs past the end) and at bytes that are not a record (no sync word, a channel length
  /// outside 1..kMaxChannelLength, a negative data length). stop_reason() then says which, with
  /// the byte offset; every whole record before it has been returned. Allocates at most the
  /// file's size. Thread: one reader per object. Not real-time.
  bool next(LogRecord& record);

  /// Empty while reading and after a clean end of file; otherwise why reading stopped early, e.g.
  /// "the log ends inside event 12 at byte 3456 (its data needs 4000 bytes, 17 remain)".
  [[nodiscard]] const std::string& stop_reason() const noexcept { return stop_reason_; }
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  [[nodiscard]] std::int64_t records_read() const noexcept { return records_; }

 private:
  bool stop(std::string reason);

  std::filesystem::path file_;
  std::FILE* stream_ = nullptr;
  std::uint64_t size_ = 0;
  std::uint64_t offset_ = 0;
  std::int64_t records_ = 0;
  bool stopped_ = false;
  std::string stop_reason_;
};

}  // namespace inertia
