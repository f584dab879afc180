#pragma once
// Whole fused segments from the stream assembler's chunks: SegmentCollector is a FusionSink that
// joins the chunks of each segment and hands over the kept segments whole, for consumers that read
// a case's rows at once (log_dataset.hpp: an event log read into a dataset) rather than as they come.
#include <Eigen/Dense>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/fusion/fused_rows.hpp"
#include "common/case_kind.hpp"

namespace inertia::fusion {

/// Contiguous fused rows of one case, whole (what SegmentCollector assembles from the chunks).
struct FusedSegment {
  std::size_t case_index = 0;
  std::string case_name;
  CaseKind kind = CaseKind::Static;
  int segment = 0;                     // 0, 1, ... among the kept segments of the case
  double sample_period_s = 0.0;
  Eigen::VectorXd t;
  Rows3 a_e;
  std::optional<Rows3> w_e;
  std::optional<Eigen::VectorXd> temp;
  Eigen::VectorXd y;
  std::vector<std::string> phase_names;
  std::vector<std::uint16_t> phase;
};

/// Concatenates the chunks of each segment and hands over the kept segments whole.
class SegmentCollector final : public FusionSink {
 public:
  using SegmentSink = std::function<void(FusedSegment&&)>;
  explicit SegmentCollector(SegmentSink sink) : sink_(std::move(sink)) {}
  void on_rows(FusedChunk&& chunk) override;
  void on_segment_end(const SegmentEnd& end) override;

 private:
  SegmentSink sink_;
  std::map<std::pair<std::size_t, int>, std::vector<FusedChunk>> open_;
  std::map<std::size_t, int> kept_;    // kept segments per case so far
};

}  // namespace inertia::fusion
