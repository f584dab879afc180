#pragma once
// What one run of inertia-daqd on a real bench leaves for the next: whether it ended by itself,
// and what it was doing with the machinery when it last said. A daemon that was killed
// (SIGKILL, a crash, the OOM killer, the watchdog) leaves its last transition; the next start
// journals it beside what it finds on the controllers, and starts disarmed, in the safe state.
// The file is TOML, rewritten whole at each transition (a new file renamed over the old and
// fsynced), so a crash leaves either the previous or the new text, never a mix.
// Thread: any (a mutex); not real-time (file I/O at each transition: arm, case, phase, abort).
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>

namespace inertia::daq {

struct RunRecord {
  long pid = 0;
  std::string bench;
  std::string started;            // UTC, ISO 8601
  std::string updated;            // UTC, ISO 8601: the newest transition
  bool ended = false;             // the daemon stopped by itself (SIGTERM, SIGINT, --duration)
  bool armed = false;
  std::string activity;           // "disarmed, safe state held", "case table, phase 1 (rotation)", ...
};

/// The record at `path`: nullopt when there is none; `why` set (and nullopt) when it cannot be read.
std::optional<RunRecord> read_run_record(const std::filesystem::path& path, std::string* why);

/// The current run's record at `path` (empty path: none is kept).
class RunRecorder {
 public:
  RunRecorder(std::filesystem::path path, std::string bench);
  /// The record the previous run left (read once, at construction), if any.
  [[nodiscard]] const std::optional<RunRecord>& previous() const noexcept { return previous_; }
  [[nodiscard]] const std::string& previous_error() const noexcept { return previous_error_; }
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }
  /// Records a transition; false with why when the file could not be written.
  bool update(bool armed, const std::string& activity, std::string* why = nullptr);
  /// The daemon stops by itself: the record says it ended.
  bool end(const std::string& activity, std::string* why = nullptr);

 private:
  bool write(std::string* why);
  std::filesystem::path path_;
  std::optional<RunRecord> previous_;
  std::string previous_error_;
  std::mutex mutex_;
  RunRecord current_;
};

/// "2026-11-27T23:40:43Z" for now.
std::string utc_now_text();

}  // namespace inertia::daq
