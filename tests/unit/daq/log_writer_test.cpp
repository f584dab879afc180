// LogWriter: LCM log format (read back by lcm::LogFile and replayed by lcm-logplayer), rotation
// by size and on request, a stalled writer that never blocks enqueue() and counts what it lost.
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "daq/daemon.hpp"
#include "daq/log_writer.hpp"
#include "tests/support/scratch_dirs.hpp"
#include "tests/support/skip_or_fail.hpp"

namespace inertia::daq {
namespace {

namespace fs = std::filesystem;

using inertia::testing::SmallDisk;
using inertia::testing::TempDir;

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> v;
  for (const auto& e : fs::directory_iterator(dir)) v.push_back(e.path());
  std::sort(v.begin(), v.end());
  return v;
}

std::size_t count_events(const std::vector<fs::path>& files, std::int64_t* sum = nullptr) {
  std::size_t n = 0;
  for (const auto& f : files) {
    lcm::LogFile log(f.string(), "r");
    while (const lcm::LogEvent* e = log.readNextEvent()) {
      ++n;
      if (sum) *sum += *static_cast<const std::int32_t*>(e->data);
    }
  }
  return n;
}

TEST(LogWriter, FileHeaderOpensEveryFile) {
  // INERTIA_BENCH goes first into each file, so a rotated file alone can be analyzed.
  TempDir tmp;
  LogWriterOptions o;
  o.dir = tmp.path / "log";
  o.base_name = "t";
  o.rotate_bytes = 5000;
  LogWriter w(o);
  const std::vector<std::uint8_t> header{1, 2, 3, 4, 5};
  w.set_file_header("HDR", header);
  std::string why;
  ASSERT_TRUE(w.open(&why)) << why;
  w.start();
  std::vector<std::uint8_t> payload(1000);
  for (std::int32_t i = 0; i < 20; ++i)
    while (!w.enqueue("CH", payload.data(), payload.size(), i)) std::this_thread::yield();
  w.stop();
  const auto files = files_in(tmp.path / "log");
  ASSERT_GE(files.size(), 4u);
  std::size_t data_events = 0;
  for (const auto& f : files) {
    lcm::LogFile log(f.string(), "r");
    const lcm::LogEvent* first = log.readNextEvent();
    ASSERT_NE(first, nullptr) << f;
    EXPECT_EQ(first->channel, "HDR") << f;
    ASSERT_EQ(first->datalen, 5);
    EXPECT_EQ(std::memcmp(first->data, header.data(), header.size()), 0);
    while (const lcm::LogEvent* e = log.readNextEvent()) {
      EXPECT_EQ(e->channel, "CH");
      ++data_events;
    }
    EXPECT_LE(fs::file_size(f), 5000u);
  }
  EXPECT_EQ(data_events, 20u);
}

TEST(LogWriter, WritesLcmLogFormatAndRotatesBySizeAndOnRequest) {
  TempDir tmp;
  LogWriterOptions o;
  o.dir = tmp.path / "log";
  o.base_name = "t";
  o.rotate_bytes = 10000;
  LogWriter w(o);
  std::string why;
  ASSERT_TRUE(w.open(&why)) << why;
  w.start();
  std::vector<std::uint8_t> payload(1000);
  std::int64_t expected = 0;
  for (std::int32_t i = 0; i < 100; ++i) {
    std::memcpy(payload.data(), &i, sizeof i);
    expected += i;
    while (!w.enqueue("CH", payload.data(), payload.size(), i)) std::this_thread::yield();
    if (i == 50) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      w.request_rotate();
    }
  }
  w.stop();
  const auto files = files_in(tmp.path / "log");
  EXPECT_GE(files.size(), 10u) << "about 100 kB in files of 10 kB";
  EXPECT_EQ(w.rotations() + 1, files.size());
  std::int64_t sum = 0;
  EXPECT_EQ(count_events(files, &sum), 100u);
  EXPECT_EQ(sum, expected) << "every message once, none twice";
  EXPECT_EQ(w.messages_lost(), 0u);
  EXPECT_EQ(w.bytes_written(), 100u * (28 + 2 + 1000));
  for (const auto& f : files) EXPECT_LE(fs::file_size(f), 10000u);
}

TEST(LogWriter, AStalledWriterNeverBlocksEnqueueAndCountsWhatItLost) {
  TempDir tmp;
  LogWriterOptions o;
  o.dir = tmp.path;
  o.queue_slots = 8;
  o.stall_after_s = 0.0;
  o.stall_ms = 500;
  LogWriter w(o);
  std::string why;
  ASSERT_TRUE(w.open(&why));
  w.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the writer is now stuck
  std::vector<std::uint8_t> payload(100);
  std::size_t accepted = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 100; ++i) accepted += w.enqueue("CH", payload.data(), payload.size(), i) ? 1 : 0;
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(took, std::chrono::milliseconds(50)) << "enqueue never waits for the disk";
  EXPECT_EQ(accepted, 8u);
  EXPECT_EQ(w.messages_lost(), 92u);
  w.stop();
  EXPECT_EQ(count_events(files_in(tmp.path)), 8u);
  EXPECT_EQ(w.messages_written(), 8u);
}


