#pragma once
// Test harness for inertia-daqd: starts the real binary as a child process (with the environment
// systemd would give it), reads its durable log with lcm::LogFile, listens to its LCM stream on a
// private multicast port, and reads sd_notify datagrams from an AF_UNIX socket.
#include <fcntl.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/resource.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daq/daemon.hpp"
#include "tests/support/scratch_dirs.hpp"
#include "inertia/daq_status_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"
#include "tests/support/skip_or_fail.hpp"

namespace inertia::daq::testing {

namespace fs = std::filesystem;

inline std::string daqd_binary() { return (fs::path(INERTIA_BINARY_DIR) / "bin" / "inertia-daqd").string(); }
inline std::string source_path(const std::string& rel) { return std::string(INERTIA_SOURCE_DIR) + "/" + rel; }
/// A test name from a bench file's name: "sim-paper-daq.toml" -> "sim_paper_daq".
inline std::string bench_test_name(std::string file) {
  file = file.substr(0, file.find('.'));
  for (char& c : file)
    if (c == '-') c = '_';
  return file;
}

using inertia::testing::SmallDisk;
using inertia::testing::TempDir;

/// A multicast URL on a port private to this test process (CTest runs each test as a process).
inline std::string private_lcm_url() {
  static int counter = 0;
  const int port = 20000 + static_cast<int>((::getpid() * 7 + 13 * counter++) % 20000);
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

/// LCM cannot work here: the test skips, or fails under CI=true (the CI script adds the route).
inline bool lcm_route_missing() { return !has_multicast_route(); }
inline constexpr const char* kNoRouteMessage =
    "no multicast route: LCM cannot run here (fix: ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo)";
/// CI=true: the CI script (inertia.sh test) adds the multicast route, so a test that needs LCM
/// and finds no route there fails: skipping would pass a CI run that tested nothing.
inline bool running_in_ci() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}
/// In a test body: skip without a multicast route, fail instead under CI=true.
#define INERTIA_REQUIRE_LCM_ROUTE()                                                                   \
  do {                                                                                                \
    if (::inertia::daq::testing::lcm_route_missing()) {                                               \
      if (::inertia::daq::testing::running_in_ci()) FAIL() << ::inertia::daq::testing::kNoRouteMessage \
                                                          << " (CI=true: the CI script adds the route)"; \
      GTEST_SKIP() << ::inertia::daq::testing::kNoRouteMessage;                                       \
    }                                                                                                 \
  } while (0)

class DaqdProcess {
 public:
  /// `binary`: another build of the daemon (the benchmark's peer), default this build's.
  /// `in_child`: runs in the child before exec (e.g. a private mount namespace); the child
  /// exits 126 when it returns false.
  DaqdProcess(const std::vector<std::string>& args, const std::vector<std::string>& extra_env, const fs::path& stderr_file,
              const std::string& binary = daqd_binary(), const std::function<bool()>& in_child = {})
      : stderr_file_(stderr_file) {
    pid_ = ::fork();
    if (pid_ == 0) {
      if (in_child && !in_child()) ::_exit(126);
      const int fd = ::open(stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, 2);
        ::dup2(fd, 1);
      }
      std::vector<std::string> argv_s{binary};
      argv_s.insert(argv_s.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (auto& a : argv_s) argv.push_back(a.data());
      argv.push_back(nullptr);
      std::vector<std::string> env_s;
      for (char** e = environ; *e != nullptr; ++e) env_s.emplace_back(*e);
      env_s.insert(env_s.end(), extra_env.begin(), extra_env.end());
      std::vector<char*> envp;
      for (auto& e : env_s) envp.push_back(e.data());
      envp.push_back(nullptr);
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
  }
  ~DaqdProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      ::waitpid(pid_, &st, 0);
    }
  }
  DaqdProcess(const DaqdProcess&) = delete;
  DaqdProcess& operator=(const DaqdProcess&) = delete;

