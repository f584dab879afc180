#pragma once
// The data-analysis half of the paper's Fig. 1:
//   blocks 5-6   per mounting, algorithm 2: model selection with misalignment estimation (or a
//                fixed model, for the paper's "simple" comparison), giving M_E^S of every case;
//   blocks 7-8   every case's references mapped to F_S with its M_E^S;
//   block 9      the cases concatenated (optionally weighted, section 3.4);
//   block 10/11  batch identification fixed on a model, or by selection (section 2.7.2).
//
// Mountings. The misalignment of a sensor case relative to the frame its references are given in
// is one unknown per mounting of the sensor. Cases that share a mounting (dataset key `mounting`,
// e.g. the three shaker orientations of Fig. 2, where the fixture is remounted but the sensor is
// not) are estimated together: each case's references are first turned into its nominal case frame
// (a_C = M_E^C a_E), where the shared misalignment is one rotation, and algorithm 2 runs on the
// concatenated cases. A case without a mounting label is a mounting of its own.
#include <Eigen/Dense>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

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
  /// asking for the largest order on the table). Median complete-model table error over the 10
  /// seeds of reproduce-paper: 0.0057 deg with 60, 0.0037 with 120, 0.0039 with 200; characterize
  /// --order 2 on the paper dataset: 3.1, 3.3 and 5.8 s of user time.
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
  /// a_p^2 and a_o^2 are left out), so the twist leaves a model error that tilts theta_x..z
  /// (0.003 deg on the noise-free shaker) and makes the mountings disagree in the batch. When
  /// true, blocks 5-6 also estimate the twist about n_i of mountings whose model uses a_p or a_o,
  /// by parabolic steps on the (prewhitened) residual sum of squares, one per refinement of step 1.
  /// Off by default: on noise-free paper data it finds the shaker's 1.16 deg twist and takes the
  /// shaker error from 0.003 to 0.00002 deg, but with table 1's noise the residual is nearly flat
  /// in the twist (5e-6 relative over +-6 deg) and the steps wander (shaker error 0.019 deg).
  bool estimate_twist = false;
  /// What the data do determine about the twist: how the mountings are turned about n_i against
  /// one another. The cross-axis terms (a_i*a_p, a_p*a_o, a_p^2 ..) are one set for the sensor,
  /// so a mounting held at its nominal twist while another is not forces the batch to fit one
  /// set of terms in two frames (sim-paper: the shaker's 1.15 deg left a_i*a_p 97 of its sd from
  /// the truth, a_i*a_o 51, a_p*a_o 48). When true, the batch estimates each further aligned
  /// mounting's twist relative to the reference mounting (the first aligned one, whose nominal
  /// twist defines the sensor's p and o axes, as algorithm 1 does), by Gauss-Newton on the
  /// whitened residual of the batch candidates, and its uncertainty joins the coefficients'
  /// covariance (a searched parameter). A twist the plan does not determine (its sd above
  /// mounting_tolerance_rad) stays at the nominal frame, and the notes say so.
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

/// A candidate term the plan does not determine, and why (for the report and the summary).
struct UndeterminedTerm {
  std::string term;
  std::string reason;
};

struct MountingResult {
  std::string mounting;
  std::vector<std::size_t> cases;           // dataset case indices
  frames::Dcm m_cs = frames::Dcm::Identity();   // M_C^S estimated (relative to the nominal case frame)
  std::vector<std::string> es_terms;        // F_E-and-F_S model used for the misalignment
  std::vector<std::string> s_terms;         // its F_S counterpart after pruning
  ident::UlsResult s_fit;                   // the F_S fit of the selected model
  double fitness = 0.0;
  std::size_t candidates_tried = 0;
  int refinements = 0;
  std::vector<std::string> excluded;        // candidates left out (IEEE rule, dependence)
  int whitening_order = 0;                  // AR order of the noise model (0: white)
  std::optional<double> known_bias;         // removed from the output before the fit
  std::optional<double> square_corner_rad_s;   // b of the squares' high pass (none: static squares)
  double twist_rad = 0.0;                   // estimated twist about n_i added to algorithm 1's M_C^S
  /// What the mounting's inputs determine (excitation.hpp): an axis without its own excitation
  /// keeps its angle at the nominal case frame; without excitation along IRA the mounting is not
  /// aligned at all (M_C^S = I, or for a gyroscope the rate cases' M_C^S).
  AxisExcitation excitation;
  bool aligned = true;
  /// Angles of F_S from the nominal case frame about i, p, o (rad) and their sd; an angle held at
  /// nominal has sd 0 and `held` says why. About i (the twist) a single-axis sensor's linear part
  /// does not see: NaN, unless the batch found it relative to the reference mounting
  /// (PipelineOptions::batch_relative_twist; `twist_reference` names that mounting).
  Eigen::Vector3d angles = Eigen::Vector3d::Zero();
  Eigen::Vector3d angles_sd = Eigen::Vector3d::Zero();
  /// Degrees of freedom of the angles' sd (few when the offsets between the mounting's phases
  /// dominate them, as a tumble's placement errors do): intervals use Student's t with them.
  double angles_dof = std::numeric_limits<double>::infinity();
  /// The part of angles_sd a held twist's tolerance adds (relative_twists in pipeline.cpp): a
  /// bound on a systematic error, the same in every run of the plan.
  Eigen::Vector3d angles_held_sd = Eigen::Vector3d::Zero();
  std::string twist_reference;              // the mounting angles(0) is relative to (empty: none)
  std::vector<std::string> held;            // what was held at the nominal frame, and why (for the user)
  std::vector<UndeterminedTerm> pruned;     // selected terms the honest inference took out, and why
};

