#pragma once
// What the stream assembler (stream_assembler.hpp) hands out as rows become final: fused rows in
// chunks of one segment of one case, the end of each segment (kept, or dropped as too short), and
// the sink interface that receives both. A live consumer (the online estimator) reads the chunks
// as they come; SegmentCollector (segment_collector.hpp) joins them into whole segments.
#include <Eigen/Dense>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/case_kind.hpp"

namespace inertia::fusion {

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// Consecutive final rows of one segment of one case (the next chunk of the same segment continues
/// it without a gap).
struct FusedChunk {
  std::size_t case_index = 0;          // into bench().cases
  std::string case_name;
  CaseKind kind = CaseKind::Static;
  int segment = 0;                     // 0, 1, ... in order of start within the case
  double sample_period_s = 0.0;        // of the sensor output's clock
  std::int64_t first_row = 0;          // position of the chunk's first row in its segment
  Eigen::VectorXd t;                   // s since the case's first sample
  Rows3 a_e;                           // fused specific force at the sensor, F_E, m/s^2
  Rows3 w_e;                           // rate of F_E, rad/s (table: encoder; others: at rest)
  std::optional<Eigen::VectorXd> temp; // fixture temperature, degC (held from the controller)
  Eigen::VectorXd y;                   // sensor output, output unit
  std::vector<std::string> phase_names;   // the case's phase labels so far
  std::vector<std::uint16_t> phase;       // per row: its label, into phase_names
  std::vector<std::int32_t> plan_phase;   // per row: the plan's phase index (-1 before the first marker)
  std::int64_t newest_mono_ns = 0;     // CLOCK_MONOTONIC of the chunk's last row
  [[nodiscard]] Eigen::Index rows() const { return y.size(); }
};

/// A segment ended: `kept` false when it was shorter than min_segment_s (its rows do not count).
struct SegmentEnd {
  std::size_t case_index = 0;
  std::string case_name;
  int segment = 0;
  std::int64_t rows = 0;
  bool kept = true;
};

/// Where fused rows go.
class FusionSink {
 public:
  virtual ~FusionSink() = default;
  virtual void on_rows(FusedChunk&& chunk) = 0;
  virtual void on_segment_end(const SegmentEnd& end) = 0;
};

}  // namespace inertia::fusion
