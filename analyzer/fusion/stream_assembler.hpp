#pragma once
// From the daemon's messages to fused ground truth for one sensor under test (design.md: "The
// event log written by the daemon and lcm-logger carries the same information [as the dataset
// folder]"). StreamAssembler is pushed bench_config_t, sample_block_t and plan_event_t in the
// order they were recorded (an event log, or live LCM for `online`):
//  - the bench (INERTIA_BENCH) says which device channel is which instrument: the sensor's output,
//    the monitors, the encoders, the fixture temperature ("<device>.<signal>" in the bench file;
//    on a simulated bench the simulator's own devices, daq/sim_bench.hpp);
//  - every device's samples go on one timeline, sample k of a block at t0_mono_ns + k * period,
//    index = round((t - origin) / period), so devices line up sample by sample; a jump of the
//    index or of channel_seq is a gap (counted and located), never filled;
//  - case markers (INERTIA_EVENT) cut the timeline into cases, phase markers label the samples;
//  - a case is fused when every device has passed its end (or at finish()): per case kind,
//    shaker -> monitor WLS with the linear encoder along the vibration axis (complementary
//    filter), rotation table -> table-encoder kinematics at the sensor's position, static and
//    thermal -> monitor WLS (reference_fusion.hpp);
//  - rows where any needed sample is invalid (validity bit clear) or missing split the case into
//    contiguous segments; segments shorter than min_segment_s are dropped. Every excluded sample
//    is accounted for in exclusions().
// Memory: samples are kept from the oldest case not yet fused; a fused case's samples are
// released, so a live stream holds about one case (the complementary filter and the table's
// attitude tracking need a whole segment, so fusion runs per case, not per block).
// Not real-time; one thread.
#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/case_kind.hpp"
#include "common/config/bench_config.hpp"
#include "inertia/bench_config_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::fusion {

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// Contiguous fused rows of one case: every needed sample valid and present.
struct FusedSegment {
  std::size_t case_index = 0;          // into bench().cases
  std::string case_name;
  CaseKind kind = CaseKind::Static;
  int segment = 0;                     // 0, 1, ... within the case
  double sample_period_s = 0.0;
  Eigen::VectorXd t;                   // s since the case's first sample
  Rows3 a_e;                           // fused specific force at the sensor, F_E, m/s^2
  std::optional<Rows3> w_e;            // rate of F_E, rad/s (table: encoder; others: at rest)
  std::optional<Eigen::VectorXd> temp; // fixture temperature, degC (held from the controller)
  Eigen::VectorXd y;                   // sensor output, output unit
  std::vector<std::string> phase_names;
  std::vector<std::uint16_t> phase;
};

/// Samples of a case left out of the fused rows, one entry per contiguous run and reason.
struct Exclusion {
  std::string case_name;
  std::string reason;                  // e.g. "accel.mon2 invalid", "linear_encoder missing (gap)", "segment < 0.5 s"
  double t_s = 0.0;                    // case time of the run's first sample
  std::int64_t samples = 0;
};

/// A jump in one device's stream (lost blocks or a device that went silent).
struct StreamGap {
  std::string device;
  std::string where;                   // log position of the block after the gap
  std::int64_t missing_samples = 0;    // by the timeline
  std::int64_t missing_seq = 0;        // by channel_seq (0: the device sampled nothing, e.g. bus-off)
};

struct AssemblerOptions {
  std::string sensor;                  // sensor under test; empty: the bench's only one
  double min_segment_s = 0.5;          // shorter valid stretches are dropped (counted)
  double crossover_hz = 5.0;           // shaker: encoder below, monitors above
};

class StreamAssembler {
 public:
  using SegmentSink = std::function<void(FusedSegment&&)>;

  StreamAssembler(AssemblerOptions options, SegmentSink sink);
  ~StreamAssembler();
  StreamAssembler(const StreamAssembler&) = delete;
  StreamAssembler& operator=(const StreamAssembler&) = delete;

  // `where` names the message's position for errors ("FILE: event 12 at byte 3456").
  /// The first bench fixes the configuration; a repeat must be identical (InputError otherwise).
  void push(const bench_config_t& bench, const std::string& where);
  /// Blocks of devices the sensor's fusion does not use are ignored; blocks before the bench
  /// are counted (skipped_blocks()).
  void push(const sample_block_t& block, const std::string& where);
  void push(const plan_event_t& event, const std::string& where);
  /// Fuses what is left (an open case ends at its last sample). InputError when no bench or no
  /// case marker was seen.
  void finish();

  [[nodiscard]] bool has_bench() const noexcept;
  /// Throws std::logic_error before the first bench.
  [[nodiscard]] const config::BenchConfig& bench() const;
  [[nodiscard]] std::size_t sensor_index() const;
  [[nodiscard]] const std::vector<Exclusion>& exclusions() const noexcept;
  [[nodiscard]] const std::vector<StreamGap>& gaps() const noexcept;
  [[nodiscard]] std::int64_t skipped_blocks() const noexcept;
  [[nodiscard]] std::int64_t fused_rows() const noexcept;
  /// Notes for the user (an open case cut at its last sample, an aborted case, ...).
  [[nodiscard]] const std::vector<std::string>& notes() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inertia::fusion
