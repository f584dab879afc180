#pragma once
// The options of the characterization procedure (blocks 5-11 of the paper's Fig. 1): how the
// models are chosen, how the noise is modelled, and the rules for mountings and held angles.
// Every stage of the procedure (pipeline.hpp) reads its part of them.
#include <map>
#include <string>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/procedure/mounting_rules.hpp"

namespace inertia::procedure {

/// How a model is chosen: by algorithm 2 / section 2.7.2 over candidates, or fixed.
struct ModelChoice {
  bool select = true;                       // false: `fixed_terms`
  ident::CandidateOptions candidates;       // r, sign/abs, temperature (noise terms: see noise_lags)
  std::vector<std::string> fixed_terms;     // for select = false; F_E-and-F_S terms for blocks 5-6
                                            // (e.g. 1 a_x a_y a_z), F_S terms for block 10 (1 a_i)
  int noise_lags = 0;                       // MA part e[k-1..k-n] estimated by ELS (coloured noise)
};

struct PipelineOptions {
  ModelChoice misalignment;                 // blocks 5-6
  ModelChoice batch;                        // blocks 10-11
  ident::SelectionOptions selection;        // t-test level, multiplicity, ULS options
  std::map<std::string, double> case_weights;   // case name -> weight (section 3.4); default 1
  /// Largest order of the autoregressive noise model used to prewhiten every fit (GLS; see
  /// prewhitening.hpp); 0 fits by ordinary least squares as the paper does. At 10 kHz an AR model
  /// needs many lags to follow 1/f noise down toward the table's rotation frequency (AIC keeps
  /// asking for the largest order on the table). 120 lags: fewer leave reproduce-paper's
  /// complete-model table error larger, and more gain nothing and cost time (docs/validation.md,
  /// 'Evidence behind choices in the code').
  int whitening_max_order = 120;
  int max_refinements = 6;                  // step-1 fixed point: nonlinear F_S terms need M_E^S
  /// Which terms blocks 5-6 leave out of a mounting and which bias it takes from another
  /// (mounting_rules.hpp). A bias a shaker-only mounting fitted itself would leak into theta_x,
  /// theta_y, theta_z (gravity points along a different case axis in each orientation) and tilt
  /// n_i: it takes the bias of the mountings that determine it (rotation table, static).
  Ieee1293Rules ieee_1293;
  /// Eq. 12 (section 3.1): the squares a_i^2, a_p^2, a_o^2 act through first-order high-pass
  /// filters K_jj(s) = K_jj s / (s + b). A static model of them is structurally wrong on the
  /// shaker (the filter removes the large mean of v^2 and shifts the phase of the 2 g v part)
  /// and tilts theta_x..z by far more than the noise does. When true, blocks 5-6 filter the square
  /// columns of every mounting with H_b(s) = s / (s + b) (bilinear, prewarped at b; the filter
  /// settled at each case's first row) and estimate the corner b by a 1-D search on the residual
  /// sum of squares of the full model (variable projection); the static model (no filter) is one
  /// of the candidates and wins when it fits better. The coefficients of the mounting fit are then
  /// the high-frequency gains K_jj. The model stays an output-error one (no y lags), so the
  /// prewhitening stays consistent.
  bool square_highpass = true;
  /// The same for the batch (blocks 10-11); off reproduces the paper's static eqs. 2 and 4.
  bool batch_square_highpass = true;
  double square_highpass_min_rad_s = 1.0;     // search range of b
  double square_highpass_max_rad_s = 1.0e4;   // (clamped below the Nyquist frequency)
  /// Algorithm 1 fixes n_i only; n_p and n_o follow the nominal case axes turned onto n_i, so a
  /// mounting whose true misalignment turns the case about n_i (e.g. 2 deg about case [1,1,1])
  /// evaluates a_p and a_o in a frame twisted against the sensor's. The terms in a_p, a_o are
  /// not closed under that twist (a_p^2 and a_o^2 pass a high pass, a_p*a_o does not; on the table
  /// a_p^2 and a_o^2 are left out), so the twist leaves a model error that tilts theta_x..z and
  /// makes the mountings disagree in the batch. When true, blocks 5-6 also estimate the twist
  /// about n_i of mountings whose model uses a_p or a_o, by parabolic steps on the (prewhitened)
  /// residual sum of squares, one per refinement of step 1.
  /// Off by default: on noise-free paper data it finds the shaker's twist and removes most of that
  /// error, but with table 1's noise the residual is nearly flat in the twist and the steps wander,
  /// leaving a larger error than the twist did (docs/validation.md, 'Evidence behind choices in
  /// the code').
  bool estimate_twist = false;
  /// What the data do determine about the twist: how the mountings are turned about n_i against
  /// one another. The cross-axis terms (a_i*a_p, a_p*a_o, a_p^2 ..) are one set for the sensor,
  /// so a mounting held at its nominal twist while another is not forces the batch to fit one
  /// set of terms in two frames, which leaves those terms many sd from the truth (sim-paper in
  /// docs/validation.md, 'Evidence behind choices in the code'). When true, the batch estimates
  /// each further aligned mounting's twist relative to the reference mounting (the first aligned
  /// one, whose nominal twist defines the sensor's p and o axes, as algorithm 1 does), by
  /// Gauss-Newton on the whitened residual of the batch candidates, and its uncertainty joins the
  /// coefficients' covariance (a searched parameter). A twist the plan does not determine (its sd
  /// above mounting_tolerance_rad) stays at the nominal frame, and the notes say so.
  bool batch_relative_twist = true;
  /// Temperature terms join the candidates (T, a_i*T; gyros T, T[k-1], y*T) whenever every case
  /// has a temperature column: a thermal plan's effects must be offered to be found, and a plan
  /// whose temperature does not vary says so (the terms are then not determined).
  bool temperature_when_measured = true;
  /// An angle a mounting's excitation does not determine is held at the nominal case frame, but
  /// the sensor is not exactly there: each held angle is taken to lie within this tolerance (one
  /// sd), and what it moves in the batch model is added to the coefficients' covariance.
  double mounting_tolerance_rad = 0.017453292519943295;   // 1 deg
};

}  // namespace inertia::procedure
