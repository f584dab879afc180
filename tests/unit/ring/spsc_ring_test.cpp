#include "common/spsc_ring.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <vector>

namespace inertia {
namespace {

static_assert(!std::is_copy_constructible_v<SpscRing<int>>);
static_assert(!std::is_copy_assignable_v<SpscRing<int>>);
static_assert(!std::is_move_constructible_v<SpscRing<int>>);
static_assert(!std::is_move_assignable_v<SpscRing<int>>);

// A sample-sized element whose fields are all derived from `seq`, so a torn or stale read
// (element published before it was fully written) shows up as a mismatch.
struct Sample64 {
  std::uint64_t seq;
  std::array<std::uint64_t, 7> payload;
};
static_assert(sizeof(Sample64) == 64);

Sample64 make_sample(std::uint64_t seq) {
  Sample64 s{seq, {}};
  for (std::size_t i = 0; i < s.payload.size(); ++i) s.payload[i] = seq * 0x9E3779B97F4A7C15ULL + i;
  return s;
}

TEST(SpscRing, CapacityIsRoundedUpToAPowerOfTwo) {
  EXPECT_EQ(SpscRing<int>(0).capacity(), 1U);
  EXPECT_EQ(SpscRing<int>(1).capacity(), 1U);
  EXPECT_EQ(SpscRing<int>(3).capacity(), 4U);
  EXPECT_EQ(SpscRing<int>(4).capacity(), 4U);
  EXPECT_EQ(SpscRing<int>(1000).capacity(), 1024U);
}

TEST(SpscRing, AbsurdCapacityThrowsInsteadOfOverflowing) {
  EXPECT_THROW(SpscRing<Sample64>(SIZE_MAX / 2), std::length_error);
}

TEST(SpscRing, EmptyRingHasNoFront) {
  SpscRing<int> ring(4);
  EXPECT_EQ(ring.front(), nullptr);
  EXPECT_TRUE(ring.empty());
  EXPECT_EQ(ring.size_approx(), 0U);
}

TEST(SpscRing, EveryAdvertisedSlotIsUsableAndAFullRingRejects) {
  SpscRing<int> ring(8);
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(ring.try_push(i)) << "slot " << i;
  EXPECT_EQ(ring.size_approx(), 8U);
  EXPECT_FALSE(ring.try_push(99));
  EXPECT_FALSE(ring.try_push(99));   // a second refusal after the index cache was refreshed
  for (int i = 0; i < 8; ++i) {
    int* front = ring.front();
    ASSERT_NE(front, nullptr);
    EXPECT_EQ(*front, i);            // the refused pushes left nothing behind
    ring.pop();
  }
  EXPECT_EQ(ring.front(), nullptr);
}

TEST(SpscRing, FrontDoesNotConsume) {
  SpscRing<int> ring(2);
  ASSERT_TRUE(ring.try_push(7));
  ASSERT_TRUE(ring.try_push(8));
  EXPECT_EQ(*ring.front(), 7);
  EXPECT_EQ(*ring.front(), 7);
  ring.pop();
  EXPECT_EQ(*ring.front(), 8);
  EXPECT_EQ(ring.size_approx(), 1U);
}

TEST(SpscRing, PoppingFreesASlotForTheProducer) {
  SpscRing<int> ring(2);
  ASSERT_TRUE(ring.try_push(1));
  ASSERT_TRUE(ring.try_push(2));
  ASSERT_FALSE(ring.try_push(3));
  ring.pop();
  EXPECT_TRUE(ring.try_push(3));
  EXPECT_EQ(*ring.front(), 2);
}

TEST(SpscRing, WrapsAroundOverManyCyclesInOrder) {
  // Batches of 1..8 against capacity 8: the indices cross the slot array's end at every
  // offset, thousands of times, and the ring passes through full and empty.
  SpscRing<std::uint64_t> ring(8);
  std::uint64_t next_push = 0;
  std::uint64_t next_pop = 0;
  for (int round = 0; round < 50'000; ++round) {
    const int batch = 1 + round % 8;
    for (int i = 0; i < batch; ++i) ASSERT_TRUE(ring.try_push(next_push++));
    EXPECT_EQ(ring.size_approx(), next_push - next_pop);
    if (batch == 8) {
      EXPECT_FALSE(ring.try_push(0));
    }
    for (int i = 0; i < batch; ++i) {
      const std::uint64_t* front = ring.front();
      ASSERT_NE(front, nullptr);
      ASSERT_EQ(*front, next_pop++);
      ring.pop();
    }
    ASSERT_EQ(ring.front(), nullptr);
  }
  EXPECT_EQ(next_pop, 225'000U);
}

TEST(SpscRing, StagedElementsAreInvisibleUntilPublished) {
  SpscRing<std::uint64_t> ring(8);
  ASSERT_TRUE(ring.try_stage(1));
  ASSERT_TRUE(ring.try_stage(2));
  EXPECT_EQ(ring.front(), nullptr);
  EXPECT_EQ(ring.size_approx(), 0U);
  ring.publish();
  EXPECT_EQ(ring.size_approx(), 2U);
  // A staged element holds its slot: 2 published + 6 staged fill the ring.
  for (std::uint64_t i = 3; i <= 8; ++i) ASSERT_TRUE(ring.try_stage(i));
  EXPECT_FALSE(ring.try_stage(9));
  EXPECT_FALSE(ring.try_push(9));
  EXPECT_EQ(ring.size_approx(), 2U);
  ring.publish();
  std::uint64_t expected = 1;
  EXPECT_EQ(ring.consume([&](std::uint64_t& v) { EXPECT_EQ(v, expected++); }), 8U);
  EXPECT_EQ(ring.front(), nullptr);
}

TEST(SpscRing, ConsumeIsBoundedAndFreesWhatItConsumed) {
  SpscRing<std::uint64_t> ring(16);
  for (std::uint64_t i = 0; i < 16; ++i) ASSERT_TRUE(ring.try_push(i));
  std::vector<std::uint64_t> got;
  EXPECT_EQ(ring.consume([&](std::uint64_t& v) { got.push_back(v); }, 5), 5U);
  EXPECT_EQ(ring.size_approx(), 11U);
  for (std::uint64_t i = 16; i < 21; ++i) ASSERT_TRUE(ring.try_push(i)) << "consume() freed five slots";
  EXPECT_FALSE(ring.try_push(21));
  // front()/pop() and consume() share the read index.
  ASSERT_NE(ring.front(), nullptr);
  EXPECT_EQ(*ring.front(), 5U);
  ring.pop();
  got.push_back(5);
  EXPECT_EQ(ring.consume([&](std::uint64_t& v) { got.push_back(v); }), 15U);
  EXPECT_EQ(ring.consume([&](std::uint64_t& v) { got.push_back(v); }), 0U);
  ASSERT_EQ(got.size(), 21U);
  for (std::uint64_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i], i);
}

// Producer pushes 0..N-1 (spinning when full, as a test may; the daemon counts a drop instead),
// consumer asserts each arrives exactly once and in order. A small ring makes both sides hit
// full and empty constantly, the paths where the index caches are refreshed.
// Both sides yield now and then while waiting: CI machines have two CPUs and may be busy, and
// a partner preempted mid-spin would otherwise stretch the test (10x under ThreadSanitizer).
inline void back_off(unsigned& spins) {
  if (++spins % 64 == 0) std::this_thread::yield();
}

template <class T, class Make, class Seq>
void pass_sequence_between_threads(std::uint64_t count, std::size_t capacity, Make make, Seq seq_of) {
  SpscRing<T> ring(capacity);
  std::uint64_t pushed_full = 0;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < count; ++i) {
      const T item = make(i);
      unsigned spins = 0;
      while (!ring.try_push(item)) {
        ++pushed_full;
        back_off(spins);
      }
    }
  });
  std::uint64_t expected = 0;
  std::uint64_t mismatches = 0;
  unsigned spins = 0;
  while (expected < count) {
    const T* front = ring.front();
    if (front == nullptr) {
      back_off(spins);
      continue;
    }
    const T want = make(expected);
    if (seq_of(*front) != expected || std::memcmp(front, &want, sizeof(T)) != 0) {
      ++mismatches;
      if (mismatches < 5) ADD_FAILURE() << "expected " << expected << ", got " << seq_of(*front);
    }
    ++expected;
    ring.pop();
  }
  producer.join();
  EXPECT_EQ(mismatches, 0U);
  EXPECT_EQ(ring.front(), nullptr) << "an element arrived twice or was invented";
  EXPECT_EQ(ring.size_approx(), 0U);
  ::testing::Test::RecordProperty("producer_full_spins", static_cast<int>(pushed_full > INT32_MAX ? INT32_MAX : pushed_full));
}

