// SegmentCollector (segment_collector.hpp): the chunks of each segment joined, the kept segments
// handed over whole.
#include "analyzer/fusion/segment_collector.hpp"

namespace inertia::fusion {

void SegmentCollector::on_rows(FusedChunk&& chunk) {
  open_[{chunk.case_index, chunk.segment}].push_back(std::move(chunk));
}

void SegmentCollector::on_segment_end(const SegmentEnd& end) {
  const auto it = open_.find({end.case_index, end.segment});
  if (it == open_.end()) return;
  std::vector<FusedChunk> chunks = std::move(it->second);
  open_.erase(it);
  if (!end.kept || chunks.empty()) return;
  Eigen::Index n = 0;
  for (const FusedChunk& c : chunks) n += c.rows();
  const FusedChunk& first = chunks.front();
  FusedSegment s;
  s.case_index = first.case_index;
  s.case_name = first.case_name;
  s.kind = first.kind;
  s.segment = kept_[first.case_index]++;
  s.sample_period_s = first.sample_period_s;
  s.t.resize(n);
  s.a_e.resize(n, 3);
  Rows3 w(n, 3);
  s.y.resize(n);
  if (first.temp) s.temp = Eigen::VectorXd(n);
  Eigen::Index at = 0;
  for (const FusedChunk& c : chunks) {
    const Eigen::Index m = c.rows();
    s.t.segment(at, m) = c.t;
    s.a_e.middleRows(at, m) = c.a_e;
    w.middleRows(at, m) = c.w_e;
    s.y.segment(at, m) = c.y;
    if (s.temp) s.temp->segment(at, m) = *c.temp;
    s.phase.insert(s.phase.end(), c.phase.begin(), c.phase.end());
    at += m;
  }
  s.w_e = std::move(w);
  s.phase_names = chunks.back().phase_names;
  sink_(std::move(s));
}

}  // namespace inertia::fusion
