// The device-clock fit against stamps of known law: a device clock off by a few tens of ppm,
// receive jitter that is one-sided (exponential, 200 us rms), samples lost at random.
#include <gtest/gtest.h>

#include <iostream>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "daq/clock_fit.hpp"

namespace inertia::daq {
namespace {

struct FitRun {
  double p99_error_us = 0.0;   // |fit - true| over the samples after settle_s, 99th percentile
  double drift_ppm = 0.0;
};

FitRun simulate_fit(double rate_hz, double ppm, double jitter_us, double loss, double seconds, double settle_s, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::exponential_distribution<double> jitter(1.0 / (jitter_us * 1e3));
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double period_ns = 1e9 / rate_hz;
  ClockFit fit(1.0 / rate_hz);
  const double t0 = 5e12, floor_ns = 150e3;   // a constant latency floor: not observable, part of the offset
  std::vector<double> errors;
  const auto n = static_cast<std::int64_t>(seconds * rate_hz);
  for (std::int64_t k = 0; k < n; ++k) {
    if (uniform(rng) < loss) continue;
    const double truth = t0 + static_cast<double>(k) * period_ns * (1.0 + ppm * 1e-6);
    fit.add(k, static_cast<std::int64_t>(std::llround(truth + floor_ns + jitter(rng))));
    if (static_cast<double>(k) >= settle_s * rate_hz) errors.push_back(std::abs(fit.time_ns(k) - (truth + floor_ns)) * 1e-3);
  }
  std::sort(errors.begin(), errors.end());
  FitRun r;
  r.p99_error_us = errors[static_cast<std::size_t>(0.99 * static_cast<double>(errors.size()))];
  r.drift_ppm = fit.drift_ppm();
  return r;
}

TEST(ClockFit, SampleTimesWithinTwentyMicrosecondsAfterTenSeconds) {
  // The target: jitter 200 us rms, clocks at +-50 ppm, 0.1 % lost frames; p99 < 20 us.
  for (const double ppm : {-50.0, 0.0, 50.0}) {
    for (const double rate : {1000.0, 10000.0}) {
      const FitRun r = simulate_fit(rate, ppm, 200.0, 1e-3, 30.0, 10.0, 7);
      std::cout << "[ figures ] " << ppm << " ppm at " << rate << " Hz: p99 " << r.p99_error_us << " us, drift "
                << r.drift_ppm << " ppm\n";
      EXPECT_LT(r.p99_error_us, 20.0) << ppm << " ppm at " << rate << " Hz";
      EXPECT_NEAR(r.drift_ppm, ppm, 1.0) << rate << " Hz";
    }
  }
}

TEST(ClockFit, ALateBurstDoesNotDragTheClock) {
  ClockFit fit(1e-3);
  for (std::int64_t k = 0; k < 20000; ++k) {
    std::int64_t stamp = 1'000'000'000 + k * 1'000'000;
    if (k >= 12000 && k < 12500) stamp += 80'000'000;   // half a second of samples 80 ms late
    fit.add(k, stamp);
  }
  EXPECT_NEAR(fit.time_ns(19999), 1'000'000'000.0 + 19999.0 * 1e6, 1e3);
  EXPECT_NEAR(fit.drift_ppm(), 0.0, 0.1);
}

TEST(ClockFit, ALoadedStretchDoesNotTiltTheDrift) {
  // 10 s at 1 kHz, 40 ppm, 200 us rms one-sided jitter; for the first 3 s a loaded PC adds 50 to
  // 150 us to every sample, so every window's least-delayed point stands 50 us or more above the
  // floor. A line through the windows' points would tilt by several ppm toward the late start;
  // the floor below them stays where the unloaded windows put it. Same tolerance as unloaded.
  std::mt19937_64 rng(11);
  std::exponential_distribution<double> jitter(1.0 / 200e3);
  std::uniform_real_distribution<double> load(50e3, 150e3);
  ClockFit fit(1e-3);
  for (std::int64_t k = 0; k < 10000; ++k) {
    const double truth = 5e12 + static_cast<double>(k) * 1e6 * (1.0 + 40e-6);
    fit.add(k, static_cast<std::int64_t>(std::llround(truth + jitter(rng) + (k < 3000 ? load(rng) : 0.0))));
  }
  std::cout << "[ figures ] loaded first 3 s: drift " << fit.drift_ppm() << " ppm (true 40), residual " << fit.residual_us() << " us\n";
  EXPECT_NEAR(fit.drift_ppm(), 40.0, 1.0);
  EXPECT_NEAR(fit.time_ns(9999), 5e12 + 9999.0 * 1e6 * (1.0 + 40e-6), 20e3);
}

// How the floor the fit follows moves with a shared host's load.
enum class Wander {
  kNone,
  kSteps,   // a load level redrawn every 0.5 s (exponential, mean 50 us)
  kSlow,    // a load that comes and goes over seconds: |AR(1)| with a 2 s time constant, rms 50 us
  kMixed,   // a level redrawn every 0.1 s (exponential, mean 60 us) over a slow one (|AR(1)|, 1.5 s):
            // what a loaded CI host showed, the windows nearly independent at lag one
};

TEST(ClockFit, TheDriftsSdCoversItsErrorOverSeedsWhenTheFloorWanders) {
  // 100 Hz for 10 s (a thermal bench's rate and the daemon test's run), 200 us exponential
  // jitter, 0.5 % lost; on top the load's wander. Three reported sd cover the error in at least
  // 97 % of 300 seeds, and the sd is not so wide that it says nothing (its mean within 8 times the
  // error's sd over the seeds).
  for (const Wander wander : {Wander::kNone, Wander::kSteps, Wander::kSlow, Wander::kMixed}) {
    int covered = 0;
    double sum = 0.0, sum2 = 0.0, reported = 0.0;
    constexpr int kSeeds = 300;
    for (int seed = 0; seed < kSeeds; ++seed) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
      std::exponential_distribution<double> jitter(1.0 / 200e3);
      std::uniform_real_distribution<double> uniform(0.0, 1.0);
      std::normal_distribution<double> normal(0.0, 1.0);
      ClockFit fit(1e-2);
      double load_ns = 0.0, slow = normal(rng), fast_ns = 0.0;
      const double time_constant_s = wander == Wander::kMixed ? 1.5 : 2.0;
      const double keep = std::exp(-0.01 / time_constant_s);   // per 10 ms sample
      for (std::int64_t k = 0; k < 1000; ++k) {
        if (wander == Wander::kSteps && k % 50 == 0) load_ns = -std::log(1.0 - uniform(rng)) * 50e3;
        slow = keep * slow + std::sqrt(1.0 - keep * keep) * normal(rng);
        if (wander == Wander::kSlow) load_ns = std::abs(slow) * 50e3;
        if (k % 10 == 0) fast_ns = -std::log(1.0 - uniform(rng)) * 60e3;
        if (wander == Wander::kMixed) load_ns = fast_ns + std::abs(slow) * 60e3;
        if (uniform(rng) < 0.005) continue;
        const double truth = 5e12 + static_cast<double>(k) * 1e7 * (1.0 + 40e-6);
        fit.add(k, static_cast<std::int64_t>(std::llround(truth + jitter(rng) + load_ns)));
      }
      const double error = fit.drift_ppm() - 40.0;
      sum += error;
      sum2 += error * error;
      reported += fit.drift_sd_ppm();
      if (std::abs(error) <= 3.0 * fit.drift_sd_ppm()) ++covered;
    }
    const double sd = std::sqrt(sum2 / kSeeds - (sum / kSeeds) * (sum / kSeeds));
    std::cout << "[ figures ] floor wander " << static_cast<int>(wander) << ": drift error sd " << sd
              << " ppm, mean " << sum / kSeeds << " ppm, reported sd (mean) " << reported / kSeeds
              << " ppm, within 3 reported sd " << covered << "/" << kSeeds << "\n";
    EXPECT_GE(covered, kSeeds * 97 / 100) << static_cast<int>(wander);
    EXPECT_LT(reported / kSeeds, 8.0 * sd) << static_cast<int>(wander);
  }
}

TEST(ClockFit, BeforeTheFirstWindowTheNominalPeriodFromTheEarliestStamp) {
  ClockFit fit(1e-3);
  fit.add(100, 2'000'000'500);
  fit.add(101, 2'001'000'700);   // waited 200 ns longer than the first
  EXPECT_DOUBLE_EQ(fit.time_ns(100), 2'000'000'500.0);
  EXPECT_DOUBLE_EQ(fit.time_ns(110), 2'010'000'500.0);
  EXPECT_EQ(fit.points(), 0u);
}

TEST(ClockFit, AStartUpBurstIsNotTheWindowsLeastDelayedSample) {
  // The first 5 samples arrive together at the 6th's time. The window's point must be one of the
  // prompt samples after them: ranked against the line that moved as the burst came in, the
  // burst's last sample won and the first fits stood 4 ms off.
  std::mt19937_64 rng(3);
  std::exponential_distribution<double> jitter(1.0 / 200e3);
  const auto truth = [](std::int64_t k) { return 5e12 + static_cast<double>(k) * 1e6; };
  ClockFit fit(1e-3);
  double worst_us = 0.0;
  for (std::int64_t k = 0; k < 1000; ++k) {
    fit.add(k, static_cast<std::int64_t>(std::llround((k < 5 ? truth(5) : truth(k)) + jitter(rng))));
    if (k >= 100) worst_us = std::max(worst_us, std::abs(fit.time_ns(k) - truth(k)) * 1e-3);
  }
  std::cout << "[ figures ] 5 ms start-up burst: fit off by at most " << worst_us << " us after the first window\n";
  EXPECT_LT(worst_us, 50.0);
}

// The CI failure this came from: the run's first samples reached the daemon late (a busy host at
// start). The fit's first edges are then tilted (two points, one late) and the next refit moves
// its line by ms; blocks stamped straight from the fit stepped between consecutive blocks, and
// the live analyzer counted a gap of samples that were all there. Stamped through the slewed
// time base, the blocks meet to a nanosecond, their periods stay within 2 % of the fit's, and
// the published times reach the fit as soon as a 2 % slew can take the correction in (the 100 ms
// the first blocks went out late: 5 s) and stay on it.
TEST(SlewedTimeBase, AStartUpStallMovesTheFitButNotTheBlocksApart) {
  std::mt19937_64 rng(3);
  std::exponential_distribution<double> jitter(1.0 / 200e3);
  const double period_ns = 1e6 * (1.0 + 50e-6);
  const auto truth = [&](std::int64_t k) { return 5e12 + static_cast<double>(k) * period_ns; };
  ClockFit fit(1e-3);
  SlewedTimeBase published;
  constexpr std::int32_t kBlock = 10;
  double largest_fit_step_ns = 0.0, previous_fit_end = std::nan(""), previous_end = std::nan("");
  double largest_seam_ns = 0.0, worst_slew = 0.0, settled_end_error_ns = 0.0;
  std::int64_t on_the_fit_from = -1;
  for (std::int64_t k = 0; k < 10000; ++k) {
    // The first 100 ms arrive together at their end.
    const double stamp = (k < 100 ? truth(100) : truth(k)) + jitter(rng);
    fit.add(k, static_cast<std::int64_t>(std::llround(stamp)));
    if ((k + 1) % kBlock != 0) continue;
    const std::int64_t first = k + 1 - kBlock;
    if (!std::isnan(previous_fit_end)) largest_fit_step_ns = std::max(largest_fit_step_ns, std::abs(fit.time_ns(first) - previous_fit_end));
    previous_fit_end = fit.time_ns(first + kBlock);
    const SlewedTimeBase::BlockTime b = published.block(fit, first, kBlock);
    const double t0 = static_cast<double>(b.t0_ns), p = b.period_s * 1e9;
    if (!std::isnan(previous_end)) largest_seam_ns = std::max(largest_seam_ns, std::abs(t0 - previous_end));
    previous_end = t0 + kBlock * p;
    worst_slew = std::max(worst_slew, std::abs(p / (fit.period_s() * 1e9) - 1.0));
    const double end_error_ns = std::abs(previous_end - fit.time_ns(first + kBlock));
    if (end_error_ns > 1.0) on_the_fit_from = -1;
    else if (on_the_fit_from < 0) on_the_fit_from = k;
    if (k > 8000) settled_end_error_ns = std::max(settled_end_error_ns, end_error_ns);
  }
  std::cout << "[ figures ] start-up stall of 100 ms: fit steps up to " << largest_fit_step_ns * 1e-3
            << " us between blocks; published seams " << largest_seam_ns << " ns, slew " << worst_slew * 100
            << " %, largest correction " << published.largest_correction_us() << " us, on the fit from "
            << on_the_fit_from * 1e-3 << " s\n";
  ASSERT_GT(largest_fit_step_ns, 500e3);   // the fit alone steps by more than half a period
  EXPECT_LT(largest_seam_ns, 1.0);
  EXPECT_LE(worst_slew, 0.02 + 1e-12);
  EXPECT_GT(published.largest_correction_us(), 500.0);
  ASSERT_GE(on_the_fit_from, 0);
  EXPECT_LT(static_cast<double>(on_the_fit_from) * 1e-3, published.largest_correction_us() * 1e-6 / 0.02 + 0.5);
  EXPECT_LT(settled_end_error_ns, 1.0);
}

TEST(SlewedTimeBase, NumbersThatJumpStartOnTheFit) {
  ClockFit fit(1e-3);
  for (std::int64_t k = 0; k < 1000; ++k) fit.add(k, 1'000'000'000 + k * 1'000'000);
  SlewedTimeBase published;
  (void)published.block(fit, 0, 10);
  const SlewedTimeBase::BlockTime after_gap = published.block(fit, 500, 10);
  EXPECT_EQ(after_gap.t0_ns, std::llround(fit.time_ns(500)));
  EXPECT_DOUBLE_EQ(after_gap.period_s, fit.period_s());
}

}  // namespace
}  // namespace inertia::daq
