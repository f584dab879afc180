#pragma once
// From the daemon's messages to fused ground truth for one sensor under test (docs/design.md: "The
// event log written by the daemon and lcm-logger carries the same information [as the dataset
// folder]"). StreamAssembler is pushed bench_config_t, sample_block_t and plan_event_t in the
// order they arrive (an event log, or live LCM for `online`) and hands out fused rows as soon as
// they are final, a few samples behind the stream:
//  - the bench (INERTIA_BENCH) says which device channel is which instrument: the sensor's output,
//    the monitors, the encoders, the fixture temperature ("<device>.<signal>" in the bench file;
//    on a simulated bench the simulator's own devices, daq/sim_bench.hpp);
//  - the rows are the sensor output's own samples (its device's sample clock: sample k of a block
//    at t0_mono_ns + k * sample_period_s); every reference is read at a row's time, sample for
//    sample where its device shares the sample instants, interpolated (4-point Lagrange) where
//    its clock differs. A jump of a device's channel_seq or time is a gap (counted, located),
//    never filled;
//  - case markers (INERTIA_EVENT) cut the rows into cases, phase markers label them. A case
//    start ends whatever case is still open, so one lost end marker costs nothing further;
//  - per case kind: shaker -> monitor WLS with the linear encoder along the vibration axis
//    (complementary filter), rotation table -> table-encoder kinematics at the sensor's position,
//    static and thermal -> monitor WLS (reference_fusion.hpp), all in their streaming forms;
//  - rows where any needed sample is invalid (validity bit clear) or missing are excluded, never
//    filled. Where only the sensor's output or monitors are lost (a lost frame of their device),
//    the fusion's state goes on through the row (the encoder's differences, the table's attitude,
//    the shaker filter coasting on its encoder) and only the output is cut there; a lost encoder
//    sample breaks the fusion. Either way the sink receives contiguous segments; a segment
//    shorter than min_segment_s is dropped when it ends (the sink hears so and discards what it
//    was given). Every excluded sample is in exclusions().
// Delay: a row is final once every device it reads has passed its time, the plan markers have
// passed it (or its phase's planned end lies beyond it), and the differences it needs have their
// next sample: one sample on the table and the shaker, four at a segment's start. A device or a
// marker that stays behind the sensor output by more than max_wait_s (live) is given up on for
// those rows (missing, or labelled with what is known), so a silent device never stalls the rest.
// The same code serves the event log (offline) and the live stream: the same messages give the
// same rows, except where the live stream gave up waiting.
// Memory: samples are kept from the oldest row not yet final; one thread, not real-time.
#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/fusion/fused_rows.hpp"
#include "analyzer/fusion/segment_collector.hpp"
#include "common/case_kind.hpp"
#include "common/config/bench_config.hpp"
#include "inertia/bench_config_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::fusion {

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
  std::int64_t missing_samples = 0;    // by the device's sample times
  std::int64_t missing_seq = 0;        // by channel_seq (0: the device sampled nothing, e.g. bus-off)
};

/// One line for a report: which device, how many samples by time and by number, where.
[[nodiscard]] std::string describe(const StreamGap& gap);

struct AssemblerOptions {
  std::string sensor;                  // sensor under test; empty: the bench's only one
  /// Shorter valid stretches are dropped (counted). A stretch is a piece of its case when lost
  /// samples cut it (log_dataset: CaseData::piece_of): at 0.1 s it still keeps most of its rows
  /// after the prewhitening's warm-up (AR orders of tens of samples at 1 kHz), and at 0.1 % lost
  /// frames it drops about 1 % of the rows, where a longer minimum drops many more
  /// (docs/validation.md, 'Evidence behind choices in the code').
  double min_segment_s = 0.1;
  double crossover_hz = 5.0;           // shaker: encoder below, monitors above
  /// How far (stream time) a device or the plan markers may stay behind the sensor output before
  /// its rows are fused without it (missing samples; phase as known): the live bound on the
  /// fusion's wait for a late or silent device (`online` sets 0.5 s). A log holds every message,
  /// so reading one waits for all of them (the default): its answer must not depend on how the
  /// devices' messages happened to interleave.
  double max_wait_s = std::numeric_limits<double>::infinity();
};

class StreamAssembler {
 public:
  using SegmentSink = SegmentCollector::SegmentSink;

  StreamAssembler(AssemblerOptions options, FusionSink& sink);
  /// Whole segments (through a SegmentCollector of its own).
  StreamAssembler(AssemblerOptions options, SegmentSink sink);
  ~StreamAssembler();
  StreamAssembler(const StreamAssembler&) = delete;
  StreamAssembler& operator=(const StreamAssembler&) = delete;

  // `where` names the message's position for errors ("FILE: event 12 at byte 3456"). A message
  // that is refused (InputError) leaves the assembler as it was: the caller may skip it and go on.
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
  /// Rows of kept segments.
  [[nodiscard]] std::int64_t fused_rows() const noexcept;
  /// Rows handed to the sink so far (kept or not yet judged).
  [[nodiscard]] std::int64_t rows_out() const noexcept;
  /// Notes for the user (an open case cut at its last sample, an aborted case, ...).
  [[nodiscard]] const std::vector<std::string>& notes() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<SegmentCollector> own_collector_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inertia::fusion