  void signal(int sig) const { ::kill(pid_, sig); }
  /// Exit status, or -1 after timeout (then the process is killed), or 128+signal.
  int wait(double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      int st = 0;
      const pid_t r = ::wait4(pid_, &st, WNOHANG, &usage_);
      if (r == pid_) {
        exited_ = true;
        return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ::kill(pid_, SIGKILL);
    int st = 0;
    ::waitpid(pid_, &st, 0);
    exited_ = true;
    return -1;
  }
  [[nodiscard]] std::string output() const {
    std::ifstream in(stderr_file_);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  [[nodiscard]] pid_t pid() const { return pid_; }
  /// CPU seconds (user + system) of the exited process.
  [[nodiscard]] double cpu_seconds() const {
    return static_cast<double>(usage_.ru_utime.tv_sec + usage_.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(usage_.ru_utime.tv_usec + usage_.ru_stime.tv_usec);
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  rusage usage_{};
  fs::path stderr_file_;
};

/// The text after `key` on the summary line of `device` ("  accel: samples 123, ..."); empty
/// when the line or the key is missing.
inline std::string summary_field(const std::string& out, const std::string& line_prefix, const std::string& key) {
  const auto at = out.find(line_prefix);
  if (at == std::string::npos) return {};
  const auto eol = out.find('\n', at);
  const std::string line = out.substr(at, eol - at);
  const auto k = line.find(key + " ");
  if (k == std::string::npos) return {};
  return line.substr(k + key.size() + 1);
}

/// The number after `key` on the summary line of `device`; -1 when missing.
inline double summary_number(const std::string& out, const std::string& line_prefix, const std::string& key) {
  const std::string field = summary_field(out, line_prefix, key);
  return field.empty() ? -1 : std::stod(field);
}

inline long long summary_value(const std::string& out, const std::string& line_prefix, const std::string& key) {
  const std::string field = summary_field(out, line_prefix, key);
  return field.empty() ? -1 : std::stoll(field);
}

/// How far the simulator fell behind its own schedule (ms), from the daemon's closing line
/// "simulated bench: at most X ms behind its schedule"; nullopt when the line is missing.
inline std::optional<double> sim_schedule_lag_ms(const std::string& daqd_out) {
  std::smatch m;
  if (!std::regex_search(daqd_out, m, std::regex(R"(simulated bench: at most ([0-9.]+) ms behind its schedule)")))
    return std::nullopt;
  return std::stod(m[1]);
}

struct LogEvent {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t utime = 0;
};

/// Every event of every *.lcmlog in `dir`, files in name order (the writer numbers them).
inline std::vector<LogEvent> read_log_dir(const fs::path& dir, std::size_t* files = nullptr) {
  std::vector<fs::path> paths;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".lcmlog") paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  if (files) *files = paths.size();
  std::vector<LogEvent> out;
  for (const auto& p : paths) {
    lcm::LogFile log(p.string(), "r");
    if (!log.good()) continue;
    while (const lcm::LogEvent* ev = log.readNextEvent()) {
      const auto* d = static_cast<const std::uint8_t*>(ev->data);
      out.push_back({ev->channel, std::vector<std::uint8_t>(d, d + ev->datalen), ev->timestamp});
    }
  }
  return out;
}

template <class T>
std::vector<T> decode_all(const std::vector<LogEvent>& events, const std::string& channel) {
  std::vector<T> out;
  for (const auto& e : events) {
    if (e.channel != channel) continue;
    T m;
    if (m.decode(e.data.data(), 0, static_cast<int>(e.data.size())) >= 0) out.push_back(std::move(m));
  }
  return out;
}

/// Collects every message on the URL in a background thread.
class LcmCollector {
 public:
  explicit LcmCollector(const std::string& url) : lcm_(url + "&recv_buf_size=8388608") {
    if (!lcm_.good()) return;
    auto* sub = lcm_.subscribe(".*", &LcmCollector::on_message, this);
    sub->setQueueCapacity(100000);
    thread_ = std::thread([this] {
      while (!stop_) lcm_.handleTimeout(50);
    });
  }
  ~LcmCollector() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  [[nodiscard]] bool good() { return lcm_.good(); }
  struct Received {
    std::string channel;
    std::vector<std::uint8_t> data;
    std::int64_t mono_ns;
    std::int64_t recv_utime;  // LCM's receive time (ReceiveBuffer::recv_utime), wall clock
  };
  std::vector<Received> take() {
    std::lock_guard lock(mutex_);
    return received_;
  }
  std::size_t count() {
    std::lock_guard lock(mutex_);
    return received_.size();
  }

 private:
  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    const auto* d = static_cast<const std::uint8_t*>(rbuf->data);
    std::lock_guard lock(mutex_);
    received_.push_back({channel, std::vector<std::uint8_t>(d, d + rbuf->data_size),
                         static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec, rbuf->recv_utime});
  }
  lcm::LCM lcm_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::vector<Received> received_;
};

/// An AF_UNIX datagram socket standing in for systemd's notify socket.
class NotifySocket {
 public:
  explicit NotifySocket(const fs::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  }
  ~NotifySocket() { ::close(fd_); }
  /// Next datagram within timeout, or "" on timeout.
  std::string receive(double timeout_s) {
    timeval tv{static_cast<time_t>(timeout_s), static_cast<suseconds_t>((timeout_s - static_cast<long>(timeout_s)) * 1e6)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
    return n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  int fd_ = -1;
  fs::path path_;
};

/// Sequence continuity of one device's blocks (docs/design.md, the LCM channels): block seq +1 each, every
/// channel's channel_seq continuing where the previous block ended. Returns the gaps found.
inline std::int64_t sequence_gaps(const std::vector<sample_block_t>& blocks) {
  std::int64_t gaps = 0;
  for (std::size_t i = 1; i < blocks.size(); ++i) {
    if (blocks[i].seq != blocks[i - 1].seq + 1) ++gaps;
    for (std::size_t c = 0; c < blocks[i].channel_seq.size(); ++c)
      if (blocks[i].channel_seq[c] != blocks[i - 1].channel_seq[c] + blocks[i - 1].num_samples) ++gaps;
  }
  if (!blocks.empty() && blocks[0].seq != 0) ++gaps;
  return gaps;
}

inline int channel_index(const sample_block_t& b, const std::string& name) {
  for (std::size_t i = 0; i < b.channel_names.size(); ++i)
    if (b.channel_names[i] == name) return static_cast<int>(i);
  return -1;
}

}  // namespace inertia::daq::testing
