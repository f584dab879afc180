#include "daq/run_record.hpp"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <sstream>
#include <toml++/toml.h>

namespace inertia::daq {

std::string utc_now_text() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::optional<RunRecord> read_run_record(const std::filesystem::path& path, std::string* why) {
  std::error_code ec;
  if (path.empty() || !std::filesystem::exists(path, ec)) return std::nullopt;
  try {
    const toml::table t = toml::parse_file(path.string());
    RunRecord r;
    r.pid = t["pid"].value_or(0L);
    r.bench = t["bench"].value_or(std::string());
    r.started = t["started"].value_or(std::string());
    r.updated = t["updated"].value_or(std::string());
    r.ended = t["ended"].value_or(false);
    r.armed = t["armed"].value_or(false);
    r.activity = t["activity"].value_or(std::string());
    return r;
  } catch (const toml::parse_error& e) {
    if (why) *why = path.string() + ": not a run record (" + std::string(e.description()) + ")";
    return std::nullopt;
  }
}

RunRecorder::RunRecorder(std::filesystem::path path, std::string bench) : path_(std::move(path)) {
  previous_ = read_run_record(path_, &previous_error_);
  current_.pid = static_cast<long>(::getpid());
  current_.bench = std::move(bench);
  current_.started = utc_now_text();
}

bool RunRecorder::update(bool armed, const std::string& activity, std::string* why) {
  std::lock_guard lock(mutex_);
  current_.armed = armed;
  current_.activity = activity;
  current_.ended = false;
  return write(why);
}

bool RunRecorder::end(const std::string& activity, std::string* why) {
  std::lock_guard lock(mutex_);
  current_.armed = false;
  current_.activity = activity;
  current_.ended = true;
  return write(why);
}

bool RunRecorder::write(std::string* why) {
  if (path_.empty()) return true;
  current_.updated = utc_now_text();
  toml::table t{{"pid", static_cast<std::int64_t>(current_.pid)}, {"bench", current_.bench},   {"started", current_.started},
                {"updated", current_.updated},                    {"ended", current_.ended},   {"armed", current_.armed},
                {"activity", current_.activity}};
  std::ostringstream text;
  text << "# inertia-daqd's run record: what this run last did with the bench (daq/run_record.hpp)\n" << t << "\n";
  const std::string body = text.str();
  const std::filesystem::path temporary = path_.string() + ".new";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
  auto fail = [&](const char* what) {
    if (why) *why = path_.string() + ": " + what + ": " + std::strerror(errno);
    return false;
  };
  if (fd < 0) return fail("create");
  const bool written = ::write(fd, body.data(), body.size()) == static_cast<ssize_t>(body.size()) && ::fsync(fd) == 0;
  ::close(fd);
  if (!written) return fail("write");
  if (::rename(temporary.c_str(), path_.c_str()) != 0) return fail("rename");
  return true;
}

}  // namespace inertia::daq
