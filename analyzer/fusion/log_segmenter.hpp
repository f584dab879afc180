#pragma once
// A log without plan markers (a real bench whose phases nobody marked): the cases and phases of
// the bench's plan cut from the references instead, so that characterize and diagnose
// still run, and say where they cut.
//
// Motion is classed per window of the references (kSegmentWindowS, shorter for short phases): rotation while the table encoder turns faster
// than kRotationRate; vibration while a monitor's detrended sd stands above its noise floor (10x
// the 10th percentile of the log's windows, at least kVibrationFloor); static otherwise. Runs of
// one class shorter than two windows join their neighbour. The plan's phases are classed alike
// (dwell and thermal_step static, rotation, sine and random vibration) and must match the
// detected runs one to one after neighbours of one class merge; a boundary between phases of
// different classes is the detected change; one between phases of the same class (a dwell before
// a thermal step, a case's first dwell after a remount) is placed by the plan's duration, counted
// from the nearest detected change of the same case. Time no phase claims (a remount between
// cases) is left out. Windows lie on a grid fixed in CLOCK_MONOTONIC, so the runs do not depend
// on the order the log holds its devices' blocks in. A window only says which window a change
// falls in; a second pass (VibrationEdgeRefiner) places each change between rest and vibration
// to the sample, as rotation's are, because a row given the wrong case carries the other
// mounting's gravity into the misalignment estimate. Not real-time: runs twice over a log.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::fusion {

// The longest window; a plan with short phases gets windows of a quarter of its shortest phase
// (so that a phase spans at least two), but never fewer than kMinWindowSamples samples.
inline constexpr double kSegmentWindowS = 0.5;
inline constexpr double kMinWindowSamples = 20.0;
inline constexpr double kRotationRate = 0.1 * 3.14159265358979323846 / 180.0;   // rad/s
inline constexpr double kVibrationFloor = 0.01;                                    // m/s^2, ~1 mg
// A table encoder dithering by a count at rest is not turning: a move is more than this many.
inline constexpr double kMoveCounts = 2.5;

enum class MotionClass { Static, Rotation, Vibration };
const char* to_string(MotionClass c);

struct MotionRun {
  MotionClass motion = MotionClass::Static;
  double start_ns = 0.0;   // CLOCK_MONOTONIC of its first window's start
  double end_ns = 0.0;     // of its last window's end
};

/// Sums of (t, y) pairs (t in s from a chosen origin) whose line fit's residuals give a detrended
/// sd: additive, so a stretch's is the difference of two running sums.
struct LineSums {
  double n = 0, t = 0, tt = 0, y = 0, ty = 0, yy = 0;
  void add(double t_s, double value);
  [[nodiscard]] LineSums operator-(const LineSums& earlier) const;
  /// The residual sum of squares of the least-squares line y = a + b t.
  [[nodiscard]] double residual_ss() const;
  [[nodiscard]] double detrended_sd() const;
};

/// Collects the references' motion per window from sample blocks, in any order.
class MotionClassifier {
 public:
  explicit MotionClassifier(const config::BenchConfig& bench);
  [[nodiscard]] double window_s() const noexcept { return window_ns_ * 1e-9; }
  void push(const sample_block_t& block);
  /// The runs of one class, in time order (empty without any reference sample).
  [[nodiscard]] std::vector<MotionRun> runs() const;
  /// The vibration threshold used (m/s^2): 10x the monitors' floor, at least kVibrationFloor.
  [[nodiscard]] double vibration_threshold() const;
  [[nodiscard]] bool has_table_encoder() const noexcept { return !table_device_.empty(); }
  /// Which monitor (index into the bench's monitors) a block's channel is, if any.
  [[nodiscard]] std::optional<std::size_t> monitor_of(const std::string& device, const std::string& signal) const;
  [[nodiscard]] std::size_t monitor_count() const noexcept { return monitor_refs_.size(); }
  [[nodiscard]] double window_ns() const noexcept { return window_ns_; }

 private:
  struct Window {
    bool turned_known = false;
    double first_t = 0, first_angle = 0, last_t = 0, last_angle = 0;
    // When the table began and stopped turning within the window (ns; NaN: it did not): the
    // sample before the first one kMoveCounts encoder counts away from the window's first angle,
    // and the last that moved that far from the one before it, so that a rotation's ends are
    // found to the sample.
    double move_first_ns, move_last_ns;
    std::vector<LineSums> monitors;
    Window();
  };
  struct MoveAnchor {   // the last angle the table was seen to move to, and when
    bool known = false;
    double angle = 0.0;
  };
  double window_ns_;
  std::string table_device_, table_signal_;
  double move_threshold_ = 0.0;     // rad: kMoveCounts counts of the table encoder
  MoveAnchor anchor_;
  std::vector<std::pair<std::string, std::string>> monitor_refs_;
  std::map<std::int64_t, Window> windows_;
};

/// The second pass: each change between a static and a vibration run moved to the samples where
/// the monitors' variance changes: the splits of the two windows around it whose likelihood (two
/// segments, each a line plus white noise, summed over the monitors) is within a likelihood ratio
/// of the best. The earlier run ends at the first of them and the later starts at the last, so
/// that the few samples where the change cannot be told belong to neither (and to no case when
/// the change ends one: a row with the wrong mounting biases the misalignment).
class VibrationEdgeRefiner {
 public:
  VibrationEdgeRefiner(const MotionClassifier& motion, std::vector<MotionRun> runs);
  void push(const sample_block_t& block);
  /// The runs with their vibration edges refined (an edge keeps its window estimate when fewer
  /// than three samples of each monitor lie on either side of it).
  [[nodiscard]] std::vector<MotionRun> runs() const;

 private:
  struct Edge {
    std::size_t run;                 // the edge is runs_[run].end_ns == runs_[run + 1].start_ns
    double from_ns, to_ns;           // where the change can lie: a window either side
    std::vector<std::vector<std::pair<double, double>>> samples;   // per monitor: (t ns, value)
  };
  const MotionClassifier& motion_;
  std::vector<MotionRun> runs_;
  std::vector<Edge> edges_;
};

/// The markers (MARK_CASE_START, MARK_PHASE_START per phase, MARK_CASE_END) that cut `runs` into
/// the plan's cases and phases, in time order, and one line per case saying where and how each
/// boundary was placed (times in s from `origin_ns`). InputError when the runs cannot be matched
/// to the plan (with both sequences), or the plan has a shock phase (a pulse in a quiet phase,
/// which the classes cannot bound).
struct Segmentation {
  std::vector<plan_event_t> markers;
  std::vector<std::string> description;
};
Segmentation segment_plan(const config::BenchConfig& bench, const std::vector<MotionRun>& runs, double origin_ns);

}  // namespace inertia::fusion
