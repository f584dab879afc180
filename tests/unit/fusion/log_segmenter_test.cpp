// The log segmenter: a log without plan markers cut into the plan's cases and phases
// from the references' motion, on synthetic blocks whose true boundaries are known.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "analyzer/fusion/log_segmenter.hpp"
#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"

namespace inertia::fusion {
namespace {

using config::PhaseKind;

config::Phase phase(PhaseKind kind, double duration_s) {
  config::Phase p;
  p.kind = kind;
  p.duration_s = duration_s;
  if (kind == PhaseKind::Rotation) p.rate_rad_s = 10.0 * std::numbers::pi / 180.0;
  if (kind == PhaseKind::Sine) {
    p.frequency_hz = 50.0;
    p.amplitude_mps2 = 5.0;
  }
  return p;
}

// A table case (dwell 2 s, rotation 4 s) and a shaker case (dwell 2 s, sine 3 s), one monitor.
config::BenchConfig bench() {
  config::BenchConfig b;
  b.table_encoder = {true, 1e-6, "table.position"};
  config::MonitorAccelerometer m;
  m.name = "mon1";
  m.channel = "ref.mon1";
  b.monitors.push_back(m);
  config::TestCase table;
  table.name = "table";
  table.kind = CaseKind::RotationTable;
  table.phases = {phase(PhaseKind::Dwell, 2.0), phase(PhaseKind::Rotation, 4.0)};
  config::TestCase shaker;
  shaker.name = "shaker";
  shaker.kind = CaseKind::Shaker;
  shaker.phases = {phase(PhaseKind::Dwell, 2.0), phase(PhaseKind::Sine, 3.0)};
  b.cases = {table, shaker};
  return b;
}

sample_block_t block(const std::string& device, const std::string& channel, std::int64_t t0_ns, const std::vector<double>& v) {
  sample_block_t b{};
  b.device = device;
  b.t0_mono_ns = t0_ns;
  b.sample_period_s = 1e-3;
  b.num_channels = 1;
  b.channel_ids = {1};
  b.channel_names = {channel};
  b.units = {"1"};
  b.channel_seq = {0};
  shape_sample_block(b, 1, static_cast<std::int32_t>(v.size()));
  for (std::size_t s = 0; s < v.size(); ++s) {
    b.values[0][s] = v[s];
    set_sample_valid(b, 0, static_cast<std::int32_t>(s), true);
  }
  return b;
}

// The truth: rest 0-3 s (1 s before the plan), rotation 3-7, rest 7-9, sine 9-12, rest 12-13,
// in blocks of 0.1 s (shorter than a window, so that the window grid matters), table first.
constexpr std::int64_t kOrigin = 5'000'000'000;
std::vector<sample_block_t> blocks() {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.002);
  double angle = 0.0;
  std::vector<sample_block_t> out;
  for (int tenth = 0; tenth < 130; ++tenth) {
    std::vector<double> table(100), mon(100);
    for (int k = 0; k < 100; ++k) {
      const double t = tenth * 0.1 + k * 1e-3;
      if (t >= 3.0 && t < 7.0) angle += 10.0 * std::numbers::pi / 180.0 * 1e-3;
      table[static_cast<std::size_t>(k)] = angle;
      mon[static_cast<std::size_t>(k)] = 9.80665 + noise(rng) + (t >= 9.0 && t < 12.0 ? 5.0 * std::sin(2 * std::numbers::pi * 50 * t) : 0.0);
    }
    const std::int64_t t0 = kOrigin + tenth * 100'000'000LL;
    out.push_back(block("table", "position", t0, table));
    out.push_back(block("ref", "mon1", t0, mon));
  }
  return out;
}

void feed(MotionClassifier& motion) {
  for (const sample_block_t& b : blocks()) motion.push(b);
}

// The runs with their vibration edges placed by the second pass over the same blocks.
std::vector<MotionRun> refined_runs() {
  MotionClassifier motion(bench());
  feed(motion);
  VibrationEdgeRefiner edges(motion, motion.runs());
  for (const sample_block_t& b : blocks()) edges.push(b);
  return edges.runs();
}

TEST(LogSegmenter, ClassesTheReferencesMotionIntoRuns) {
  MotionClassifier motion(bench());
  feed(motion);
  const std::vector<MotionRun> runs = motion.runs();
  ASSERT_EQ(runs.size(), 5u);
  const MotionClass want[] = {MotionClass::Static, MotionClass::Rotation, MotionClass::Static, MotionClass::Vibration,
                              MotionClass::Static};
  const double edges[] = {0.0, 3.0, 7.0, 9.0, 12.0, 13.0};
  for (std::size_t i = 0; i < runs.size(); ++i) {
    EXPECT_EQ(runs[i].motion, want[i]) << i;
    EXPECT_NEAR((runs[i].start_ns - kOrigin) * 1e-9, edges[i], kSegmentWindowS) << i;
    EXPECT_NEAR((runs[i].end_ns - kOrigin) * 1e-9, edges[i + 1], kSegmentWindowS) << i;
  }
  // The floor is the monitor's noise sd, 0.002 m/s^2, read as the 10th percentile of 26 window
  // sds of 500 samples each (each within ~3 % of it, the percentile ~1.3 of those low): the
  // threshold is 10x it, within 10 % (3 sd of the percentile).
  EXPECT_NEAR(motion.vibration_threshold(), 10.0 * 0.002, 10.0 * 0.002 * 0.1);
}

TEST(LogSegmenter, RunsDoNotDependOnTheOrderTheLogHoldsTheBlocksIn) {
  // A daemon under load logs its devices' blocks in a varying interleave: the table's in time
  // order, a monitor's wherever its thread wrote them. Here the monitor's all come first, last
  // to first, and the first sample seen is the monitor's last.
  MotionClassifier forward(bench()), shuffled(bench());
  feed(forward);
  std::vector<sample_block_t> monitor, table;
  for (const sample_block_t& b : blocks()) (b.device == "ref" ? monitor : table).push_back(b);
  for (auto it = monitor.rbegin(); it != monitor.rend(); ++it) shuffled.push(*it);
  for (const sample_block_t& b : table) shuffled.push(b);
  const std::vector<MotionRun> a = forward.runs(), b = shuffled.runs();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].motion, b[i].motion) << i;
    EXPECT_EQ(a[i].start_ns, b[i].start_ns) << i;
    EXPECT_EQ(a[i].end_ns, b[i].end_ns) << i;
  }
  // The window sums add the same samples in another order: equal to rounding, which the sd's
  // cancellation (gravity's square against the noise's, 1e-7 of it) magnifies to ~1e-9.
  EXPECT_NEAR(forward.vibration_threshold(), shuffled.vibration_threshold(), 1e-6 * forward.vibration_threshold());
}

