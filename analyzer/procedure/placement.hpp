#pragma once
// What the fixture's placement of each case adds to a mounting's misalignment, to first order.
//
// Algorithm 1 reads the sensitivities theta = k n_i along the nominal case axes from the inputs
// the plan states in the case frame. A case placed off its nominal frame by a small rotation
// delta_c presents the sensor a_true = a + delta_c x a, so its every sample's output gains
// theta . (delta_c x a) = a' [theta]x delta_c, and the least-squares fit on the regressors
// r = [a, 1] (the bias with it where the mounting estimates one) moves by
//   d_theta = (G^-1 H_c [theta]x delta_c) in its first three rows,
// G the mounting's Gram of r, H_c = sum over the case's samples of r a'. With independent
// placements of stated sd sigma_c per axis, theta's covariance gains sum_c sigma_c^2 J_c J_c'.
//
// Only the cases the inference's clusters cannot show count: a case of several clusters (its
// phases, or the live estimator's runs) shares one placement among them, which their scatter
// never reveals; a case of one cluster shows its placement as that cluster's offset, and the
// cluster scatter already holds it. A spin case on a rate table is the example: its rates at
// +-30 and +-90 deg/s read a gyroscope's tilt through one placement, seen by no phase alone.
// The batch (mounting_stage.cpp) and the live estimator (online/live_solver.cpp) both call it.
#include <Eigen/Dense>

#include <cstddef>
#include <span>

namespace inertia::procedure {

struct CasePlacement {
  Eigen::Matrix4d gram = Eigen::Matrix4d::Zero();   // [input 1]'[input 1] over the case's samples, case frame
  double sd_rad = 0.0;                              // the fixture's stated accuracy, per axis
  std::size_t clusters = 1;                         // the case's clusters in the inference
};

/// theta's covariance from the placements of `cases` (a mounting's, all of them: G sums every
/// case's gram); `with_bias` where the mounting's fit estimates a bias. Zero without a case of
/// several clusters and a placement sd.
Eigen::Matrix3d placement_covariance(const Eigen::Vector3d& theta, std::span<const CasePlacement> cases, bool with_bias);

}  // namespace inertia::procedure