struct CaseOutcome {
  std::size_t case_index = 0;
  frames::Dcm m_es = frames::Dcm::Identity();   // estimated M_E^S (blocks 5-6)
  Eigen::Index first_row = 0;               // first case sample in the batch rows
  Eigen::Index begin = 0, rows = 0;         // rows of the batch stack
};

struct PipelineResult {
  std::vector<MountingResult> mountings;
  std::vector<CaseOutcome> cases;
  std::vector<ident::Term> terms;           // the batch model (F_S)
  ident::UlsResult fit;                     // batch fit: theta, std_dev, residuals (stacked rows)
  ident::ParameterTTest t_test;
  ident::ResidualMeanTest residual_mean;
  double aic = 0.0;
  frames::Dcm m_cs = frames::Dcm::Identity();   // of the first mounting (model file)
  Eigen::VectorXd whitening;                // batch AR noise model a_1..a_m (empty: white)
  /// With square_highpass: the corner b of the batch's squares (a_i^2, a_p^2, a_o^2 enter as
  /// s/(s + b) a_j^2, so their coefficients are the high-frequency gains K_jj of eq. 12);
  /// none: static squares. A model file must carry it to mean the same model.
  std::optional<double> square_corner_rad_s;
  std::vector<UndeterminedTerm> undetermined;
  /// The offsets between the cases' phases (statistics.hpp, cluster_offsets) that the batch's
  /// covariance includes, and each process term's test dof (between-phase where the offsets
  /// carry most of its variance).
  ident::ClusterOffsets inference;
  Eigen::VectorXd test_dof;
  /// Per process term, the part of its sd the held angles' tolerance adds (mounting_tolerance_rad):
  /// a bound on a systematic error, the same in every run of the plan (zero: none held).
  Eigen::VectorXd held_sd;
  /// Plan-level statements for the user: what was pooled or inferred, what the plan does not
  /// determine and what excitation it would need.
  std::vector<std::string> notes;
};

/// Runs blocks 5-11 on `data`. Throws InputError for bad input (missing columns, bad options) and
/// std::runtime_error when nothing can be identified (the message names the terms involved).
PipelineResult run_pipeline(const dataset::Dataset& data, const PipelineOptions& options,
                            std::string_view dataset_label);

/// Blocks 5-6 alone for one mounting (exposed for tests and reproduce-paper).
/// `known_bias`: a bias (output unit) estimated elsewhere, subtracted from the output first.
MountingResult estimate_mounting(const dataset::Dataset& data, const std::vector<std::size_t>& cases,
                                 const std::string& mounting, const PipelineOptions& options,
                                 std::string_view dataset_label, std::optional<double> known_bias = std::nullopt);

/// A case's batch weight: the weight given for its plan case (itself, or the case it is a piece
/// of: a log split by lost samples); 1 otherwise.
double case_weight(const PipelineOptions& options, const dataset::CaseData& c);

/// InputError naming a weight whose case the dataset does not have (run_pipeline calls it).
void check_case_weights(const dataset::Dataset& data, const PipelineOptions& options);

/// A case as the grouping into mountings sees it.
struct MountingKey {
  std::string name;     // its plan case
  std::string label;    // its `mounting` label ("": none)
  CaseKind kind = CaseKind::Static;
};
using MountingGroups = std::vector<std::pair<std::string, std::vector<std::size_t>>>;

/// Which cases share a mounting (blocks 5-6): the batch pipeline's and the live estimator's one
/// rule. Cases with one `mounting` label share it and an unlabelled case is its own, in order of
/// first appearance; with no label anywhere, an accelerometer's static and thermal poses (two or
/// more) share one mounting "poses", put first (a tumble: the sensor stays in its fixture, which
/// is turned between poses); a gyroscope's cases are one mounting "all cases" (paper section 2.2:
/// its M_C^S is read from the rates of every case). What was inferred goes to `notes`.
MountingGroups group_mountings(const std::vector<MountingKey>& cases, dataset::SensorKind sensor,
                               std::vector<std::string>* notes = nullptr);
/// The same for a dataset's cases (keyed by their plan case).
MountingGroups mountings_of(const dataset::Dataset& data, std::vector<std::string>* notes = nullptr);

}  // namespace inertia::procedure
