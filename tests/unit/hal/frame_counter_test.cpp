// The frame counter's unwrapping against known truth: an adapter's 16-bit counter at 10 kHz,
// its frames stamped on reception with one-sided (exponential) jitter, through roll-overs, lost
// frames, long silences, restarts of the counter, duplicates and frames out of order.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "hal/socketcan/frame_counter.hpp"

namespace inertia::hal::socketcan {
namespace {

using Verdict = FrameCounter::Verdict;

constexpr double kRateHz = 10000.0;
constexpr double kPeriodNs = 1e9 / kRateHz;
constexpr std::uint64_t kRange = 65536;

/// A 16-bit adapter: sample n taken at n periods (host clock), its frame stamped 150 us later
/// plus exponential jitter of 200 us mean (truth known to the test).
struct Adapter {
  std::mt19937_64 rng{5};
  std::exponential_distribution<double> jitter{1.0 / 200e3};
  std::int64_t stamp(std::int64_t n) { return 1'000'000'000 + std::llround(static_cast<double>(n) * kPeriodNs + 150e3 + jitter(rng)); }
};

TEST(FrameCounter, NumbersFollowTheCountThroughRollOversAndLostFrames) {
  Adapter adapter;
  FrameCounter counter(16, kPeriodNs);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::int64_t checked = 0;
  // 20 s: three roll-overs; 1 % of the frames never arrive.
  for (std::int64_t n = 1000; n < 200'000; ++n) {
    if (n > 1000 && uniform(adapter.rng) < 0.01) continue;
    const auto r = counter.take(static_cast<std::uint64_t>(n) % kRange, adapter.stamp(n));
    ASSERT_EQ(r.verdict, n == 1000 ? Verdict::First : Verdict::Next) << n;
    ASSERT_EQ(r.index, n) << n;
    ++checked;
  }
  EXPECT_GT(checked, 190'000);
}

TEST(FrameCounter, ASilenceOfSeveralRollOversKeepsItsLength) {
  // 6.5 to 9.8 s without a frame is one roll-over and a part: by value alone 65536 short.
  // Also 20 s (three roll-overs) and a silence just short of one roll-over.
  for (const double silence_s : {6.0, 6.5, 7.3, 8.1, 9.8, 13.2, 20.0}) {
    Adapter adapter;
    FrameCounter counter(16, kPeriodNs);
    std::int64_t n = 40'000;
    for (; n < 41'000; ++n) ASSERT_NE(counter.take(static_cast<std::uint64_t>(n) % kRange, adapter.stamp(n)).verdict, Verdict::Reset);
    n += std::llround(silence_s * kRateHz);
    for (std::int64_t k = 0; k < 100; ++k, ++n) {
      const auto r = counter.take(static_cast<std::uint64_t>(n) % kRange, adapter.stamp(n));
      ASSERT_EQ(r.verdict, Verdict::Next) << silence_s << " s";
      ASSERT_EQ(r.index, n) << silence_s << " s";
    }
  }
}

TEST(FrameCounter, ARestartOfTheCounterIsANewSegmentNumberedOnFromTheTime) {
  // The adapter resets at sample `at` (its counter anywhere, from just after a roll-over to just
  // before one), is silent for `down` seconds and counts from 0 again. The frame after the
  // restart is a reset, numbered where the receive time puts it: within the difference of the
  // two frames' jitter of its true number. Numbers then go on by the count.
  for (const std::int64_t at : {40'000LL, 65'535LL + 40'000, 98'304LL, 131'000LL, 70'000LL}) {
    for (const double down_s : {0.0001, 0.05, 1.0}) {
      Adapter adapter;
      FrameCounter counter(16, kPeriodNs);
      std::int64_t last_stamp = 0;
      for (std::int64_t n = 0; n < at; ++n) {
        last_stamp = adapter.stamp(n);
        ASSERT_EQ(counter.take(static_cast<std::uint64_t>(n) % kRange, last_stamp).index, n);
      }
      const std::int64_t restart = at + std::llround(down_s * kRateHz);
      std::int64_t offset = 0;   // the new segment's numbers against the true ones
      for (std::int64_t n = restart; n < restart + 2000; ++n) {
        const std::int64_t stamp = adapter.stamp(n);
        const auto r = counter.take(static_cast<std::uint64_t>(n - restart) % kRange, stamp);
        if (n == restart) {
          ASSERT_EQ(r.verdict, Verdict::Reset) << "reset at " << at << " after " << down_s << " s";
          // Numbered from the elapsed receive time: off by the two stamps' jitter difference.
          const double jitter_samples =
              std::abs(static_cast<double>(stamp - last_stamp) - static_cast<double>(n - at + 1) * kPeriodNs) / kPeriodNs;
          EXPECT_LE(std::abs(static_cast<double>(r.index - n)), jitter_samples + 0.5) << at << " " << down_s;
          offset = r.index - n;
          continue;
        }
        ASSERT_EQ(r.verdict, Verdict::Next) << n;
        ASSERT_EQ(r.index - n, offset) << "numbers go on by the count within the segment";
      }
    }
  }
}

TEST(FrameCounter, AFrameStampedLateIsNoReset) {
  // A transfer delayed by 40 ms (a stalled host, a USB adapter's late batch): the frames of the
  // delay arrive together, their counter consecutive. Nothing restarted: numbered by the count.
  Adapter adapter;
  FrameCounter counter(16, kPeriodNs);
  for (std::int64_t n = 0; n < 50'000; ++n) {
    std::int64_t stamp = adapter.stamp(n);
    if (n >= 30'000 && n < 30'400) stamp = adapter.stamp(30'400) + 40'000'000 + (n - 30'000) * 1000;
    const auto r = counter.take(static_cast<std::uint64_t>(n) % kRange, stamp);
    ASSERT_NE(r.verdict, Verdict::Reset) << n;
    ASSERT_EQ(r.index, n) << n;
  }
}

TEST(FrameCounter, DuplicatesAndFramesOutOfOrderAreRefusedAndNeverNumberedTwice) {
  Adapter adapter;
  FrameCounter counter(16, kPeriodNs);
  // Frames 0..99, of which 98 and 60 did not come (yet).
  for (std::int64_t n = 0; n < 100; ++n) {
    if (n != 98 && n != 60) {
      ASSERT_EQ(counter.take(static_cast<std::uint64_t>(n), adapter.stamp(n)).index, n);
    }
  }
  // The newest frame again, at once and 2 ms later; an older one that came already.
  EXPECT_EQ(counter.take(99, adapter.stamp(99) + 10'000).verdict, Verdict::Duplicate);
  EXPECT_EQ(counter.take(99, adapter.stamp(99) + 2'000'000).verdict, Verdict::Duplicate);
  EXPECT_EQ(counter.take(97, adapter.stamp(99)).verdict, Verdict::Duplicate);
  EXPECT_EQ(counter.take(36, adapter.stamp(99)).verdict, Verdict::Duplicate);
  // Overtaken frames: 1 and 39 behind the newest; 64 behind, beyond what is remembered.
  EXPECT_EQ(counter.take(98, adapter.stamp(99)).verdict, Verdict::OutOfOrder);
  EXPECT_EQ(counter.take(60, adapter.stamp(99)).verdict, Verdict::OutOfOrder);
  EXPECT_EQ(counter.take(99 - FrameCounter::kReorderFrames, adapter.stamp(99)).verdict, Verdict::OutOfOrder);
  EXPECT_EQ(counter.newest(), 99);
  // The frames after are numbered as if those had not come.
  for (std::int64_t n = 100; n < 200; ++n) {
    const auto r = counter.take(static_cast<std::uint64_t>(n), adapter.stamp(n));
    ASSERT_EQ(r.verdict, Verdict::Next);
    ASSERT_EQ(r.index, n);
  }
  // Across a roll-over: 65535 behind 2 is out of order, not a forward step of 65533.
  FrameCounter wrapped(16, kPeriodNs);
  for (std::int64_t n = 65'530; n < 65'539; ++n) {
    if (n != 65'535) {
      ASSERT_EQ(wrapped.take(static_cast<std::uint64_t>(n) % kRange, adapter.stamp(n)).index, n);
    }
  }
  EXPECT_EQ(wrapped.take(65'535, adapter.stamp(65'539)).verdict, Verdict::OutOfOrder);
  EXPECT_EQ(wrapped.take(65'534, adapter.stamp(65'539)).verdict, Verdict::Duplicate);
  EXPECT_EQ(wrapped.take(65'539 % kRange, adapter.stamp(65'539)).index, 65'539);
}

TEST(FrameCounter, WithoutARateTheValueAloneNumbersTheFrames) {
  // No nominal period: the shortest step forward (the behaviour before receive times counted).
  FrameCounter counter(8, 0.0);
  std::int64_t expected = 250;
  EXPECT_EQ(counter.take(250, 0).index, 250);
  for (int k = 1; k < 600; ++k) {
    ++expected;
    const auto r = counter.take(static_cast<std::uint64_t>(expected) % 256, 0);
    ASSERT_EQ(r.verdict, Verdict::Next);
    ASSERT_EQ(r.index, expected);
  }
  EXPECT_EQ(counter.take(static_cast<std::uint64_t>(expected) % 256, 0).verdict, Verdict::Duplicate);
  EXPECT_EQ(counter.take(static_cast<std::uint64_t>(expected - 3) % 256, 0).verdict, Verdict::Duplicate);
  expected += 2;   // expected - 1 never comes
  EXPECT_EQ(counter.take(static_cast<std::uint64_t>(expected) % 256, 0).index, expected);
  EXPECT_EQ(counter.take(static_cast<std::uint64_t>(expected - 1) % 256, 0).verdict, Verdict::OutOfOrder);
}

TEST(FrameCounter, AWideCounterNeverRollsOverAndGoingBackIsARestart) {
  Adapter adapter;
  FrameCounter counter(32 + 31, kPeriodNs);
  for (std::int64_t n = 0; n < 1000; ++n) ASSERT_EQ(counter.take(static_cast<std::uint64_t>(n) + 5'000'000, adapter.stamp(n)).index, n + 5'000'000);
  EXPECT_EQ(counter.take(5'000'000 + 990, adapter.stamp(1000)).verdict, Verdict::Duplicate);
  const auto r = counter.take(3, adapter.stamp(1500));
  EXPECT_EQ(r.verdict, Verdict::Reset);
  EXPECT_NEAR(static_cast<double>(r.index), 5'000'000.0 + 1500.0, 10.0);
}

}  // namespace
}  // namespace inertia::hal::socketcan
