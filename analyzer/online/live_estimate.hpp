#pragma once
// The online estimator's estimate from its statistics (online_estimator.hpp): blocks 5-6 per
// mounting (algorithm 1 to its fixed point, in the batch's mounting order, the bias handed on as
// the batch hands it), the batch model over all mountings with their M_C^S, the twists between
// mountings, the terms at the level of the phases' means left out while nothing tells them from
// the phases' offsets, and the case scatter in the covariance. The convergence test solves again
// with a case or some phases left out and the mountings' M_C^S held.
#include <Eigen/Dense>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "analyzer/online/case_accumulator.hpp"
#include "analyzer/online/information.hpp"
#include "analyzer/online/live_model.hpp"
#include "analyzer/online/live_noise_model.hpp"
#include "analyzer/online/live_solver.hpp"

namespace inertia::online {

/// One solve of the estimate: per mounting the statistics and the M_C^S it used, and the batch fit
/// over all mountings.
struct LiveEstimate {
  std::vector<std::size_t> order;          // mountings in fit order
  std::vector<Information> infos;          // per mounting
  std::vector<Eigen::Matrix3d> m_cs;       // per mounting, as the batch used it
  std::vector<Eigen::Matrix3d> angle_covariances;
  std::vector<std::array<bool, 3>> held_angles;   // per mounting (MountingFit::held, a held twist)
  StatFit batch;
  CaseScatter scatter;
  bool aligned = true;                     // some mounting aligned (else the frame-free terms only)
  std::vector<Eigen::Index> model;         // the terms the batch fitted (the solver's model)
  std::vector<Eigen::Index> confounded;    // left out: at the phases' level, with no phase to spare
  std::vector<Eigen::Index> insignificant; // left out of a searched model: by algorithm 2, or its test failed (ident::term_leaving)
  int angles_from_means = 0;               // mounting angles read from the poses' means (case scatter's dof)
};

class EstimateSolver {
 public:
  EstimateSolver(const LiveModel& live, CaseAccumulator& statistics, const LiveNoiseModel& noise)
      : live(live), statistics(statistics), noise(noise) {}

  const LiveModel& live;
  CaseAccumulator& statistics;
  const LiveNoiseModel& noise;
  bool hold_unexcited = true;   // MountingStatistics::hold_unexcited of the next solve()

  /// Blocks 5-6 per mounting and the batch; `update_states`: the mountings keep the M_C^S found;
  /// `left_out`: a case or a run left out, `fixed_m_cs`: the mountings' misalignments to use
  /// instead of estimating them (the convergence test), with their uncertainty and the estimate
  /// they come from.
  LiveEstimate solve(bool update_states, const std::optional<LeftOut>& left_out = std::nullopt,
                     const std::vector<Eigen::Matrix3d>* fixed_m_cs = nullptr,
                     const std::vector<Eigen::Matrix3d>* fixed_angle_covariances = nullptr,
                     const std::vector<std::array<bool, 3>>* fixed_held_angles = nullptr,
                     const LiveEstimate* fixed_from = nullptr);

 private:
  /// Each case's statistics (the open segment's included) and its mounting's M_C^S.
  struct CaseStatistics {
    std::vector<Information> with_open;
    std::vector<const Information*> infos;
    std::vector<Eigen::Matrix3d> m_cs;
    std::vector<std::size_t> state;   // each one's case state (CaseAccumulator::cases)
  };
  /// The covariance of the whitened noise's sums over a case's runs, under its density
  /// (LiveNoiseModel::density_of), for the run lengths it was taken at.
  struct RunNoise {
    std::vector<std::int64_t> rows;
    Eigen::MatrixXd sums_covariance;
  };
  std::vector<RunNoise> run_noise_;   // per case state
  /// Per case of `cs`, its runs' noise sums' covariance (empty: white, no density fitted).
  [[nodiscard]] std::vector<Eigen::MatrixXd> run_noise(const CaseStatistics& cs);

  /// The solver for what the rows so far can determine: terms of the temperature wait until it
  /// has moved (a near-constant T column stands in for the bias, and y*T for the output itself).
  [[nodiscard]] LiveSolver active_solver(const std::vector<Eigen::Index>& terms) const;
  [[nodiscard]] CaseStatistics case_statistics(const std::vector<Eigen::Matrix3d>& m_cs,
                                               const std::optional<LeftOut>& left_out) const;
  /// The mounting angles fitted to the phases' means outside the model: the tilts of mountings
  /// read from poses (static and thermal cases: from the poses' levels).
  [[nodiscard]] int angles_from_means(const std::vector<MountingFit>* fits) const;
  /// The cases' offsets the noise model does not explain, into the batch's covariance.
  void add_case_scatter(LiveEstimate& s, const CaseStatistics& cs, const LiveSolver& batch_solver);
  /// The batch's post-selection inference on the statistics (procedure/post_selection_inference.hpp):
  /// the batch's covariance with the mountings' angle uncertainty (add_misalignment_uncertainty)
  /// and the offsets between the phases (add_case_scatter), and one term at a time the term that
  /// leaves by the rule the batch's inference applies (ident::term_leaving), never the bias or the
  /// scale factor, at the structure's level over the model's terms (ident::family_threshold):
  ///  - a term at the level of the phases' means (constant within every phase: a tumble's poses)
  ///    is told from the phases' offsets (a pose's placement) only by the phases left over
  ///    (s.confounded);
  ///  - in a searched model (LiveModel::searched) every other term is tested too (s.insignificant);
  ///    a model file's terms leave only when confounded.
  /// Bonferroni over `search_space` terms: the terms the data determine before the selection, as
  /// algorithm 2 counts its search space.
  /// Leaves s.batch the fit of what is left, its covariance complete, and s.scatter its offsets;
  /// returns the solver of that model.
  LiveSolver infer_and_prune(LiveEstimate& s, const LiveSolver& batch_solver, std::size_t search_space,
                             const std::vector<const Information*>& infos,
                             const std::vector<Eigen::Matrix3d>& m_cs, const CaseStatistics& cs,
                             const std::vector<MountingFit>& fits, const std::vector<Eigen::Matrix3d>& angle_covariances,
                             const std::vector<std::array<bool, 3>>& held_angles);
};

}  // namespace inertia::online