TEST(LogWriter, AFullDiskLeavesWholeRecordsCountsWhatItCouldNotWriteAndResumes) {
  TempDir tmp;
  SmallDisk disk(tmp.path / "disk", "2m");
  if (!disk.why_not.empty()) INERTIA_SKIP_OR_FAIL_IN_CI(disk.why_not);
  {  // 1.25 MiB of the 2 MiB taken by something else: about 75 messages fit
    std::ofstream filler(disk.path / "filler", std::ios::binary);
    const std::vector<char> chunk(1 << 16, 'f');
    for (int i = 0; i < 20; ++i) filler.write(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    ASSERT_TRUE(filler.good());
  }
  LogWriterOptions o;
  o.dir = disk.path / "log";
  o.base_name = "t";
  o.fsync_interval_ms = 5;
  LogWriter w(o);
  std::string why;
  ASSERT_TRUE(w.open(&why)) << why;
  w.start();
  // 10 kB messages, each numbered, one at a time (the queue never overflows: every loss here
  // is the disk's).
  std::vector<std::uint8_t> payload(10'000);
  auto send = [&](std::int32_t i) {
    std::memcpy(payload.data(), &i, sizeof i);
    std::fill(payload.begin() + sizeof i, payload.end(), static_cast<std::uint8_t>(i));
    ASSERT_TRUE(w.enqueue("CH", payload.data(), payload.size(), i));
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (w.messages_written() + w.messages_lost() < static_cast<std::uint64_t>(i) + 1 &&
           std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
  };
  std::int32_t i = 0;
  for (; i < 300 && !w.disk_full(); ++i) send(i);
  ASSERT_TRUE(w.disk_full()) << "2 MiB filled";
  const std::int32_t first_lost = i - 1;
  for (const std::int32_t end = i + 20; i < end; ++i) send(i);  // 20 more while full
  EXPECT_TRUE(w.disk_full());
  fs::remove(disk.path / "filler");  // space is back
  for (const std::int32_t end = i + 40; i < end; ++i) send(i);
  EXPECT_FALSE(w.disk_full()) << "writing again";
  w.stop();

  const std::uint64_t lost = w.messages_lost();
  EXPECT_EQ(lost, w.disk_full_lost());
  EXPECT_EQ(lost, 21u) << "the one that hit the full disk and the 20 after it";
  EXPECT_EQ(w.messages_written() + lost, static_cast<std::uint64_t>(i));
  // Read back: whole records only, each intact, exactly the lost ones missing.
  const auto files = files_in(o.dir);
  ASSERT_EQ(files.size(), 1u);
  lcm::LogFile log(files[0].string(), "r");
  std::vector<std::int32_t> seen;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    ASSERT_EQ(e->channel, "CH");
    ASSERT_EQ(e->datalen, 10'000);
    std::int32_t k = 0;
    std::memcpy(&k, e->data, sizeof k);
    const auto* d = static_cast<const std::uint8_t*>(e->data);
    EXPECT_EQ(std::count(d + sizeof k, d + 10'000, static_cast<std::uint8_t>(k)), 10'000 - 4) << "message " << k;
    EXPECT_EQ(e->timestamp, k);
    seen.push_back(k);
  }
  ASSERT_EQ(seen.size(), w.messages_written());
  std::int32_t expect = 0;
  for (const std::int32_t k : seen) {
    if (expect == first_lost) expect += 21;  // the gap: exactly the lost messages
    EXPECT_EQ(k, expect);
    expect = k + 1;
  }
  EXPECT_EQ(expect, i);
  EXPECT_EQ(fs::file_size(files[0]), w.messages_written() * (28u + 2u + 10'000u)) << "no partial record left";
}

TEST(LogWriter, AnUnwritableDirectoryIsNamed) {
  LogWriterOptions o;
  o.dir = "/proc/no-such-dir/log";
  LogWriter w(o);
  std::string why;
  EXPECT_FALSE(w.open(&why));
  EXPECT_NE(why.find("/proc/no-such-dir/log"), std::string::npos) << why;
}

class Counter {
 public:
  int n = 0;
  void on(const lcm::ReceiveBuffer*, const std::string&) { ++n; }
};

TEST(LogWriter, LcmLogplayerReplaysTheLog) {
  if (std::system("command -v lcm-logplayer > /dev/null 2>&1") != 0) INERTIA_SKIP_OR_FAIL_IN_CI("lcm-logplayer not installed");
  if (!has_multicast_route()) INERTIA_SKIP_OR_FAIL_IN_CI("no multicast route (ip route add 224.0.0.0/4 dev lo)");
  TempDir tmp;
  LogWriterOptions o;
  o.dir = tmp.path;
  o.base_name = "replay";
  LogWriter w(o);
  std::string why;
  ASSERT_TRUE(w.open(&why));
  w.start();
  const std::int64_t now_us =
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::vector<std::uint8_t> payload(64, 7);
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(w.enqueue("INERTIA_REPLAY", payload.data(), payload.size(), now_us + i * 1000));
  w.stop();
  const std::string url = "udpm://239.255.76.67:" + std::to_string(30000 + ::getpid() % 20000) + "?ttl=0";
  lcm::LCM lcm(url);
  ASSERT_TRUE(lcm.good());
  Counter c;
  lcm.subscribe("INERTIA_REPLAY", &Counter::on, &c);
  const std::string cmd = "lcm-logplayer -s 10 -l '" + url + "' " + w.current_path() + " > /dev/null 2>&1 &";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (c.n < 20 && std::chrono::steady_clock::now() < deadline) lcm.handleTimeout(100);
  EXPECT_EQ(c.n, 20);
}

}  // namespace
}  // namespace inertia::daq
