// Faults on the systemd journal as structured entries: the real daemon, in a private
// mount namespace whose /run holds a socket of ours at /run/systemd/journal/socket, so that
// sd_journal_send's datagrams (the journal's native protocol, KEY=VALUE lines) come to the test
// as they would come to journald. Skipped where a mount namespace cannot be made (not root).
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/mount.h>
#include <sys/stat.h>

#include <map>

#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

using Entry = std::map<std::string, std::string>;

/// Binds the journal's socket under `run` and collects every entry sent to it.
class JournalSocket {
 public:
  explicit JournalSocket(const fs::path& run) {
    fs::create_directories(run / "systemd" / "journal");
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", (run / "systemd" / "journal" / "socket").c_str());
    bound_ = ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    timeval tv{0, 100'000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    thread_ = std::thread([this] {
      char buf[65536];
      while (!stop_) {
        const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
        if (n <= 0) continue;
        Entry e;
        std::istringstream in(std::string(buf, static_cast<std::size_t>(n)));
        std::string line;
        while (std::getline(in, line)) {
          const auto eq = line.find('=');
          if (eq != std::string::npos) e[line.substr(0, eq)] = line.substr(eq + 1);
        }
        std::lock_guard lock(mutex_);
        entries_.push_back(std::move(e));
      }
    });
  }
  ~JournalSocket() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  [[nodiscard]] bool bound() const { return bound_; }
  std::vector<Entry> entries() {
    std::lock_guard lock(mutex_);
    return entries_;
  }

 private:
  int fd_ = -1;
  bool bound_ = false;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::mutex mutex_;
  std::vector<Entry> entries_;
};

/// In the child: a mount namespace of its own with `run` on /run. False when refused.
bool private_run(const fs::path& run) {
  return ::unshare(CLONE_NEWNS) == 0 && ::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) == 0 &&
         ::mount(run.c_str(), "/run", nullptr, MS_BIND, nullptr) == 0;
}

/// Whether this process may make one (tried in a throw-away child).
bool mount_namespace_allowed(const fs::path& run) {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(private_run(run) ? 0 : 1);
  int st = 0;
  ::waitpid(pid, &st, 0);
  return WIFEXITED(st) && WEXITSTATUS(st) == 0;
}

const Entry* find(const std::vector<Entry>& entries, const std::string& device, const std::string& fault,
                  const std::string& state) {
  for (const Entry& e : entries) {
    const auto get = [&e](const char* k) { return e.count(k) ? e.at(k) : std::string(); };
    if (get("DEVICE") == device && get("FAULT") == fault && get("FAULT_STATE") == state) return &e;
  }
  return nullptr;
}

TEST(DaqdJournal, ABusOffIsAStructuredEntryWithTheSamplesItCost) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const fs::path run = tmp.path / "run";
  fs::create_directories(run);
  if (!mount_namespace_allowed(run))
    INERTIA_SKIP_OR_FAIL_IN_CI("cannot make a private mount namespace here (needs root): no journal socket to stand in");
  JournalSocket journal(run);
  ASSERT_TRUE(journal.bound());
  // Under systemd stderr is a journal stream named by JOURNAL_STREAM: the daemon then leaves the
  // plain line out (the structured entry carries the same MESSAGE).
  const fs::path err = tmp.path / "stderr.txt";
  std::ofstream(err).flush();
  struct stat st{};
  ASSERT_EQ(::stat(err.c_str(), &st), 0);
  const std::string stream = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  // Paced 3.5 s; bus-off from 0.5 s for 1.2 s: 12000 rows of the 10 kHz CAN device never sent.
  DaqdProcess daqd({"--config", source_path("tests/integration/configs/daq-small.toml"), "--duration", "3.5", "--lcm-url",
                    private_lcm_url(), "--fault", "bus-off@0.5+1.2"},
                   {"JOURNAL_STREAM=" + stream}, err, daqd_binary(), [run] { return private_run(run); });
  ASSERT_EQ(daqd.wait(60), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto entries = journal.entries();
  const Entry* raised = find(entries, "accel", "bus-off", "raised");
  const Entry* cleared = find(entries, "accel", "bus-off", "cleared");
  ASSERT_NE(raised, nullptr) << entries.size() << " entries\n" << daqd.output();
  ASSERT_NE(cleared, nullptr) << daqd.output();
  EXPECT_EQ(raised->at("MESSAGE"), "inertia-daqd: accel: fault bus-off");
  EXPECT_EQ(raised->at("PRIORITY"), "4");
  EXPECT_EQ(raised->at("SYSLOG_IDENTIFIER"), "inertia-daqd");
  EXPECT_EQ(raised->count("SAMPLES_LOST"), 0u);
  // Nominal rate x the window minus what arrived: the 12000 rows of the outage, give or take
  // what was still on its way at the window's ends (the supervisor looks once a second).
  ASSERT_EQ(cleared->count("SAMPLES_LOST"), 1u);
  const long long lost = std::stoll(cleared->at("SAMPLES_LOST"));
  EXPECT_NEAR(static_cast<double>(lost), 12000.0, 1000.0);
  EXPECT_NE(cleared->at("MESSAGE").find("accel: cleared bus-off (" + cleared->at("SAMPLES_LOST") + " samples per channel"),
            std::string::npos);
  // stderr is "the journal" here: the fault lines are not printed twice.
  EXPECT_EQ(daqd.output().find("fault bus-off"), std::string::npos) << daqd.output();
  // Only faults, every one with its device.
  for (const Entry& e : entries) EXPECT_EQ(e.count("DEVICE"), 1u);
}

}  // namespace
}  // namespace inertia::daq::testing
