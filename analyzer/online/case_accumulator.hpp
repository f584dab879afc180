#pragma once
// The online estimator's statistics (online_estimator.hpp): the fused rows of each test case,
// through the noise model's filter, summed into the regression's sufficient statistics
// (information.hpp), one run per plan phase and cluster; the cases grouped into mountings as the
// batch groups them; the segment still open kept apart until it ends, and dropped if it ends too
// short. Also what the estimate and its convergence test ask of them: which cases have rows in the
// estimate, a case's statistics with a case or some of its phases left out.
#include <Eigen/Dense>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/fusion/fused_rows.hpp"
#include "analyzer/online/information.hpp"
#include "analyzer/online/live_model.hpp"
#include "analyzer/online/live_noise_model.hpp"
#include "analyzer/online/live_solver.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "analyzer/procedure/plan_validation.hpp"
#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::online {

/// What the convergence test leaves out: a case, or runs [first, last) of it (its phases).
struct LeftOut {
  std::size_t case_index = 0;
  std::optional<std::pair<std::size_t, std::size_t>> runs;   // into runs_of(case_index)
  [[nodiscard]] bool leaves(std::size_t r) const { return runs && r >= runs->first && r < runs->second; }
};

class CaseAccumulator {
 public:
  CaseAccumulator(const LiveModel& live, LiveNoiseModel& noise) : live(live), noise(noise) {}

  struct CaseState {
    std::size_t plan_case = 0;
    std::string name;
    std::size_t mounting = 0;
    RunStatistics stats;
    std::vector<std::string> phase_names;   // the stream's, for the run labels
    std::int64_t rows = 0;
    double placement_sd_rad = 0.0;           // the plan's stated placement accuracy of the case
  };
  struct MountingState {
    std::string name;
    std::vector<std::size_t> cases;
    procedure::MountingKind kind;
    bool poses_only = true;   // static and thermal cases only: its tilts are read from the poses' levels
    frames::Dcm m_cs = frames::Dcm::Identity();
    MountingFit fit;
  };
  struct OpenSegment {
    std::size_t state = 0;
    std::size_t plan_case = 0;
    int segment = 0;
    double period = 0.0;
    std::unique_ptr<SegmentPipeline> pipeline;
    RunStatistics stats;
    dataset::CaseData history;   // the last max_lag rows (case frame), for lagged columns
    std::int64_t rows = 0;       // rows into the statistics
    std::int64_t raw_rows = 0;   // rows received
  };

  const LiveModel& live;
  LiveNoiseModel& noise;
  std::vector<CaseState> cases;
  std::vector<MountingState> mountings;
  std::optional<OpenSegment> open;
  // The fixture temperature's range over the rows pushed (temperature_moved()).
  double temp_lo = std::numeric_limits<double>::infinity(), temp_hi = -std::numeric_limits<double>::infinity();
  std::int64_t rows_total = 0;
  double nominal_period = 0.0;
  /// Per basis term the model fits, whether the plan's own inputs excite it so far: the batch's
  /// rule (procedure::TermExcitation), tallied over every row pushed.
  std::vector<procedure::TermExcitation> excitation;
  /// A segment ended since the convergence test last ran: the data changed by a whole segment.
  bool segment_closed = false;

  /// The noise pipeline of a new segment (the noise model's filter, the squares' high passes).
  [[nodiscard]] std::unique_ptr<SegmentPipeline> pipeline(double period) const;

  /// The longest stretch of a phase that is one cluster of the case scatter. Slow noise (1/f,
  /// drift) moves a minute's rows together; cut into minutes, a thermal step's offsets carry it
  /// into the sd of what varies within the step (its T terms), which the whole step's offset
  /// cannot. Shorter than every phase of the shipped benches but the thermal ones.
  static constexpr double kClusterS = 60.0;

  /// Rows of one segment through its noise pipeline into `stats`, a new run where the plan's phase
  /// changes, a new cluster after every kClusterS of it.
  void add_rows(SegmentPipeline& pipeline, RunStatistics& stats, double period, const Eigen::MatrixXd& x,
                const Eigen::VectorXd& y, const Eigen::MatrixX3d& inputs, const std::vector<std::uint16_t>& phase,
                const std::vector<std::int32_t>& plan_phase) const;

  /// Rows of one segment of test case `tc`. False when none of them entered the statistics (all
  /// still the lagged columns' history).
  bool push(const fusion::FusedChunk& chunk, const config::TestCase& tc);
  void end_segment(const fusion::SegmentEnd& end);

  /// Whether the open segment is long enough to count.
  [[nodiscard]] bool open_counts() const;
  /// Whether case c has rows in the estimate (kept ones, or an open segment long enough to count).
  [[nodiscard]] bool has_data(std::size_t c) const;
  /// Case c's runs, the open segment's included while it counts.
  [[nodiscard]] std::vector<const RunStatistics::Run*> runs_of(std::size_t c) const;
  /// Case c's statistics as the estimate reads them, `left_out`'s run taken out when it is c's
  /// (nullopt: the case is left out, or has no rows in the estimate).
  [[nodiscard]] std::optional<Information> case_information(std::size_t c, const std::optional<LeftOut>& left_out) const;
  /// Whether every case of the plan has rows in the estimate.
  [[nodiscard]] bool every_plan_case_in() const;
  /// ... and none is still running (its next phase may determine more): what is not determined
  /// then, the plan does not determine.
  [[nodiscard]] bool whole_plan_in() const { return every_plan_case_in() && !open; }
  /// Whether the fixture temperature has moved enough for its terms (the batch's rule).
  [[nodiscard]] bool temperature_moved() const;
  /// Whether the rows so far excite basis term `term` in the plan's own frames (the batch's rule,
  /// procedure::judged_by_excitation; a term it does not judge is excited).
  [[nodiscard]] bool excited(Eigen::Index term) const;
  [[nodiscard]] std::size_t cases_with_data() const;

 private:
  /// The mounting case `tc` belongs to: the batch's grouping of the plan (or of `tc` alone).
  [[nodiscard]] std::string mounting_label(const config::TestCase& tc) const;
  std::size_t state_of(std::size_t plan_case, const config::TestCase& tc);
  void forget(Eigen::Index rows);
  void close_open(bool kept);
};

}  // namespace inertia::online
