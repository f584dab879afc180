#pragma once
// What the fixture's placement of each case adds to the estimates' uncertainty.
//
// A case placed off its nominal frame by a small rotation delta_c (stated sd sigma_c per axis,
// dataset::CaseData::placement_sd_rad) presents the sensor a_true = a + delta_c x a: every sample
// of the case moves together, by what that turn moves the model's prediction.
//
// The offline inference (the mounting stage's and the batch's, post_selection_inference.hpp)
// holds every stated placement as a known part of the residual's covariance,
// R = R_noise + P P', P's columns what a turn of one case by its sd about one case axis moves
// the prediction (placement_columns, the terms' nonlinearity included). The offsets between
// clusters are then estimated only beyond what the noise and the placements explain. A case of
// several clusters (a spin case on a rate table: its rates at +-30 and +-90 deg/s read a
// gyroscope's tilt through one placement, seen by no phase alone) and a case of one (a tumble's
// pose) are alike there.
//
// The live estimator, which keeps statistics per mounting and not rows per case, and a mounting
// whose model is fixed (no inference) take the first order of the same effect on the angles
// (placement_covariance): algorithm 1 reads theta = k n_i along
// the nominal case axes, the output gains theta . (delta_c x a) = a' [theta]x delta_c, and the
// least-squares fit on the regressors r = [a, 1] (the bias with it where the mounting estimates
// one) moves by d_theta = (G^-1 H_c [theta]x delta_c) in its first three rows, G the mounting's
// Gram of r, H_c = sum over the case's samples of r a'; theta's covariance gains
// sum_c sigma_c^2 J_c J_c'. Every placed case counts, a case of one cluster (a tumble's pose) as
// well as a spin case: a pose's tilt moves the fit's sensitivities, which absorb most of it, and
// the offsets estimated between the clusters see only what the fit leaves (on a six-position
// tumble, 2 of the 6 pose means), so they cannot stand for the stated placements.
#include <Eigen/Dense>

#include <cstddef>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/prewhitening.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

struct CasePlacement {
  Eigen::Matrix4d gram = Eigen::Matrix4d::Zero();   // [input 1]'[input 1] over the case's samples, case frame
  double sd_rad = 0.0;                              // the fixture's stated accuracy, per axis
};

/// theta's covariance from the placements of `cases` (a mounting's, all of them: G sums every
/// case's gram); `with_bias` where the mounting's fit estimates a bias. Zero without a placement sd.
Eigen::Matrix3d placement_covariance(const Eigen::Vector3d& theta, std::span<const CasePlacement> cases, bool with_bias);

/// A plan case's stated placement (dataset::CaseData::placement_sd_rad) and the dataset cases
/// that are its pieces, which share it.
struct StatedPlacement {
  std::vector<std::size_t> pieces;   // dataset case indices
  double sd_rad = 0.0;
};

/// Every plan case of `data` with a stated placement.
std::vector<StatedPlacement> stated_placements(const dataset::Dataset& data);

/// The placements as part of the residual's covariance R = R_noise + P P' of a fit of `terms`
/// (coefficients `theta`) on the stack of `inputs` (stack_regressions with `first_row`, the
/// squares through `square_corner`, then `whitener`): per placement with rows among the inputs
/// (StackInput::case_index) and per case axis (IRA, XRA, YRA), a column of P, the central
/// difference of the prediction with that case frame turned by +-1 sd about the axis (zero on the
/// other cases' rows). Exact for the terms' nonlinearity within the sd; the pieces of one case
/// turn together. Cases of one cluster and of several alike: the inference's offsets between
/// clusters are then what the noise and the placements leave (post_selection_inference.hpp).
Eigen::MatrixXd placement_columns(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                                  std::span<const StackInput> inputs, std::span<const StatedPlacement> placements,
                                  const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                  std::optional<double> square_corner, const ArWhitener& whitener);

}  // namespace inertia::procedure
