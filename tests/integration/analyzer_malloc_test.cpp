// inertia-analyze sets glibc's malloc tunables for its analysis (analyzer/main.cpp,
// configure_malloc): it runs itself again with them in GLIBC_TUNABLES where the kernel has
// transparent huge pages, and leaves a caller's own malloc tunables as they are; that run sets
// OpenMP's wait policy to passive unless the caller set one. Observed from
// the kernel: the running analyzer's environment (/proc/PID/environ), the real binary, the PID the
// test started.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/child_process.hpp"
#include "tests/support/files.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

bool huge_pages_available() {
  std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string modes;
  return std::getline(mode, modes) && modes.find("[never]") == std::string::npos;
}

struct AnalyzerRun {
  std::optional<std::string> tunables;      // GLIBC_TUNABLES as the running analyzer's environment shows it
  std::optional<std::string> wait_policy;   // OMP_WAIT_POLICY likewise
  int status = -1;                          // exit status; -1: still running after 60 s (killed)
};

/// Runs a simulation of the paper plan (about a second) with GLIBC_TUNABLES = `given` (none:
/// unset): its environment as the kernel shows it 0.3 s after the start (the one its image was
/// started with), and how it ended. A run that started itself over and over would never end.
AnalyzerRun run_analyzer(const std::optional<std::string>& given, const fs::path& dir) {
  const char* before = std::getenv("GLIBC_TUNABLES");
  const std::optional<std::string> restore = before != nullptr ? std::optional<std::string>(before) : std::nullopt;
  if (given) {
    ::setenv("GLIBC_TUNABLES", given->c_str(), 1);
  } else {
    ::unsetenv("GLIBC_TUNABLES");
  }
  const pid_t pid = testing::start_child({testing::analyze_binary(), "simulate", "--bench",
                                          std::string(INERTIA_SOURCE_DIR) + "/config/sim-paper.toml", "--out",
                                          (dir / "dataset").string()},
                                         dir / "simulate.txt");
  if (restore) {
    ::setenv("GLIBC_TUNABLES", restore->c_str(), 1);
  } else {
    ::unsetenv("GLIBC_TUNABLES");
  }
  AnalyzerRun run;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  {
    std::ifstream in("/proc/" + std::to_string(pid) + "/environ", std::ios::binary);
    std::string entry;
    while (std::getline(in, entry, '\0'))
      if (entry.rfind("GLIBC_TUNABLES=", 0) == 0) {
        run.tunables = entry.substr(15);
      } else if (entry.rfind("OMP_WAIT_POLICY=", 0) == 0) {
        run.wait_policy = entry.substr(16);
      }
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return run;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  run.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return run;
}

TEST(AnalyzerMalloc, RunsWithHugePageTunablesWhereTheKernelHasThem) {
  const testing::TempDir dir("inertia-analyzer-malloc");
  const AnalyzerRun run = run_analyzer(std::nullopt, dir.path);
  EXPECT_EQ(run.status, 0) << testing::text_of(dir.path / "simulate.txt");
  if (!huge_pages_available()) {
    EXPECT_FALSE(run.tunables.has_value()) << *run.tunables;
    return;
  }
  ASSERT_TRUE(run.tunables.has_value()) << "no GLIBC_TUNABLES in the running analyzer's environment";
  EXPECT_EQ(run.tunables->rfind("glibc.malloc.hugetlb=1", 0), 0U) << *run.tunables;
  EXPECT_EQ(run.wait_policy.value_or("(none)"), "passive");
}

TEST(AnalyzerMalloc, KeepsACallersOwnOpenMPWaitPolicy) {
  if (!huge_pages_available()) GTEST_SKIP() << "the kernel has no transparent huge pages: the analyzer runs as started";
  const testing::TempDir dir("inertia-analyzer-malloc");
  const char* before = std::getenv("OMP_WAIT_POLICY");
  const std::optional<std::string> restore = before != nullptr ? std::optional<std::string>(before) : std::nullopt;
  ::setenv("OMP_WAIT_POLICY", "active", 1);
  const AnalyzerRun run = run_analyzer(std::nullopt, dir.path);
  if (restore) {
    ::setenv("OMP_WAIT_POLICY", restore->c_str(), 1);
  } else {
    ::unsetenv("OMP_WAIT_POLICY");
  }
  EXPECT_EQ(run.status, 0) << testing::text_of(dir.path / "simulate.txt");
  ASSERT_TRUE(run.tunables.has_value());
  EXPECT_EQ(run.wait_policy.value_or("(none)"), "active");
}

TEST(AnalyzerMalloc, KeepsACallersOwnMallocTunables) {
  const testing::TempDir dir("inertia-analyzer-malloc");
  const std::string given = "glibc.malloc.arena_max=2";
  const AnalyzerRun run = run_analyzer(given, dir.path);
  EXPECT_EQ(run.status, 0) << testing::text_of(dir.path / "simulate.txt");
  ASSERT_TRUE(run.tunables.has_value());
  EXPECT_EQ(*run.tunables, given);
}

TEST(AnalyzerMalloc, StartsItselfOnceBesideACallersOtherTunables) {
  if (!huge_pages_available()) GTEST_SKIP() << "the kernel has no transparent huge pages: the analyzer runs as started";
  const testing::TempDir dir("inertia-analyzer-malloc");
  const AnalyzerRun run = run_analyzer("glibc.cpu.x86_rep_movsb_threshold=4096", dir.path);
  EXPECT_EQ(run.status, 0) << testing::text_of(dir.path / "simulate.txt");
  ASSERT_TRUE(run.tunables.has_value());
  EXPECT_EQ(run.tunables->rfind("glibc.malloc.hugetlb=1", 0), 0U) << *run.tunables;
}

}  // namespace
}  // namespace inertia
