// OutputFolder and AtomicFileWriter on real folders and files: a run's output appears whole at
// commit or not at all, replaces an earlier output whole, refuses a folder of someone else's
// files, and the next run removes the staging folder a stopped run left.
#include "common/output_folder.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

#include "common/atomic_file.hpp"
#include "common/input_error.hpp"
#include "tests/support/files.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

using testing::text_of;

int staging_folders_beside(const fs::path& target) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(target.parent_path()))
    n += e.path().filename().string().starts_with(target.filename().string() + ".");
  return n;
}

TEST(OutputFolder, ANewOutputAppearsOnlyAtCommit) {
  const testing::TempDir dir("inertia-out");
  const fs::path target = dir.path / "run";
  OutputFolder folder(target / "", "test");   // a trailing separator names the same folder
  std::ofstream(folder.path() / "model.toml") << "x";
  EXPECT_FALSE(fs::exists(target));
  EXPECT_EQ(folder.final_path(folder.path() / "model.toml"), target / "model.toml");
  folder.commit();
  EXPECT_EQ(text_of(target / "model.toml"), "x");
  EXPECT_TRUE(fs::exists(target / OutputFolder::kMarker));
  EXPECT_EQ(staging_folders_beside(target), 0);
}

TEST(OutputFolder, AnEarlierOutputIsReplacedWholeAndKeptUntilCommit) {
  const testing::TempDir dir("inertia-out");
  const fs::path target = dir.path / "run";
  {
    OutputFolder first(target, "test");
    std::ofstream(first.path() / "old.txt") << "old";
    first.commit();
  }
  OutputFolder second(target, "test");
  std::ofstream(second.path() / "new.txt") << "new";
  EXPECT_EQ(text_of(target / "old.txt"), "old");   // the earlier output stands until this one is whole
  second.commit();
  EXPECT_FALSE(fs::exists(target / "old.txt"));
  EXPECT_EQ(text_of(target / "new.txt"), "new");
  EXPECT_EQ(staging_folders_beside(target), 0);
}

TEST(OutputFolder, ARunThatDoesNotCommitLeavesTheTargetAsItWas) {
  const testing::TempDir dir("inertia-out");
  const fs::path target = dir.path / "run";
  {
    OutputFolder folder(target, "test");
    std::ofstream(folder.path() / "half.txt") << "half";
  }
  EXPECT_FALSE(fs::exists(target));
  EXPECT_EQ(staging_folders_beside(target), 0);
}

TEST(OutputFolder, AFolderOfOtherFilesIsRefusedAndUntouched) {
  const testing::TempDir dir("inertia-out");
  const fs::path mine = dir.path / "mine";
  fs::create_directories(mine);
  std::ofstream(mine / "thesis.tex") << "years of work";
  try {
    OutputFolder folder(mine, "test");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("holds files inertia did not write"), std::string::npos) << e.what();
  }
  EXPECT_EQ(text_of(mine / "thesis.tex"), "years of work");
  EXPECT_EQ(staging_folders_beside(mine), 0);
  std::ofstream(dir.path / "a-file") << "";
  EXPECT_THROW(OutputFolder(dir.path / "a-file", "test"), InputError);
  const fs::path empty = dir.path / "empty";
  fs::create_directories(empty);
  OutputFolder folder(empty, "test");   // an empty folder is taken
  folder.commit();
  EXPECT_TRUE(fs::exists(empty / OutputFolder::kMarker));
}

TEST(OutputFolder, TheStagingOfAStoppedRunIsRemovedByTheNextOne) {
  const testing::TempDir dir("inertia-out");
  const fs::path target = dir.path / "run";
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ::waitpid(dead, nullptr, 0);
  const fs::path left = dir.path / ("run.incomplete-" + std::to_string(dead));
  const fs::path running = dir.path / ("run.incomplete-" + std::to_string(::getppid()));   // a live process's
  fs::create_directories(left);
  fs::create_directories(running);
  OutputFolder folder(target, "test");
  EXPECT_FALSE(fs::exists(left));
  EXPECT_TRUE(fs::exists(running));
  fs::remove_all(running);
}

TEST(AtomicFileWriter, TheFileAppearsWholeAtCommitAndAnUncommittedOneLeavesNothing) {
  const testing::TempDir dir("inertia-out");
  const fs::path file = dir.path / "samples.csv";
  write_file_atomically(file, "old\n");
  {
    AtomicFileWriter writer(file);
    writer.append("a,");
    writer.append("b\n");
    EXPECT_EQ(text_of(file), "old\n");   // the earlier file stands until commit
  }
  EXPECT_EQ(text_of(file), "old\n");
  {
    AtomicFileWriter writer(file);
    writer.append("new\n");
    writer.commit();
  }
  EXPECT_EQ(text_of(file), "new\n");
  int others = 0;
  for (const auto& e : fs::directory_iterator(dir.path)) others += e.path() != file;
  EXPECT_EQ(others, 0) << "no temporary file left";
}

}  // namespace
}  // namespace inertia
