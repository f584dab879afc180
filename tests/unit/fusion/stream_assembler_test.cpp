// StreamAssembler on synthetic messages with a known truth: noise-free monitors, encoders and
// sensor output generated from a chosen specific force, pushed as the daemon would (devices
// interleaved, markers first), then with a lost block, invalid samples and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/fusion/stream_assembler.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"
#include "common/units.hpp"

namespace inertia::fusion {
namespace {

constexpr double kRate = 1000.0;
constexpr std::int64_t kT0 = 1'000'000'000;   // ns
constexpr std::int64_t kPeriodNs = 1'000'000;
constexpr std::int32_t kBlock = 50;

// Four skewed monitors (section 2.3 layout), a shaker case, a static case and a table case with
// two rotations about different axes (the attitude must be carried from one to the next).
const char* const kBench = R"([bench]
name = "synthetic"
sample_rate_hz = 1000.0

[[sensor]]
name = "acc1"
type = "accelerometer"

[[sensor]]
name = "acc2"
type = "accelerometer"

[[monitor]]
name = "mon1"
axis = [0.70710678, 0.70710678, 0.0]
bias_g = 2e-3
scale_error = 1e-3
noise_sd_g = 5e-4
[[monitor]]
name = "mon2"
axis = [0.70710678, 0.0, 0.70710678]
bias_g = -1e-3
noise_sd_g = 5e-4
[[monitor]]
name = "mon3"
axis = [0.70710678, -0.70710678, 0.0]
noise_sd_g = 5e-4
[[monitor]]
name = "mon4"
axis = [0.70710678, 0.0, -0.70710678]
noise_sd_g = 5e-4

[linear_encoder]
resolution_m = 1e-9

[table_encoder]
resolution_rad = 1e-9

[[case]]
name = "still"
kind = "static"
orientation = "IA"
[[case.phase]]
kind = "dwell"
duration_s = 1.0

[[case]]
name = "shake"
kind = "shaker"
orientation = "PA"
[[case.phase]]
kind = "sine"
frequency_hz = 10.0
amplitude_g = 1.0
duration_s = 1.0

[[case]]
name = "turn"
kind = "rotation_table"
m_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[[case.phase]]
kind = "rotation"
axis = [1.0, 0.0, 0.0]
angle_deg = 90.0
duration_s = 1.0
[[case.phase]]
kind = "rotation"
axis = [0.0, 1.0, 0.0]
rate_deg_s = 90.0
duration_s = 1.0
)";

constexpr double kOmega = 2 * kPi * 10.0;          // shaker sine
constexpr double kAmp = kStandardGravity;          // 1 g

// Truth over the plan: case 0 samples [0, 1000), case 1 [1000, 2000), case 2 [2000, 4000).
struct Truth {
  Eigen::Vector3d a;
  double x_m = 0.0;       // armature displacement
  double angle = 0.0;     // table angle
  std::string phase;
};

double turn_angle(std::int64_t k) {   // phase 0: 90 deg over 1 s, smooth; phase 1: 90 deg/s
  const double t = static_cast<double>(k) / kRate;
  if (k < 1000) return 0.5 * (kPi / 2) * (1 - std::cos(kPi * t));
  return kPi / 2 + (kPi / 2) * (t - 1.0);
}

Truth truth_at(std::int64_t n) {
  Truth tr;
  const Eigen::Vector3d g(0, 0, kStandardGravity);
  if (n < 1000) {
    tr.a = g;
    tr.phase = "static";
  } else if (n < 2000) {
    const double t = static_cast<double>(n - 1000) / kRate;
    tr.a = g + Eigen::Vector3d(kAmp * std::sin(kOmega * t), 0, 0);
    tr.x_m = -kAmp / (kOmega * kOmega) * std::sin(kOmega * t);
    tr.phase = "sine";
  } else {
    const std::int64_t k = n - 2000;
    tr.angle = turn_angle(k);
    const frames::Dcm after_first = frames::frame_rotation(Eigen::Vector3d::UnitX(), kPi / 2);
    tr.a = k < 1000 ? Eigen::Vector3d(frames::frame_rotation(Eigen::Vector3d::UnitX(), tr.angle) * g)
                    : Eigen::Vector3d(frames::frame_rotation(Eigen::Vector3d::UnitY(), tr.angle - kPi / 2) * after_first * g);
    tr.phase = "rotation";
  }
  return tr;
}

double output_of(const Eigen::Vector3d& a) { return 3.0 * a.x() - 0.5 * a.z() + 0.25; }

bench_config_t bench_message() {
  bench_config_t b{};
  b.bench_name = "synthetic";
  b.num_files = 1;
  b.paths = {"synthetic.toml"};
  b.texts = {kBench};
  return b;
}

sample_block_t block(const std::string& device, const std::vector<std::string>& names, std::int64_t first,
                     std::int32_t n, std::int64_t seq) {
  sample_block_t b{};
  b.device = device;
  shape_sample_block(b, static_cast<std::int32_t>(names.size()), n);
  b.seq = seq;
  b.t0_mono_ns = kT0 + first * kPeriodNs;
  b.sample_period_s = 1.0 / kRate;
  for (std::size_t c = 0; c < names.size(); ++c) {
    b.channel_ids[c] = static_cast<std::int32_t>(c + 1);
    b.channel_names[c] = names[c];
    b.units[c] = "1";
    b.channel_seq[c] = first;
    for (std::int32_t s = 0; s < n; ++s) set_sample_valid(b, static_cast<std::int32_t>(c), s, true);
  }
  return b;
}

sample_block_t accel_block(std::int64_t first, std::int32_t n) {
  // What the monitors read: (1 + scale) n.a + bias, as the bench file calibrates them.
  const Eigen::Vector3d axes[4] = {Eigen::Vector3d(1, 1, 0).normalized(), Eigen::Vector3d(1, 0, 1).normalized(),
                                   Eigen::Vector3d(1, -1, 0).normalized(), Eigen::Vector3d(1, 0, -1).normalized()};
  const double bias[4] = {g_to_mps2(2e-3), g_to_mps2(-1e-3), 0, 0};
  const double scale[4] = {1e-3, 0, 0, 0};
  sample_block_t b = block("accel", {"acc1", "acc2", "mon1", "mon2", "mon3", "mon4", "sample_index"}, first, n, first / kBlock);
  for (std::int32_t s = 0; s < n; ++s) {
    const Truth tr = truth_at(first + s);
    const auto ss = static_cast<std::size_t>(s);
    b.values[0][ss] = output_of(tr.a);
    b.values[1][ss] = -output_of(tr.a);
    for (int j = 0; j < 4; ++j) b.values[2 + static_cast<std::size_t>(j)][ss] = (1 + scale[j]) * axes[j].dot(tr.a) + bias[j];
    b.values[6][ss] = static_cast<double>(first + s);
  }
  return b;
}

sample_block_t encoder_block(const std::string& device, std::int64_t first, std::int32_t n) {
  sample_block_t b = block(device, {"count", "position"}, first, n, first / kBlock);
  for (std::int32_t s = 0; s < n; ++s) {
    const Truth tr = truth_at(first + s);
    b.values[1][static_cast<std::size_t>(s)] = device == "table_encoder" ? tr.angle : tr.x_m;
  }
  return b;
}

plan_event_t mark(std::int8_t what, const std::string& c, const std::string& kind, std::int32_t phase,
                  const std::string& label, std::int64_t first, std::int64_t last) {
  plan_event_t e{};
  e.mark = what;
  e.case_name = c;
  e.kind = kind;
  e.phase = label;
  e.phase_index = phase;
  e.mono_ns = kT0 + (what == plan_event_t::MARK_CASE_END ? last : first) * kPeriodNs;
  e.start_mono_ns = kT0 + first * kPeriodNs;
  e.end_mono_ns = kT0 + last * kPeriodNs;
  return e;
}

struct PlanRun {
  std::vector<FusedSegment> segments;
  std::unique_ptr<StreamAssembler> assembler;
};

// Pushes the plan as the daemon does: markers when their sample is written (ahead of the
// samples), the devices' blocks interleaved. `edit` may drop or alter accel blocks.
PlanRun run_plan(const std::string& sensor, const std::function<bool(sample_block_t&)>& edit = {}) {
  PlanRun r;
  AssemblerOptions o;
  o.sensor = sensor;
  o.min_segment_s = 0.1;
  r.assembler = std::make_unique<StreamAssembler>(o, [&r](FusedSegment&& s) { r.segments.push_back(std::move(s)); });
  StreamAssembler& a = *r.assembler;
  a.push(bench_message(), "bench");
  struct C {
    const char* name;
    const char* kind;
    std::int64_t first, last;
    std::vector<std::pair<std::int64_t, const char*>> phases;
  };
  const std::vector<C> plan = {{"still", "static", 0, 999, {{0, "static"}}},
                               {"shake", "shaker", 1000, 1999, {{1000, "sine"}}},
                               {"turn", "rotation_table", 2000, 3999, {{2000, "rotation"}, {3000, "rotation"}}}};
  int event = 0;
  for (std::int64_t first = 0; first < 4000; first += kBlock) {
    for (const C& c : plan) {
      if (c.first >= first && c.first < first + kBlock) {
        a.push(mark(plan_event_t::MARK_CASE_START, c.name, c.kind, -1, "", c.first, c.last + 1), "event " + std::to_string(event++));
        for (std::size_t p = 0; p < c.phases.size(); ++p)
          a.push(mark(plan_event_t::MARK_PHASE_START, c.name, c.kind, static_cast<std::int32_t>(p), c.phases[p].second,
                      c.phases[p].first, c.phases[p].first + 1000), "event " + std::to_string(event++));
      }
    }
    sample_block_t acc = accel_block(first, kBlock);
    const bool keep = !edit || edit(acc);
    a.push(encoder_block("table_encoder", first, kBlock), "table");
    if (keep) a.push(acc, "accel block " + std::to_string(first / kBlock));
    a.push(encoder_block("linear_encoder", first, kBlock), "linear");
    for (const C& c : plan)
      if (c.last >= first && c.last < first + kBlock)
        a.push(mark(plan_event_t::MARK_CASE_END, c.name, c.kind, -1, "", c.first, c.last), "event " + std::to_string(event++));
  }
  a.finish();
  return r;
}

TEST(StreamAssembler, InterleavedDevicesGiveTheTruthPerCase) {
  const PlanRun r = run_plan("acc1");
  ASSERT_EQ(r.segments.size(), 3u);
  const char* names[] = {"still", "shake", "turn"};
  const std::int64_t firsts[] = {0, 1000, 2000};
  for (std::size_t c = 0; c < 3; ++c) {
    SCOPED_TRACE(names[c]);
    const FusedSegment& s = r.segments[c];
    EXPECT_EQ(s.case_name, names[c]);
    EXPECT_EQ(s.case_index, c);
    EXPECT_DOUBLE_EQ(s.sample_period_s, 1e-3);
    ASSERT_EQ(s.t.size(), c == 2 ? 2000 : 1000);
    double worst = 0.0, worst_y = 0.0;
    // The shaker's complementary filter starts from rest: judge after its settling (~5 time
    // constants of a 5 Hz critically damped pair, 0.3 s); the table's derivatives are central.
    const Eigen::Index from = c == 1 ? 300 : 1;
    for (Eigen::Index k = from; k < s.t.size() - 1; ++k) {
      const Truth tr = truth_at(firsts[c] + k);
      worst = std::max(worst, (s.a_e.row(k).transpose() - tr.a).norm());
      worst_y = std::max(worst_y, std::abs(s.y(k) - output_of(tr.a)));
      EXPECT_EQ(s.phase_names[s.phase[static_cast<std::size_t>(k)]], tr.phase);
    }
    // Noise-free inputs: monitors exact to rounding; the table's second difference of a smooth
    // angle is off by O((w T)^2); the encoder's double difference at 10 Hz by (wT)^2/12 = 3e-4.
    EXPECT_LT(worst, c == 1 ? 1e-3 * kAmp : 1e-6 * kStandardGravity) << "worst |a_E - truth|";
    EXPECT_EQ(worst_y, 0.0);
    EXPECT_NEAR(s.t(0), 0.0, 1e-15);
    ASSERT_TRUE(s.w_e.has_value());
  }
  // Table: the rate is the encoder's, about the phase's axis.
  const FusedSegment& turn = r.segments[2];
  EXPECT_NEAR((*turn.w_e)(1500, 1), kPi / 2, 1e-6);
  EXPECT_NEAR((*turn.w_e)(1500, 0), 0.0, 1e-9);
  EXPECT_NEAR((*turn.w_e)(500, 0), (turn_angle(501) - turn_angle(499)) * kRate / 2, 1e-9);
  EXPECT_TRUE(r.assembler->exclusions().empty());
  EXPECT_TRUE(r.assembler->gaps().empty());
  EXPECT_EQ(r.assembler->fused_rows(), 4000);
}

// A static case is a pose: its specific force is the pose's gravity, whatever the bench's
// monitors read there (their noise in every row's regressors is what a nonlinear candidate of an
// axis at rest fits). The shaker case still reads them.
TEST(StreamAssembler, AStaticCaseTakesThePosesGravityNotTheMonitors) {
  const PlanRun r = run_plan("acc1", [](sample_block_t& b) {
    if (b.t0_mono_ns >= kT0 + 1000 * kPeriodNs) return true;
    for (std::size_t c = 2; c < 6; ++c)
      for (std::size_t s = 0; s < b.values[c].size(); ++s) b.values[c][s] += (s % 2 == 0 ? 0.05 : -0.03) * static_cast<double>(c);
    return true;
  });
  ASSERT_EQ(r.segments.size(), 3u);
  const FusedSegment& still = r.segments[0];
  ASSERT_EQ(still.case_name, "still");
  ASSERT_EQ(still.a_e.rows(), 1000);
  for (Eigen::Index k = 0; k < still.a_e.rows(); ++k)
    ASSERT_EQ(still.a_e.row(k), Eigen::RowVector3d(0.0, 0.0, kStandardGravity)) << "row " << k;
  const FusedSegment& shake = r.segments[1];
  double worst = 0.0;
  for (Eigen::Index k = 300; k < shake.a_e.rows() - 1; ++k) worst = std::max(worst, (shake.a_e.row(k).transpose() - truth_at(1000 + k).a).norm());
  EXPECT_LT(worst, 1e-3 * kAmp);
}

TEST(StreamAssembler, LostBlockSplitsTheCaseAndIsCounted) {
  // Accel block 25 (samples 1250..1299 of the shaker case) never arrives.
  const PlanRun r = run_plan("acc2", [](sample_block_t& b) { return b.t0_mono_ns != kT0 + 1250 * kPeriodNs; });
  ASSERT_EQ(r.assembler->gaps().size(), 1u);
  EXPECT_EQ(r.assembler->gaps()[0].device, "accel");
  EXPECT_EQ(r.assembler->gaps()[0].missing_samples, 50);
  EXPECT_EQ(r.assembler->gaps()[0].missing_seq, 50);
  EXPECT_EQ(r.assembler->gaps()[0].where, "accel block 26");
  std::vector<const FusedSegment*> shake;
  for (const auto& s : r.segments)
    if (s.case_name == "shake") shake.push_back(&s);
  ASSERT_EQ(shake.size(), 2u);
  EXPECT_EQ(shake[0]->t.size(), 250);
  EXPECT_EQ(shake[1]->t.size(), 700);
  EXPECT_EQ(shake[1]->segment, 1);
  EXPECT_NEAR(shake[1]->t(0), 0.3, 1e-12);
  EXPECT_DOUBLE_EQ(shake[1]->y(10), -output_of(truth_at(1310).a)) << "acc2 is the other sensor's column";
  std::int64_t missing = 0;
  for (const Exclusion& x : r.assembler->exclusions()) {
    EXPECT_EQ(x.case_name, "shake");
    EXPECT_NE(x.reason.find("missing (gap)"), std::string::npos) << x.reason;
    EXPECT_NEAR(x.t_s, 0.25, 1e-12);
    missing = std::max(missing, x.samples);
  }
  EXPECT_EQ(missing, 50);
  EXPECT_EQ(r.assembler->fused_rows(), 4000 - 50);
}

TEST(StreamAssembler, InvalidSamplesAreExcludedNeverFilled) {
  // mon2 invalid for samples 300..309 of the shaker case; the sensor output invalid at 3500.
  const PlanRun r = run_plan("acc1", [](sample_block_t& b) {
    const std::int64_t first = (b.t0_mono_ns - kT0) / kPeriodNs;
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      if (first + s >= 1300 && first + s < 1310) set_sample_valid(b, 3, s, false);
      if (first + s == 3500) set_sample_valid(b, 0, s, false);
    }
    return true;
  });
  std::vector<std::size_t> sizes;
  for (const auto& s : r.segments) sizes.push_back(static_cast<std::size_t>(s.t.size()));
  EXPECT_EQ(sizes, (std::vector<std::size_t>{1000, 300, 690, 1500, 499}));
  std::int64_t mon2 = 0, acc1 = 0;
  for (const Exclusion& x : r.assembler->exclusions()) {
    if (x.reason == "accel.mon2 invalid") mon2 += x.samples;
    if (x.reason == "accel.acc1 invalid") acc1 += x.samples;
  }
  EXPECT_EQ(mon2, 10);
  EXPECT_EQ(acc1, 1);
  // The segment after the invalid run starts where the samples come back, on the same timeline.
  EXPECT_NEAR(r.segments[2].t(0), 0.310, 1e-12);
  EXPECT_NEAR(r.segments[2].a_e(0, 2), kStandardGravity, 1e-9);
  // The table segment after sample 3500: still the attitude of the second phase.
  const FusedSegment& last = r.segments.back();
  EXPECT_NEAR(last.t(0), 1.501, 1e-12);
  EXPECT_LT((last.a_e.row(100).transpose() - truth_at(2000 + 1601).a).norm(), 1e-6);
}

