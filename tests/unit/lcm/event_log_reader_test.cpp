// EventLogReader (common/lcm/event_log_reader.hpp): the records of an LCM event log as written by
// lcm_eventlog, every whole record before a torn tail, garbage or a length the file cannot hold,
// and why reading stopped.
#include <gtest/gtest.h>
#include <lcm/eventlog.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/input_error.hpp"
#include "common/lcm/event_log_reader.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia {
namespace {

namespace fs = std::filesystem;

class EventLogReaderTest : public ::testing::Test {
 protected:
  testing::TempDir tmp_{"inertia-event-log-reader"};
  fs::path dir_ = tmp_.path;

  // Three records written by liblcm itself.
  fs::path write_log(const std::string& name) {
    const fs::path file = dir_ / name;
    lcm_eventlog_t* log = lcm_eventlog_create(file.c_str(), "w");
    EXPECT_NE(log, nullptr);
    for (int i = 0; i < 3; ++i) {
      std::string channel = "CHANNEL_" + std::to_string(i);
      std::vector<std::uint8_t> data(static_cast<std::size_t>(10 * (i + 1)), static_cast<std::uint8_t>(i));
      lcm_eventlog_event_t e{};
      e.timestamp = 1000 + i;
      e.channellen = static_cast<std::int32_t>(channel.size());
      e.datalen = static_cast<std::int32_t>(data.size());
      e.channel = channel.data();
      e.data = data.data();
      EXPECT_EQ(lcm_eventlog_write_event(log, &e), 0);
    }
    lcm_eventlog_destroy(log);
    return file;
  }
  static std::string bytes_of(const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  static void put(const fs::path& f, const std::string& bytes) { std::ofstream(f, std::ios::binary) << bytes; }
  static std::vector<LogRecord> read_all(EventLogReader& r) {
    std::vector<LogRecord> out;
    LogRecord rec;
    while (r.next(rec)) out.push_back(rec);
    return out;
  }
};

TEST_F(EventLogReaderTest, ReadsWhatLiblcmWrote) {
  EventLogReader r(write_log("whole.lcmlog"));
  const auto records = read_all(r);
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records[2].channel, "CHANNEL_2");
  EXPECT_EQ(records[2].data, std::vector<std::uint8_t>(30, 2));
  EXPECT_EQ(records[1].utime, 1001);
  EXPECT_EQ(r.stop_reason(), "");
}

TEST_F(EventLogReaderTest, TornTailKeepsEveryWholeRecordAndSaysWhere) {
  const std::string whole = bytes_of(write_log("whole.lcmlog"));
  for (std::size_t cut : {std::size_t{5}, std::size_t{20}}) {
    const fs::path torn = dir_ / "torn.lcmlog";
    put(torn, whole.substr(0, whole.size() - cut));
    EventLogReader r(torn);
    EXPECT_EQ(read_all(r).size(), 2u) << cut;
    EXPECT_NE(r.stop_reason().find("the log ends inside event 2"), std::string::npos) << r.stop_reason();
  }
}

// A data length of 2^31 - 1 in a short file: liblcm would allocate 2 GiB before reading; here the
// record is a torn tail, nothing is allocated for it.
TEST_F(EventLogReaderTest, HugeLengthIsATornTailNotAnAllocation) {
  std::string bytes = bytes_of(write_log("whole.lcmlog"));
  const std::size_t second = 28 + 9 + 10;   // header + "CHANNEL_0" + 10 data bytes
  bytes[second + 24] = '\x7F';
  bytes[second + 25] = bytes[second + 26] = bytes[second + 27] = '\xFF';
  put(dir_ / "huge.lcmlog", bytes);
  EventLogReader r(dir_ / "huge.lcmlog");
  EXPECT_EQ(read_all(r).size(), 1u);
  EXPECT_NE(r.stop_reason().find("ends inside event 1"), std::string::npos) << r.stop_reason();
}

TEST_F(EventLogReaderTest, GarbageStopsReadingWithItsOffset) {
  std::string bytes = bytes_of(write_log("whole.lcmlog"));
  bytes[28 + 9 + 10] = 'x';   // the second record's sync word
  put(dir_ / "garbage.lcmlog", bytes);
  EventLogReader r(dir_ / "garbage.lcmlog");
  EXPECT_EQ(read_all(r).size(), 1u);
  EXPECT_NE(r.stop_reason().find("byte 47"), std::string::npos) << r.stop_reason();
  put(dir_ / "not-a-log", "hello");
  EXPECT_THROW(EventLogReader(dir_ / "not-a-log"), InputError);
  EXPECT_THROW(EventLogReader(dir_ / "missing"), InputError);
}

}  // namespace
}  // namespace inertia