TEST(LogSegmenter, ABlockTheAssemblerWouldRefuseIsNoMotion) {
  // fuzz_event_log's finding: a block whose times lie past int64 overflowed the window index.
  MotionClassifier motion(bench());
  feed(motion);
  const std::vector<MotionRun> before = motion.runs();
  sample_block_t hostile = block("ref", "mon1", kOrigin, std::vector<double>(50, 100.0));
  hostile.sample_period_s = 1e70;
  motion.push(hostile);
  hostile.sample_period_s = 1e-3;
  hostile.valid_bytes = 1;   // malformed: another length than its samples need
  motion.push(hostile);
  VibrationEdgeRefiner edges(motion, motion.runs());
  edges.push(hostile);
  const std::vector<MotionRun> after = motion.runs();
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t i = 0; i < after.size(); ++i) EXPECT_EQ(after[i].start_ns, before[i].start_ns) << i;
}

TEST(LogSegmenter, VibrationEdgesArePlacedToTheSample) {
  MotionClassifier motion(bench());
  feed(motion);
  const std::vector<MotionRun> coarse = motion.runs(), fine = refined_runs();
  ASSERT_EQ(fine.size(), 5u);
  ASSERT_EQ(fine[3].motion, MotionClass::Vibration);
  const auto sec = [](double ns) { return (ns - kOrigin) * 1e-9; };
  // The sine starts at zero, so its first sample is rest: the change is found within a sample
  // or two; the windows alone placed it within a window (62.5 ms here).
  EXPECT_NEAR(sec(fine[3].start_ns), 9.0, 2e-3);
  EXPECT_NEAR(sec(fine[3].end_ns), 12.0, 2e-3);
  EXPECT_NEAR(sec(coarse[3].start_ns), 9.0, motion.window_s());
  // Only the samples within the likelihood interval are left to neither run.
  EXPECT_LE(fine[3].start_ns - fine[2].end_ns, 3e6);
  EXPECT_LE(fine[4].start_ns - fine[3].end_ns, 3e6);
  // Rotation's edges are the encoder's, untouched.
  EXPECT_EQ(fine[1].start_ns, coarse[1].start_ns);
  EXPECT_EQ(fine[1].end_ns, coarse[1].end_ns);
}

