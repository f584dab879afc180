#pragma once
// The online estimator's noise model (online_estimator.hpp, "Noise"): the first noise_window_s of
// rows are kept; then an autoregressive model is fitted to the residuals of the white-noise fit
// on them (AIC order up to whitening_max_order, as the batch), and every row so far enters the
// statistics again through it. A model with output-multiplied terms keeps its rows unfiltered and
// scales the variances instead, by what the batch's sandwich under that noise makes of a column
// constant within each run (procedure::unfiltered_long_run_ratio). A whitened model keeps each
// case's whitened residual's own noise (case_density), whose colour below what the AR model
// follows moves the case's phases together (LiveSolver::add_case_scatter).
#include <Eigen/Dense>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::online {

struct LiveModel;
class CaseAccumulator;
class EstimateSolver;

/// Rows of the noise window as they entered the statistics (basis columns, output, inputs).
struct BufferedRows {
  std::size_t state = 0;
  std::size_t plan_case = 0;
  int segment = 0;
  double period = 0.0;
  Eigen::MatrixXd base;
  Eigen::VectorXd y;
  Eigen::MatrixX3d inputs;   // along the case axes (Information::add_inputs)
  std::vector<std::uint16_t> phase;   // per row: the chunk's phase label
  std::vector<std::int32_t> plan_phase;   // per row: the plan's phase index
};

/// The noise in the window's residuals: per piece (one per run and plan phase) what is left about
/// the piece's own level (taken off in `residuals`), and only the pieces of at least
/// kNoiseFloorRows rows whose power is within kNoiseFloorPowerRatio of the quietest such piece.
/// The model is fitted on the window's rows before the plan determines it (over two poses, a
/// bias alone): the phases' levels it cannot yet explain are no noise, and would read as a near
/// unit root; nor is the misfit that follows a phase's changing input (a table's move between
/// poses, tens of times the noise). Noise is the same in every phase; a factor of 4 in power (2
/// in rms) is the band its sampling and its slow part leave between phases.
inline constexpr Eigen::Index kNoiseFloorRows = 50;
inline constexpr double kNoiseFloorPowerRatio = 4.0;
[[nodiscard]] std::vector<procedure::CaseRows> noise_pieces(Eigen::VectorXd& residuals, std::vector<procedure::CaseRows> pieces);

struct LiveNoiseModel {
  std::vector<BufferedRows> buffer;   // the window's rows, until the model is fitted
  std::int64_t buffered_rows = 0;
  bool fitted = false;
  Eigen::VectorXd ar;                 // AR coefficients (empty: white)
  /// The whitened residual's own noise below what the AR model follows (noise/coloured_noise.hpp),
  /// as the batch's inference fits it per case: per case state the density fitted on its rows in
  /// the window, per unit variance (the solve scales it by its fit's residual variance; empty
  /// function: none there), and for the other cases that of the window's longest. None for a
  /// model kept unfiltered, which scales its variances instead.
  std::vector<std::function<double(double)>> case_density;
  std::function<double(double)> density;

  /// The density of case state `state`'s whitened noise (empty function: white).
  [[nodiscard]] const std::function<double(double)>& density_of(std::size_t state) const {
    return state < case_density.size() && case_density[state] ? case_density[state] : density;
  }

  /// Fits the model on the window (the white-noise estimate from `estimates`), then sends every
  /// row of the window through it into `statistics` again, or scales the solver's variances.
  void fit(LiveModel& live, CaseAccumulator& statistics, EstimateSolver& estimates);
};

}  // namespace inertia::online
