// Runs side by side (common/parallel.hpp): every index once, results in their slots, the loops
// inside a task on one thread, and a task's exception carried to the caller.
#include "common/parallel.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace inertia::parallel {
namespace {

class Jobs : public ::testing::Test {
 protected:
  void TearDown() override { set_jobs(1); }
};

TEST_F(Jobs, EveryIndexRunsOnceIntoItsSlotOnUpToTheJobsThreads) {
  set_jobs(3);
  std::vector<long> slot(100, -1);
  std::mutex lock;
  std::set<std::thread::id> threads;
  for_each_index(static_cast<long>(slot.size()), [&](long i) {
    slot[static_cast<std::size_t>(i)] = i * i;
    const std::lock_guard<std::mutex> guard(lock);
    threads.insert(std::this_thread::get_id());
  });
  for (std::size_t i = 0; i < slot.size(); ++i) EXPECT_EQ(slot[i], static_cast<long>(i * i)) << i;
  EXPECT_GE(threads.size(), 1U);
  EXPECT_LE(threads.size(), 3U);
  // Fewer items than jobs: no more threads than items; none: nothing runs.
  std::atomic<int> ran{0};
  for_each_index(1, [&](long) { ++ran; });
  for_each_index(0, [&](long) { ++ran; });
  EXPECT_EQ(ran.load(), 1);
}

TEST_F(Jobs, LoopsInsideATaskRunOnItsThreadAlone) {
  set_jobs(4);
  EXPECT_EQ(threads_for(100), 4);
  std::vector<int> inside(8, 0);
  for_each_index(8, [&](long i) { inside[static_cast<std::size_t>(i)] = threads_for(100); });
  for (int t : inside) EXPECT_EQ(t, 1);
  EXPECT_EQ(threads_for(100), 4) << "the caller's own loops keep their threads";
}

TEST_F(Jobs, TheFirstFailingIndexsExceptionReachesTheCallerAndNoNewTaskStarts) {
  set_jobs(1);   // one thread: the order of the tasks is the order of the indices
  std::vector<int> ran(10, 0);
  try {
    for_each_index(10, [&](long i) {
      ran[static_cast<std::size_t>(i)] = 1;
      if (i == 3 || i == 6) throw std::runtime_error("task " + std::to_string(i));
    });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "task 3");
  }
  for (std::size_t i = 0; i < ran.size(); ++i) EXPECT_EQ(ran[i], i <= 3 ? 1 : 0) << i;
  // With threads the exception is still one of the tasks', and the caller's state is intact.
  set_jobs(2);
  EXPECT_THROW(for_each_index(50, [&](long i) {
                 if (i % 7 == 6) throw std::invalid_argument("bad");
               }),
               std::invalid_argument);
  EXPECT_EQ(threads_for(10), 2);
}

TEST_F(Jobs, CallsOneAfterAnotherShareTheSameHelperThreads) {
  // Threads are kept from one call to the next: a call's helper is no new thread. The kernel's
  // thread ids (gettid) tell threads apart; pthread ids are reused with the stacks glibc caches.
  set_jobs(2);
  std::mutex lock;
  std::set<pid_t> threads;
  for (int call = 0; call < 20; ++call) {
    for_each_index(16, [&](long) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      const std::lock_guard<std::mutex> guard(lock);
      threads.insert(::gettid());
    });
  }
  EXPECT_GE(threads.size(), 1U);
  EXPECT_LE(threads.size(), 2U) << "the caller and one kept helper";
}

TEST_F(Jobs, CallersSideBySideEachRunEveryIndexOnce) {
  // Two callers at once: one has the kept helpers, the other starts threads of its own.
  set_jobs(2);
  constexpr long kItems = 200;
  std::vector<std::vector<std::atomic<int>>> runs(2);
  for (auto& r : runs) r = std::vector<std::atomic<int>>(kItems);
  std::vector<std::thread> callers;
  for (std::size_t c = 0; c < runs.size(); ++c) {
    callers.emplace_back([&, c] {
      for (int round = 0; round < 10; ++round)
        for_each_index(kItems, [&](long i) { ++runs[c][static_cast<std::size_t>(i)]; });
    });
  }
  for (std::thread& t : callers) t.join();
  for (std::size_t c = 0; c < runs.size(); ++c)
    for (long i = 0; i < kItems; ++i) EXPECT_EQ(runs[c][static_cast<std::size_t>(i)].load(), 10) << "caller " << c << ", index " << i;
}

}  // namespace
}  // namespace inertia::parallel