// A lost frame of the accel device (the output and every monitor invalid for three
// samples, the encoders intact) cuts the output there, and nothing else: the fusion goes on
// through the hole (the table's differences, the shaker's filter coasting on its encoder), so the
// rows after it equal an unbroken stream's. Restarting the fusion there put a 2 m/s^2 offset on
// the next shaker piece of a real-style log (the new differences' first values, extrapolated,
// in the filter's low path) and one-sided differences on the table's.
TEST(StreamAssembler, ALostFrameCutsTheOutputButNotTheFusion) {
  const std::vector<std::int64_t> holes = {1400, 3300};   // mid-sine on the shaker; mid-rotation on the table
  const auto lose = [&](sample_block_t& b) {
    const std::int64_t first = (b.t0_mono_ns - kT0) / kPeriodNs;
    for (std::int32_t s = 0; s < b.num_samples; ++s)
      for (const std::int64_t h : holes)
        if (first + s >= h && first + s < h + 3)
          for (std::int32_t c = 0; c < b.num_channels; ++c) set_sample_valid(b, c, s, false);
    return true;
  };
  const PlanRun whole = run_plan("acc1");
  const PlanRun cut = run_plan("acc1", lose);
  std::vector<std::size_t> sizes;
  for (const auto& s : cut.segments) sizes.push_back(static_cast<std::size_t>(s.t.size()));
  EXPECT_EQ(sizes, (std::vector<std::size_t>{1000, 400, 597, 1300, 697}));
  EXPECT_EQ(cut.assembler->fused_rows(), 4000 - 6);
  // Every row of every piece equals the unbroken stream's row at the same time.
  double worst = 0.0;
  for (const FusedSegment& piece : cut.segments) {
    const FusedSegment& full = whole.segments[piece.case_index];
    for (Eigen::Index k = 0; k < piece.t.size(); ++k) {
      const auto at = static_cast<Eigen::Index>(std::llround(piece.t(k) * kRate));
      ASSERT_LT(at, full.t.size());
      worst = std::max(worst, (piece.a_e.row(k) - full.a_e.row(at)).cwiseAbs().maxCoeff());
      EXPECT_EQ(piece.y(k), full.y(at));
    }
  }
  // The coasting filter takes the encoder's second difference for the lost readings, which is
  // (w T)^2 / 12 = 3e-4 of the sine's 1 g off the truth; three such samples through the 5 Hz
  // low pass leave 3e-8 g. A restarted fusion is off by the vibration's size.
  EXPECT_LT(worst, 1e-7 * kStandardGravity);
  std::int64_t acc1 = 0;
  for (const Exclusion& x : cut.assembler->exclusions())
    if (x.reason == "accel.acc1 invalid") acc1 += x.samples;
  EXPECT_EQ(acc1, 6);
}

