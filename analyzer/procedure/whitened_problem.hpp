#pragma once
// A stacked regression as the procedure fits it: the squares through their high pass (eq. 12),
// with the corner searched by the GLS criterion, and every row AR-whitened by the noise model of
// the full candidate set's residual. The plan's static stretches give the noise law below one
// cycle per case that the inference after selection uses. Blocks 5-6 (each mounting) and the
// batch build their problems the same way, through whiten_problem.
#include <Eigen/Dense>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// Columns of `labels` that are plain squares of a sensor-frame acceleration (a_i^2, a_p^2,
/// a_o^2, at any lag): the terms eq. 12 passes through K_jj(s).
std::vector<Eigen::Index> square_columns(const std::vector<std::string>& labels);

/// Whether a fit's process terms include such a square.
bool has_square_term(const ident::UlsResult& fit);

/// Applies the squares' high pass with corner `corner_rad_s` (none: static squares) to a freshly
/// stacked problem.
void apply_square_model(StackedRegression& s, const dataset::Dataset& data, std::optional<double> corner_rad_s);

/// The plan's own noise where it holds still: the Allan variance of the unwhitened residual over
/// the static stretches (noise::static_stretches: dwells, static cases), pooled, and its terms.
/// A case's whitened residual cannot say what its noise does below one cycle per case, and a case's
/// mean (the bias, a pose's static terms) is read there. The static stretches of all cases together
/// can, where each case's whitened residual leaves the flicker and random walk undetermined.
struct StaticNoiseLaw {
  noise::NoiseFit fit;
  double tau0_s = 0.0;
  Eigen::Index plan_rows = 0;   // the rows of every case: one cycle per plan is the lowest frequency it spans

  /// The whitened residual's two-sided density per sample at f cycles per sample, below one cycle
  /// per case (noise::fitted_spectrum's below_record): the law's white part and its determined
  /// flicker and random walk through the whitener's gain at DC, A(1)^2, held at its level at one
  /// cycle per plan below that.
  [[nodiscard]] std::function<double(double)> below_record(const ArWhitener& whitener) const;
};

/// The law of `residuals` (unwhitened, rows of `layout`) over the static stretches of `data`; none
/// when the plan has none of 64 samples or more, too few octaves for the fit, or the law does not
/// hold on its own stretches.
std::optional<StaticNoiseLaw> static_noise_law(const Eigen::VectorXd& residuals, const std::vector<CaseRows>& layout,
                                               const dataset::Dataset& data);

struct WhiteningOptions {
  int max_order = 0;                        // of the AR noise model (0: white)
  /// Search the squares' corner on these rows; otherwise `square_corner` is applied as given.
  bool search_square_corner = false;
  std::optional<double> square_corner;      // none: static squares
  double corner_min_rad_s = 1.0;            // search range of the corner
  double corner_max_rad_s = 1.0e4;          // (clamped below the Nyquist frequency)
  ident::ErrOptions err;                    // the full candidate set's identifiable columns
  ident::UlsOptions uls;                    // its fit (white: noise lags are not used)
};

struct WhitenedProblem {
  StackedRegression regression;             // squares high-passed, rows whitened
  ArWhitener whitener;
  std::optional<StaticNoiseLaw> noise_law;
  std::optional<double> square_corner_rad_s;
  /// The columns the data determine (identifiable_ranking, less what the fit let go), ERR order.
  std::vector<Eigen::Index> identifiable;
};

/// The whitening of `options`: the squares' corner searched (`search_square_corner`, with the
/// squares' high pass on) or `square_corner` applied.
WhiteningOptions whitening_options(const PipelineOptions& options, bool search_square_corner,
                                   std::optional<double> square_corner);

/// `stacked` (unfiltered, unwhitened) as the procedure fits it: the squares' corner searched on
/// the unwhitened rows, the noise model fitted to the residual of every identifiable column, then
/// the corner searched again on the whitened rows (the GLS criterion: under 1/f noise the
/// unwhitened residual is dominated by the noise's slow wander, and a corner found there scatters
/// many times more than its information says), and the rows whitened. The high pass and the
/// whitening are both linear filters run case by case, so they commute but for a case's first
/// few samples.
WhitenedProblem whiten_problem(StackedRegression stacked, const dataset::Dataset& data, const WhiteningOptions& options);

}  // namespace inertia::procedure
