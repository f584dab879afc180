#pragma once
// Building the fused segments of the case being fused (stream_assembler.hpp). Each row of the
// sensor output gets the case's inputs read from the device buffers (the monitors, the encoder,
// the fixture temperature), its phase label and, on a rotation table, the table's attitude; once
// the encoder's differences it needs are final, the fusion per case kind makes its reference
// (monitor WLS, the shaker's complementary filter on the linear encoder, the table's kinematics).
// The rows go to the sink in chunks of contiguous segments: a lost encoder sample ends a segment,
// a lost output or monitor sample (the fusion's state goes on through it) cuts the output into
// pieces, and a piece shorter than min_segment_s is dropped. Every excluded sample is counted.
#include <Eigen/Dense>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/fusion/device_buffers.hpp"
#include "analyzer/fusion/plan_marks.hpp"
#include "analyzer/fusion/reference_fusion.hpp"
#include "analyzer/fusion/stream_assembler.hpp"
#include "common/config/bench_config.hpp"
#include "common/frames.hpp"

namespace inertia::fusion {

// A row read from the devices, waiting for the differences it needs.
struct RawRow {
  double t_ns = 0.0;
  double t_case_s = 0.0;
  double y = 0.0;
  Eigen::Vector3d monitors_a = Eigen::Vector3d::Zero();   // monitor WLS (non-table cases)
  double encoder = 0.0;                                   // displacement or table angle
  std::int32_t phase_index = -1;
  std::uint16_t phase_label = 0;
  double temp = 0.0;
  // A hole: the sensor's output or a monitor is lost here while the encoder is not, so the
  // fusion's state (differences, the shaker's filter, the table's attitude) goes on through the
  // row; the row itself is excluded and ends the piece of the segment before it.
  bool hole = false;
};

// Exclusions per reason, as runs of consecutive rows.
struct ExclusionRun {
  double t_case_s = 0.0;
  std::int64_t samples = 0;
};

class SegmentBuilder {
 public:
  /// Keeps references to all four: they outlive the builder (StreamAssembler's members).
  SegmentBuilder(const AssemblerOptions& options, FusionSink& sink, const DeviceBuffers& buffers,
                 std::vector<std::string>& notes)
      : options_(options), sink_(sink), buffers_(buffers), notes_(notes) {}

  /// The bench whose cases are fused (kept by reference), and the index of its sensor under test.
  void use_bench(const config::BenchConfig& bench, std::size_t sensor) {
    bench_ = &bench;
    sensor_ = sensor;
  }

  /// The marks of the case being fused; nullptr when none is.
  [[nodiscard]] const CaseMarks* case_marks() const { return fuser_ ? fuser_->marks : nullptr; }
  /// Starts fusing case c (the case fused before it ends). InputError when the bench cannot fuse it.
  void open_case(const CaseMarks& c);
  /// Output sample s of block ob, at time t in the case being fused (c). False when it must wait
  /// for more messages.
  bool add_row(const StoredBlock& ob, std::int32_t s, const CaseMarks& c, double t, double half);
  /// An output gap between two blocks ends the open segment (the rows are not there).
  void note_output_gap(const StoredBlock& a, const StoredBlock& b);
  /// Hands the rows fused so far to the sink.
  void flush_chunk();
  /// The case being fused is over: its open segment ends, its exclusions are counted.
  void end_case();

  [[nodiscard]] const std::vector<Exclusion>& exclusions() const noexcept { return exclusions_; }
  [[nodiscard]] std::int64_t rows_kept() const noexcept { return rows_kept_; }
  [[nodiscard]] std::int64_t rows_out() const noexcept { return rows_out_; }

 private:
  // A segment is a stretch of continuous fusion; holes cut its output into pieces, each handed to
  // the sink as a segment of its own (number), so the sink's segments stay contiguous.
  struct Segment {
    int number = 0;
    std::int64_t piece_rows = 0;       // rows appended to the current piece
    double piece_first_t_case = 0.0;
    bool next_piece = false;           // a hole ended a piece: the next row starts another
    bool has_temp = false;
    CentralDifferences differences{1.0};
    std::int32_t differenced_phase = -1;   // the plan phase of the newest row differenced
    std::optional<ComplementaryFilter> filter;
    std::deque<RawRow> pending;
    FusedChunk out;
  };
  struct Fuser {
    const CaseMarks* marks = nullptr;   // points into PlanMarks::cases (front)
    std::size_t case_index = 0;
    std::string name;
    CaseKind kind = CaseKind::Static;
    std::vector<std::size_t> used;
    std::vector<std::size_t> monitor_needs;
    std::optional<std::size_t> encoder_need;   // table or linear encoder
    std::optional<MonitorFusion> monitors;
    // A static or thermal case on a bench without three monitors: the specific force is gravity in
    // the plan's pose, which a static pose is by definition (a placement error is the fixture's,
    // for the analyzer's honest inference to carry, as on a tumble with a known pose and no monitor).
    std::optional<Eigen::Vector3d> pose_specific_force;
    bool needs_temperature = false;   // a thermal case, or one with a thermal_step phase
    Eigen::VectorXd readings, monitor_bias, monitor_gain;   // calibration from the bench file
    std::vector<std::string> phase_names;
    std::map<std::int32_t, std::uint16_t> phase_labels;   // phase index (-1 unplanned) -> label
    // Table attitude, carried from phase to phase through the encoder.
    std::map<std::int32_t, frames::Dcm> attitude;
    std::map<std::int32_t, double> base;
    std::int32_t phases_seen = -1;            // highest phase index with a row
    bool attitude_pending = false;            // that phase's attitude not fixed yet
    std::optional<ComplementaryFilter> filter_before_break;   // the shaker filter of the last segment
    std::int32_t attitude_lost_from = std::numeric_limits<std::int32_t>::max();
    Eigen::Vector3d prev_axis = Eigen::Vector3d::UnitZ();
    std::optional<double> prev_base;
    frames::Dcm running_attitude = frames::Dcm::Identity();
    std::optional<Segment> segment;
    int segments_started = 0;
    std::int64_t rows = 0;
    std::map<std::string, ExclusionRun> runs;
  };

  void start_segment(bool with_temp);
  /// Turns the raw rows whose differences are final into fused rows.
  void finalize_ready(bool ending);
  void append(Segment& s, const RawRow& row, const Eigen::Vector3d& a, const Eigen::Vector3d& w);
  /// The piece of output rows before a hole, or at the segment's end, ends: kept or dropped.
  void end_piece();
  void end_segment();
  void label_phase(Fuser& f, const CaseMarks& c, double t, double half, RawRow& row);
  /// The table's attitude at the row's phase (tracked through the encoder from the case's start
  /// attitude): false when it is unknown (a rotation whose first row had no angle, or any phase
  /// after it). A phase at rest (not a rotation) may fix it at its first usable row instead: the
  /// table has not turned since the phase began, so any of its angles is the phase's start angle
  /// (on a real time base a device's first sample can come a fraction of a period after another's).
  bool table_attitude(Fuser& f, const RawRow& row, bool usable);
  void count_exclusions(Fuser& f, const std::vector<std::string>& reasons, double t_case);

  const AssemblerOptions& options_;
  FusionSink& sink_;
  const DeviceBuffers& buffers_;
  std::vector<std::string>& notes_;
  const config::BenchConfig* bench_ = nullptr;
  std::size_t sensor_ = 0;
  std::optional<Fuser> fuser_;
  std::vector<Exclusion> exclusions_;
  std::int64_t rows_kept_ = 0;
  std::int64_t rows_out_ = 0;
};

}  // namespace inertia::fusion