// Found by fuzz_event_log: a linear-encoder block whose sample period is 5.4e-23 s put
// the sample index of the next row past the int64 range (an undefined conversion, reported by
// UBSan). Those rows have the encoder missing, as after a lost block; nothing is read for them.
// The bench, a shaker case with its sine phase open, and the table encoder's first block: what
// the two absurd-period tests below share before their own blocks.
void open_sine_phase(StreamAssembler& a) {
  a.push(bench_message(), "bench");
  a.push(mark(plan_event_t::MARK_CASE_START, "shake", "shaker", -1, "", 0, kBlock), "start");
  a.push(mark(plan_event_t::MARK_PHASE_START, "shake", "shaker", 0, "sine", 0, kBlock), "phase");
  a.push(encoder_block("table_encoder", 0, kBlock), "table");
}

TEST(StreamAssembler, ReferenceWithAnAbsurdPeriodIsMissingNotRead) {
  AssemblerOptions o;
  o.sensor = "acc1";
  o.min_segment_s = 0.0;
  std::vector<FusedSegment> segments;
  StreamAssembler a(o, [&segments](FusedSegment&& s) { segments.push_back(std::move(s)); });
  open_sine_phase(a);
  a.push(accel_block(0, kBlock), "accel");
  sample_block_t encoder = encoder_block("linear_encoder", 0, kBlock);
  encoder.sample_period_s = 5.421010862427522e-23;   // the fuzzer's period
  a.push(encoder, "linear");
  a.push(mark(plan_event_t::MARK_CASE_END, "shake", "shaker", -1, "", 0, kBlock - 1), "end");
  a.finish();
  std::int64_t missing = 0;
  for (const Exclusion& x : a.exclusions())
    if (x.reason.find("linear_encoder.position missing") != std::string::npos) missing += x.samples;
  EXPECT_GE(missing, kBlock - 5);   // every row but those at the encoder's only real instant
  EXPECT_LE(a.fused_rows(), 5);
}

