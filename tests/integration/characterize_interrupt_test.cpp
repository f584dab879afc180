// characterize stopped by SIGINT in the middle of its work, as an operator's Ctrl-C stops it: the
// process ends within a second, the earlier complete output in --out stands unchanged, what the
// stopped run wrote is only in a folder named incomplete, and the next run removes that folder.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include "common/output_folder.hpp"
#include "tests/support/child_process.hpp"
#include "tests/support/files.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

using testing::analyze_binary;
using testing::start_child;
using testing::text_of;

int finish(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

int incomplete_folders(const fs::path& target) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(target.parent_path()))
    n += e.path().filename().string().starts_with(target.filename().string() + ".incomplete-");
  return n;
}

TEST(CharacterizeInterrupt, SigintStopsWithinASecondAndTheEarlierOutputStands) {
  const testing::TempDir dir("inertia-interrupt");
  const fs::path data = dir.path / "data", out = dir.path / "char";
  ASSERT_EQ(finish(start_child({analyze_binary(), "simulate", "--bench", std::string(INERTIA_SOURCE_DIR) + "/config/sim-paper.toml", "--out",
                          data.string()},
                         dir.path / "simulate.txt")),
            0);
  const std::vector<std::string> characterize = {analyze_binary(), "characterize", "--dataset", data.string(), "--out", out.string()};
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(finish(start_child(characterize, dir.path / "first.txt")), 0) << text_of(dir.path / "first.txt");
  const double whole_run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string model = text_of(out / "model.toml");
  ASSERT_FALSE(model.empty());

  // Stopped at a third of a whole run: the identification is under way, nothing committed yet.
  const pid_t pid = start_child(characterize, dir.path / "second.txt");
  std::this_thread::sleep_for(std::chrono::duration<double>(whole_run_s / 3.0));
  ASSERT_EQ(incomplete_folders(out), 1) << "the run writes into its staging folder";
  const auto signalled = std::chrono::steady_clock::now();
  ::kill(pid, SIGINT);
  const int status = finish(pid);
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count();
  std::cout << "[ figures ] a whole run " << whole_run_s << " s; stopped " << stop_s << " s after SIGINT\n";
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << status;
  EXPECT_LT(stop_s, 1.0);
  EXPECT_EQ(text_of(out / "model.toml"), model) << "the earlier complete output stands";
  EXPECT_TRUE(fs::exists(out / OutputFolder::kMarker));
  EXPECT_EQ(incomplete_folders(out), 1) << "what the stopped run wrote is named incomplete";

  ASSERT_EQ(finish(start_child(characterize, dir.path / "third.txt")), 0) << text_of(dir.path / "third.txt");
  EXPECT_EQ(incomplete_folders(out), 0) << "the next run removed the stopped run's folder";
  EXPECT_FALSE(text_of(out / "model.toml").empty());
}

}  // namespace
}  // namespace inertia