TEST(LogSegmenter, CutsThePlanAtDetectedChangesAndPlacesTheRestByDuration) {
  MotionClassifier motion(bench());
  feed(motion);
  const Segmentation seg = segment_plan(bench(), motion.runs(), kOrigin);
  // Per case: start, one start per phase, end.
  ASSERT_EQ(seg.markers.size(), 8u);
  const auto at = [](const plan_event_t& m) { return (static_cast<double>(m.start_mono_ns) - kOrigin) * 1e-9; };
  EXPECT_EQ(seg.markers[0].mark, plan_event_t::MARK_CASE_START);
  EXPECT_EQ(seg.markers[0].case_name, "table");
  // The table's dwell starts where the plan's 2 s end at the detected rotation start (the rest
  // before the plan belongs to it only up to its duration), the rotation at the change.
  EXPECT_NEAR(at(seg.markers[1]), 1.0, kSegmentWindowS);
  EXPECT_EQ(seg.markers[1].phase, "static");
  EXPECT_NEAR(at(seg.markers[2]), 3.0, kSegmentWindowS);
  EXPECT_EQ(seg.markers[2].phase, "rotation");
  EXPECT_EQ(seg.markers[3].mark, plan_event_t::MARK_CASE_END);
  EXPECT_NEAR((static_cast<double>(seg.markers[3].end_mono_ns) - kOrigin) * 1e-9, 7.0, kSegmentWindowS);
  EXPECT_EQ(seg.markers[4].case_name, "shaker");
  EXPECT_NEAR(at(seg.markers[5]), 7.0, kSegmentWindowS);
  EXPECT_NEAR(at(seg.markers[6]), 9.0, kSegmentWindowS);
  EXPECT_EQ(seg.markers[6].phase, "sine");
  EXPECT_NEAR((static_cast<double>(seg.markers[7].end_mono_ns) - kOrigin) * 1e-9, 12.0, kSegmentWindowS);
  ASSERT_EQ(seg.description.size(), 2u);
  EXPECT_NE(seg.description[0].find("plan duration"), std::string::npos) << seg.description[0];
}

TEST(LogSegmenter, TwoCasesMeetingInOneRestLeaveTheSamplesAroundTheCutToNeither) {
  // The table case ends and the shaker case begins where the rotation stops, at 7 s (to the
  // encoder's sample); the sine's edges to a sample or two after the second pass.
  const Segmentation seg = segment_plan(bench(), refined_runs(), kOrigin);
  ASSERT_EQ(seg.markers.size(), 8u);
  const auto sec = [](std::int64_t ns) { return (static_cast<double>(ns) - kOrigin) * 1e-9; };
  const double guard = 10e-3;   // ten samples at the bench's 1 kHz
  EXPECT_NEAR(sec(seg.markers[3].end_mono_ns), 7.0 - guard, 1.5e-3);
  EXPECT_NEAR(sec(seg.markers[4].start_mono_ns), 7.0 + guard, 1.5e-3);
  EXPECT_NEAR(sec(seg.markers[6].start_mono_ns), 9.0, 2e-3);
  EXPECT_NEAR(sec(seg.markers[7].end_mono_ns), 12.0, 2e-3);
  EXPECT_NE(seg.description[0].find("plan duration"), std::string::npos) << seg.description[0];
}

TEST(LogSegmenter, AMotionThePlanDoesNotHaveOrAShockIsBadInput) {
  MotionClassifier motion(bench());
  feed(motion);
  config::BenchConfig other = bench();
  other.cases.pop_back();   // the plan ends with the table: the sine is unaccounted for
  try {
    (void)segment_plan(other, motion.runs(), kOrigin);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("(static, rotation, static, vibration)"), std::string::npos) << what;
    EXPECT_NE(what.find("(static, rotation)"), std::string::npos) << what;
    EXPECT_NE(what.find("inertia-daqd mark"), std::string::npos) << what;
  }
  config::BenchConfig shock = bench();
  shock.cases[1].phases[1].kind = PhaseKind::Shock;
  EXPECT_THROW((void)segment_plan(shock, motion.runs(), kOrigin), InputError);
}

}  // namespace
}  // namespace inertia::fusion