TEST(StreamAssembler, AnOutputWithAnAbsurdPeriodKeepsNoSegment) {
  // fuzz_stream_assembler found it: the shortest segment kept, in rows of a 1e-150 s period,
  // overflowed int64 (UB, seed stream_assembler/tiny-sample-period). No segment is that long.
  AssemblerOptions o;
  o.sensor = "acc1";
  o.min_segment_s = 0.5;
  std::vector<FusedSegment> segments;
  StreamAssembler a(o, [&segments](FusedSegment&& s) { segments.push_back(std::move(s)); });
  open_sine_phase(a);
  a.push(encoder_block("linear_encoder", 0, kBlock), "linear");
  sample_block_t accel = accel_block(0, kBlock);
  accel.sample_period_s = 1e-150;
  a.push(accel, "accel");
  a.push(mark(plan_event_t::MARK_CASE_END, "shake", "shaker", -1, "", 0, kBlock - 1), "end");
  EXPECT_NO_THROW(a.finish());
  EXPECT_TRUE(segments.empty());
}

// fuzz_event_log found it: a bench whose monitors all lie in one plane let fusion's
// std::invalid_argument escape the reader and end the process. It is the bench's fault, named
// with the case, like any other bad input.
TEST(StreamAssembler, MonitorsThatDoNotSpanThreeDimensionsAreBadInput) {
  std::string text = kBench;
  for (const auto& [from, to] : {std::pair<std::string, std::string>{"[0.70710678, 0.0, 0.70710678]", "[0.0, 1.0, 0.0]"},
                                 {"[0.70710678, 0.0, -0.70710678]", "[1.0, 0.0, 0.0]"}}) {
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);   // every monitor axis now in the x-y plane
  }
  bench_config_t bench = bench_message();
  bench.texts = {text};
  AssemblerOptions o;
  o.sensor = "acc1";
  o.min_segment_s = 0.0;
  StreamAssembler a(o, [](FusedSegment&&) {});
  try {
    a.push(bench, "bench");
    a.push(mark(plan_event_t::MARK_CASE_START, "shake", "shaker", -1, "", 0, kBlock), "start");
    a.push(mark(plan_event_t::MARK_PHASE_START, "shake", "shaker", 0, "sine", 0, kBlock), "phase");
    a.push(encoder_block("linear_encoder", 0, kBlock), "linear");
    a.push(encoder_block("table_encoder", 0, kBlock), "table");
    a.push(accel_block(0, kBlock), "accel");
    a.push(mark(plan_event_t::MARK_CASE_END, "shake", "shaker", -1, "", 0, kBlock - 1), "end");
    a.finish();
    FAIL() << "coplanar monitors were fused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("case shake (shaker)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("do not span three dimensions"), std::string::npos) << e.what();
  }
}