// The daemon's pattern: the producer stages a batch of varying length and publishes it, the
// consumer takes whatever is visible in bounded batches. Same checks as above.
template <class T, class Make, class Seq>
void pass_batches_between_threads(std::uint64_t count, std::size_t capacity, Make make, Seq seq_of) {
  SpscRing<T> ring(capacity);
  std::thread producer([&] {
    std::uint64_t i = 0;
    std::uint64_t batch = 1;
    unsigned spins = 0;
    while (i < count) {
      const std::uint64_t end = std::min(count, i + batch);
      while (i < end && ring.try_stage(make(i))) ++i;
      ring.publish();
      if (i < end) back_off(spins);  // full: wait for the consumer, as a test may
      batch = batch % 97 + 1;        // 1..97, so batches straddle the wrap at every offset
    }
  });
  std::uint64_t expected = 0;
  std::uint64_t mismatches = 0;
  unsigned spins = 0;
  std::size_t bound = 1;
  while (expected < count) {
    const std::size_t n = ring.consume(
        [&](const T& item) {
          const T want = make(expected);
          if (seq_of(item) != expected || std::memcmp(&item, &want, sizeof(T)) != 0) {
            ++mismatches;
            if (mismatches < 5) ADD_FAILURE() << "expected " << expected << ", got " << seq_of(item);
          }
          ++expected;
        },
        bound);
    bound = bound % 61 + 1;
    if (n == 0) back_off(spins);
  }
  producer.join();
  EXPECT_EQ(mismatches, 0U);
  EXPECT_EQ(ring.front(), nullptr) << "an element arrived twice or was invented";
}

TEST(SpscRingThreads, StagedBatchesAndBoundedConsumeKeepEveryElementInOrder) {
  pass_batches_between_threads<std::uint64_t>(
      2'000'000, 256, [](std::uint64_t i) { return i; }, [](std::uint64_t v) { return v; });
  pass_batches_between_threads<Sample64>(
      200'000, 64, make_sample, [](const Sample64& s) { return s.seq; });
}

TEST(SpscRingThreads, TenMillionSequenceNumbersNoLossNoDuplicateInOrder) {
  pass_sequence_between_threads<std::uint64_t>(
      10'000'000, 1024, [](std::uint64_t i) { return i; }, [](std::uint64_t v) { return v; });
}

TEST(SpscRingThreads, SampleSizedElementsArriveWhole) {
  pass_sequence_between_threads<Sample64>(
      1'000'000, 64, make_sample, [](const Sample64& s) { return s.seq; });
}

}  // namespace
}  // namespace inertia
