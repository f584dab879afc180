// The run record: what one run leaves for the next, read back as written, replaced whole.
#include "daq/run_record.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

#include "tests/support/scratch_dirs.hpp"

namespace inertia::daq {
namespace {

TEST(RunRecord, TheNextRunReadsWhatThisOneLastSaid) {
  testing::TempDir dir;
  const auto path = dir.path / "inertia-daqd.run";
  {
    RunRecorder first(path, "bench-a");
    EXPECT_FALSE(first.previous());
    EXPECT_TRUE(first.previous_error().empty());
    std::string why;
    ASSERT_TRUE(first.update(true, "case table, phase 1 (rotation) commanded", &why)) << why;
    // Killed here: no end.
  }
  RunRecorder second(path, "bench-a");
  ASSERT_TRUE(second.previous());
  const RunRecord& r = *second.previous();
  EXPECT_EQ(r.pid, static_cast<long>(::getpid()));
  EXPECT_EQ(r.bench, "bench-a");
  EXPECT_FALSE(r.ended);
  EXPECT_TRUE(r.armed);
  EXPECT_EQ(r.activity, "case table, phase 1 (rotation) commanded");
  EXPECT_EQ(r.started.size(), 20u);   // 2026-11-27T23:40:43Z
  ASSERT_TRUE(second.end("stopped (SIGTERM)"));
  RunRecorder third(path, "bench-a");
  ASSERT_TRUE(third.previous());
  EXPECT_TRUE(third.previous()->ended);
  EXPECT_FALSE(third.previous()->armed);
  EXPECT_EQ(third.previous()->activity, "stopped (SIGTERM)");
  EXPECT_FALSE(std::filesystem::exists(dir.path / "inertia-daqd.run.new"));
}

TEST(RunRecord, AnUnreadableRecordIsSaidAndAMissingDirectoryIsAnError) {
  testing::TempDir dir;
  const auto path = dir.path / "inertia-daqd.run";
  std::ofstream(path) << "this is = = not toml";
  RunRecorder r(path, "bench-a");
  EXPECT_FALSE(r.previous());
  EXPECT_NE(r.previous_error().find("not a run record"), std::string::npos) << r.previous_error();
  RunRecorder nowhere(dir.path / "missing" / "inertia-daqd.run", "bench-a");
  std::string why;
  EXPECT_FALSE(nowhere.update(false, "disarmed", &why));
  EXPECT_NE(why.find("create: No such file or directory"), std::string::npos) << why;
  RunRecorder none({}, "bench-a");
  EXPECT_TRUE(none.update(false, "disarmed"));   // no record kept: nothing to fail
}

}  // namespace
}  // namespace inertia::daq