TEST(StreamAssembler, BadInputIsNamed) {
  AssemblerOptions o;
  auto sink = [](FusedSegment&&) {};
  {
    StreamAssembler a(o, sink);
    try {
      a.push(bench_message(), "log: event 0 at byte 0");
      FAIL() << "two sensors and none chosen";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--sensor"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("event 0 at byte 0"), std::string::npos) << e.what();
    }
  }
  {
    o.sensor = "acc9";
    StreamAssembler a(o, sink);
    try {
      a.push(bench_message(), "here");
      FAIL();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("unknown sensor 'acc9' (the bench's sensors: acc1, acc2)"), std::string::npos)
          << e.what();
    }
  }
  {
    o.sensor = "acc1";
    StreamAssembler a(o, sink);
    EXPECT_THROW(a.finish(), InputError) << "no bench";
    a.push(accel_block(0, kBlock), "block before the bench");
    EXPECT_EQ(a.skipped_blocks(), 1);
    a.push(bench_message(), "bench");
    a.push(accel_block(0, kBlock), "block");
    try {
      a.finish();
      FAIL() << "no case markers";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no case markers"), std::string::npos) << e.what();
    }
    bench_config_t other = bench_message();
    other.texts[0] += "\n# edited\n";
    EXPECT_THROW(a.push(other, "second bench"), InputError);
    EXPECT_THROW(a.push(mark(plan_event_t::MARK_CASE_START, "nosuch", "static", -1, "", 0, 1), "ev"), InputError);
  }
}

}  // namespace
}  // namespace inertia::fusion
