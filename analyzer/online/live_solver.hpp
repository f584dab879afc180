#pragma once
// The live estimator's answer from its sufficient statistics (information.hpp), re-derived at
// every publish: the paper's procedure on statistics instead of samples.
//  - Per mounting (blocks 5-6): the model in its external-frame form (eq. 1: the scale factor
//    split over a_x a_y a_z of the mounting's nominal case frame, the other terms in F_S) fitted
//    with M_C^S from algorithm 1 on its own sensitivities, to the fixed point. The mountings'
//    rules are the batch pipeline's (procedure/mounting_rules.hpp): on a rotation table a_p^2 and
//    a_o^2 are left out (IEEE 1293 12.3.5.7), a mounting of shaker cases only takes the bias from
//    the mountings that determine it.
//  - The batch (blocks 10-11): the model in F_S over every mounting, each with its M_C^S.
//  - The squares' corner b of eq. 12: the corner (or static squares) with the least residual sum
//    of squares, by the batch's rule (procedure/corner_search.hpp), on columns interpolated
//    between the grid's nodes (corner_grid.hpp).
//  - What the data cannot determine (a column in the span of the others, or no excitation at
//    all) is left out of the fit and named, never guessed.
// Every step is a few small dense solves: the cost does not depend on how many samples came in.
#include <Eigen/Dense>

#include <array>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/online/corner_grid.hpp"
#include "analyzer/online/information.hpp"
#include "analyzer/online/live_basis.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/placement.hpp"
#include "analyzer/procedure/turn_search.hpp"
#include "analyzer/procedure/mounting_rules.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::online {

/// A least-squares fit on statistics.
struct StatFit {
  bool ok = false;
  std::vector<Eigen::Index> terms;          // basis term indices fitted, in the order given
  Eigen::VectorXd theta, sd;                // per fitted term
  Eigen::VectorXd conditional_sd;           // sd with every M_C^S taken as known
  Eigen::MatrixXd gram_inverse;             // (Phi'Phi)^-1 of the fitted terms
  Eigen::MatrixXd covariance;
  std::vector<Eigen::Index> undetermined;   // basis term indices the data did not determine
  double rss = 0.0;                         // sum of squared (whitened) residuals
  double weight = 0.0;                      // samples
  double s2 = 0.0;                          // residual variance rss / (weight - p)
  std::optional<double> corner_rad_s;       // the squares' high pass (none: static squares)
  std::string why;                          // when !ok
  [[nodiscard]] std::optional<double> value(Eigen::Index term) const;
};

/// A mounting's statistics and what is known of its misalignment.
struct MountingStatistics {
  std::string name;
  Information info;
  procedure::MountingKind kind;
  Eigen::Matrix3d m_cs = Eigen::Matrix3d::Identity();   // warm start of algorithm 1
  /// Hold the angles the inputs do not excite (procedure::axis_excitation). Off: every axis is
  /// fitted, as free regressors, for the least residual (what the noise model is fitted on).
  bool hold_unexcited = true;
  /// Each of its cases' placement (procedure/placement.hpp): their inputs' Gram, stated sd and runs.
  std::vector<procedure::CasePlacement> placements;
};

struct MountingFit {
  bool determined = false;                  // the data fixed M_C^S
  Eigen::Matrix3d m_cs = Eigen::Matrix3d::Identity();
  /// Rotation of F_S from the nominal case frame (rotation vector, case axes ~ i, p, o), rad; the
  /// component about the sensitive axis is not observable from one axis and is NaN.
  Eigen::Vector3d angles = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d angles_sd = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Matrix3d angles_covariance = Eigen::Matrix3d::Zero();   // of the rotation vector (rank 2: no twist)
  /// The part of angles_covariance the cases' placements give (procedure::placement_covariance
  /// through algorithm 1): a turn found later (RelativeTurn) re-estimates the tilts from the noise
  /// alone and adds it back.
  Eigen::Matrix3d placement_angles_covariance = Eigen::Matrix3d::Zero();
  /// The rotation vector's components (i, p, o) held at the nominal frame: not determined by the
  /// mounting's inputs, assumed within the mounting tolerance (angles_covariance carries its square).
  std::array<bool, 3> held{};
  std::optional<double> bias;               // the external-frame fit's bias, when it has one
  double bias_sd = 0.0;                     // ... and its sd
  int refinements = 0;
  StatFit fit;
  std::string note;
};

/// Offsets between the clusters of the cases' rows (Information's runs: a phase, or a minute of a
/// long one) that the noise model does not explain: 1/f noise below an AR model's reach, a fixture
/// remounted between cases, a pose's placement, a thermal step's drift. Taken by the batch's rule,
/// ident::cluster_offsets, on the runs' sums: the offsets' variance (common, and in proportion to
/// the cluster's cross-axis loading), its dof, and what it adds to every estimate's covariance.
struct CaseScatter {
  int clusters = 0;
  int dof = 0;                      // between-cluster dof left by the model's cluster means and the angles
  double tau2 = 0.0;                // mean offset variance per cluster, output unit squared (the noise model undone)
  bool weighed = false;             // the clusters' means weighed by their offsets (ident::weighed_by_offsets)
  /// The fit's terms whose column is constant within every cluster (ident::phase_level_columns,
  /// the batch's rule): a static pose's terms. Such terms and the clusters' offsets (a pose's
  /// placement) are told apart only by the clusters left over.
  std::vector<Eigen::Index> phase_level;
  /// The offsets as ident::cluster_offsets took them, in the fit's terms' order (the weighed
  /// estimate's `within` and `covariance` when weighed): what each term's test reads
  /// (ident::term_leaving).
  ident::ClusterOffsets offsets;
};

struct CandidateStat {
  Eigen::Index term = -1;                   // basis term index
  double err = 0.0;                         // share of the output energy (about its mean) the term explains
  double value = 0.0, sd = 0.0, t = 0.0;
  double p_value = 1.0;
  bool significant = false;                 // p below alpha over the number of candidates
};

struct SolverOptions {
  ident::UlsOptions uls;
  int max_refinements = 50;                 // algorithm 1's fixed point
  double refinement_tolerance_rad = 1e-10;
  procedure::Ieee1293Rules ieee_1293;       // the batch's (procedure::PipelineOptions::ieee_1293)
  double structure_alpha = 0.01;
  /// procedure::PipelineOptions::batch_relative_twist and mounting_tolerance_rad, the same here.
  bool relative_twist = true;
  double mounting_tolerance_rad = 0.017453292519943295;
  /// For a model kept white (output-multiplied terms: no AR whitening), the residual's long-run
  /// variance over its variance (procedure::unfiltered_long_run_ratio): every variance the solver
  /// reports is scaled by it. 1 for a whitened model.
  double long_run_variance_factor = 1.0;
};

/// A mounting's turn against the reference mounting (LiveSolver::relative_turns).
struct RelativeTurn {
  bool estimated = false;   // its twist about n_i (with its tilts) found from the data
  bool held = false;        // its twist not determined: held at the nominal frame
  double twist_rad = 0.0;   // the twist found (about n_i, against the reference)
  double twist_sd_rad = 0.0;
  /// Of the turn found, as a rotation vector about i, p, o (the information's inverse; for a held
  /// twist the tolerance about i): what add_misalignment_uncertainty propagates.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  /// Of a turn found, the tilts not searched (not determined by the mounting's excitation): held
  /// at where the mounting's fit left them, within the tolerance (in `covariance`). Angles about
  /// i, p, o, as MountingFit::held.
  std::array<bool, 3> held_angles{};
  procedure::TwistHeld why;   // of a held twist
};

/// The cases as the clusters' inference reads them (LiveSolver::add_case_scatter's arguments, for
/// LiveSolver::relative_turns): each case's statistics and its mounting, per case the covariance of
/// the whitened noise's sums over its runs (empty: white), A(1) of the noise model, and the
/// mounting angles estimated from the clusters' means.
struct CaseClusters {
  std::vector<const Information*> infos;
  std::vector<std::size_t> mountings;
  std::vector<Eigen::MatrixXd> run_noise;
  double noise_gain = 1.0;
  int angles_from_means = 0;
};

class LiveSolver {
 public:
  /// `model`: basis term indices of the model (F_S); `sensitivities`: of a_x a_y a_z (w_x w_y
  /// w_z for a gyroscope); `grid`: the nodes the filtered statistics were kept at (empty: static
  /// squares only); `static_option`: static squares compete with the high pass.
  LiveSolver(const LiveBasis& basis, std::vector<Eigen::Index> model, std::vector<Eigen::Index> sensitivities,
             dataset::SensorKind sensor, CornerGrid grid, bool static_option, SolverOptions options);

  /// Blocks 5-6 on one mounting; `known_bias` is subtracted first (shaker-only mountings), and its sd
  /// `known_bias_sd` is in the angles' (procedure::estimate_mounting's rule).
  [[nodiscard]] MountingFit fit_mounting(const MountingStatistics& m, std::optional<double> known_bias,
                                         double known_bias_sd = 0.0) const;
  /// Blocks 10-11: the model over the mountings, each with its M_C^S.
  [[nodiscard]] StatFit fit_batch(const std::vector<const Information*>& infos,
                                  const std::vector<Eigen::Matrix3d>& m_cs) const;
  /// The same at a given corner (none: static squares).
  [[nodiscard]] StatFit fit_batch_at(const std::vector<const Information*>& infos, const std::vector<Eigen::Matrix3d>& m_cs,
                                     std::optional<double> corner) const;
  /// The batch pipeline's relative twists (procedure::search_turns, the search both share) on the
  /// statistics: each aligned mounting but `reference` turned (its twist about n_i and the tilts
  /// `tilts_determined[mounting]` says its excitation determines, turned()'s axes 0 and 1) to the
  /// least residual of the batch model at `corner`, by the batch's Gauss-Newton steps from the
  /// statistics (turn_derivative_gram). A twist whose sd with the tilts free exceeds the tolerance
  /// is held. Turns `m_cs` by what it finds.
  /// The turns' covariance is the batch's sandwich (relative_twists.cpp): with `cases`, the one the
  /// coefficients get (turn_covariance); without, the white noise's.
  [[nodiscard]] std::vector<RelativeTurn> relative_turns(const std::vector<const Information*>& infos,
                                                         std::vector<Eigen::Matrix3d>& m_cs, std::size_t reference,
                                                         const std::vector<bool>& aligned,
                                                         const std::vector<std::array<bool, 2>>& tilts_determined,
                                                         std::optional<double> corner, const CaseClusters* cases = nullptr) const;
  /// The covariance of the turn parameters' Gauss-Newton step at `at` as add_case_scatter takes the
  /// coefficients': the prediction's derivatives by the turns join the fitted columns, and their
  /// block of the cluster sandwich (the noise's colour over the runs, the offsets between them that
  /// it does not explain) is the turns'. A turn read from the cases' means (a twist moving gravity
  /// from p to o in static stretches) is then as uncertain as the flicker and the remounts make
  /// those means, as the batch's residual spectrum per run says. None with fewer than two clusters.
  [[nodiscard]] std::optional<Eigen::MatrixXd> turn_covariance(const StatFit& at, std::span<const procedure::TurnParameter> parameters,
                                                               const CaseClusters& cases, const std::vector<Eigen::Matrix3d>& m_cs,
                                                               double step) const;
  /// What the mountings' misalignment uncertainty adds to the batch's covariance (the batch's own
  /// covariance treats M_C^S as known), by the batch's rules:
  ///  - estimated angles: the batch refitted with each M_C^S turned by +-1 sd along each principal
  ///    direction of their covariance, half the difference;
  ///  - a held angle (`held`, per mounting the rotation vector's components): the batch refitted with
  ///    the mounting turned by the tolerance about it, less the batch (procedure::held_angle_response):
  ///    where the angle's first-order effect vanishes (a static pose's scale factor goes as its
  ///    cosine) a symmetric difference would add nothing.
  /// Added to batch.covariance and sd.
  void add_misalignment_uncertainty(StatFit& batch, const std::vector<const Information*>& infos,
                                    const std::vector<Eigen::Matrix3d>& m_cs,
                                    const std::vector<Eigen::Matrix3d>& angle_covariances,
                                    const std::vector<std::array<bool, 3>>& held) const;
  /// Adds the case scatter to batch.covariance and sd (see CaseScatter). `cases`: each case's
  /// statistics and its mounting's M_C^S; `noise_gain`: A(1) = 1 - sum a_j of the noise model.
  /// `angles_from_means`: the mounting angles estimated from the same clusters' means outside the
  /// model (ident::cluster_offsets' estimated_elsewhere). `run_noise`: per case, the covariance of
  /// the whitened noise's sums over its runs per unit variance of the noise (Z'RZ of the batch's
  /// ident::ColouredNoise over the fit's residual variance; empty or none: white). With it the noise's colour below what the AR model follows (flicker that moves
  /// a case's phases together) enters as the batch's coloured sandwich does, its X'RX and X'RZ
  /// taken on the runs' means: each column's variation within a run meets the noise as white.
  /// A model kept unfiltered has none: the long-run factor scales its variances.
  CaseScatter add_case_scatter(StatFit& batch, const std::vector<const Information*>& cases,
                               const std::vector<Eigen::Matrix3d>& m_cs, double noise_gain, int angles_from_means = 0,
                               const std::vector<Eigen::MatrixXd>* run_noise = nullptr) const;
  /// The same solver for another model (a subset of the basis's terms).
  [[nodiscard]] LiveSolver with_model(std::vector<Eigen::Index> model) const {
    LiveSolver s = *this;
    s.model_ = std::move(model);
    return s;
  }
  [[nodiscard]] Eigen::Index bias_term() const { return bias_; }
  /// Per term of `terms`: +1, or -1 for an output-multiplied one, which ULS's prediction negates
  /// (uls_batch.hpp): the prediction is sum sign_j theta_j phi_j.
  [[nodiscard]] Eigen::VectorXd prediction_signs(const std::vector<Eigen::Index>& terms) const;
  /// The fit's coefficients as its prediction takes them, sign_j theta_j (prediction_signs): the
  /// fitted prediction of rows is their basis columns, transformed to `fit.terms`, times this.
  [[nodiscard]] Eigen::VectorXd signed_theta(const StatFit& fit) const {
    return fit.theta.cwiseProduct(prediction_signs(fit.terms));
  }
  /// [Phi D y]'[Phi D y] over `infos`: Phi the fitted terms of `at` (each mounting with its M_C^S),
  /// D per turn parameter the derivative of the fitted prediction Phi(theta) with respect to it
  /// (its mounting turned by +-`step` rad, central difference of the transform; zero on the other
  /// mountings' rows). What a Gauss-Newton step of the turn search reads (procedure::search_turns).
  [[nodiscard]] Eigen::MatrixXd turn_derivative_gram(const StatFit& at, std::span<const procedure::TurnParameter> parameters,
                                                     const std::vector<const Information*>& infos,
                                                     const std::vector<Eigen::Matrix3d>& m_cs, double step) const;
  void set_long_run_variance_factor(double factor) { options_.long_run_variance_factor = factor; }
  [[nodiscard]] double long_run_variance_factor() const { return options_.long_run_variance_factor; }
  /// Algorithm 2 without the misalignment steps (section 2.7.2, ident::select_model on the normal
  /// equations, as the batch's block 10-11 selection runs on rows) over the terms `batch` fitted,
  /// at its corner: the terms it selects. The sensor's sensitivities and the bias are never left
  /// out; the ranking is the batch's (ident::rank_identifiable).
  [[nodiscard]] std::vector<Eigen::Index> select(const StatFit& batch, const std::vector<const Information*>& infos,
                                                 const std::vector<Eigen::Matrix3d>& m_cs) const;
  /// ERR and t of each candidate (basis term indices) added alone to the batch fit `batch`.
  [[nodiscard]] std::vector<CandidateStat> structure(const std::vector<Eigen::Index>& candidates, const StatFit& batch,
                                                     const std::vector<const Information*>& infos,
                                                     const std::vector<Eigen::Matrix3d>& m_cs) const;

  [[nodiscard]] const std::vector<Eigen::Index>& model() const { return model_; }
  [[nodiscard]] const CornerGrid& grid() const { return grid_; }

 private:
  /// [Phi y]'[Phi y] of `terms` summed over the mountings, at `corner` (none: static squares);
  /// with `differences`, the successive differences' [dPhi dy]'[dPhi dy] instead.
  Eigen::MatrixXd gram(const std::vector<Eigen::Index>& terms, const std::vector<const Information*>& infos,
                       const std::vector<Eigen::Matrix3d>& m_cs, std::optional<double> corner, bool differences = false) const;
  /// The fit at the corner with the least residual (procedure::least_residual_corner over the
  /// grid's nodes, the static squares competing when allowed).
  template <class FitAt>
  StatFit best_corner(FitAt&& fit_at) const;
  /// The normal equations of `terms` from their Gram matrix `gram` over `weight` samples, with the
  /// output-multiplied terms' factor statistics.
  [[nodiscard]] ident::NormalEquations equations(const Eigen::MatrixXd& gram, double weight, const std::vector<Eigen::Index>& terms,
                                                 const std::vector<const Information*>& infos,
                                                 const std::vector<Eigen::Matrix3d>& m_cs) const;
  /// ULS on `gram` (over `terms`), leaving out what the data does not determine, by the rules of
  /// ident/normal_equations.hpp (the sensor's sensitivities ranked first and never left out).
  [[nodiscard]] StatFit fit(const Eigen::MatrixXd& gram, double weight, const std::vector<Eigen::Index>& terms,
                            const std::vector<const Information*>& infos, const std::vector<Eigen::Matrix3d>& m_cs) const;
  /// What ident::cluster_offsets reads of the cases' runs (add_case_scatter): the columns
  /// `transform(c, t_base, t_filtered)` gives case c, in the linear form of `sign`, with the
  /// residual of the coefficients `theta` (`sign.size()` columns).
  struct RunSums {
    Eigen::MatrixXd gram;   // [X y]'[X y], X in the linear form
    double weight = 0.0;
    ident::ClusterSums sums;
    Eigen::VectorXd output_sums;
    std::vector<std::pair<std::size_t, std::size_t>> origin;   // per cluster: its case and run
  };
  using CaseTransform = std::function<void(std::size_t, Eigen::MatrixXd&, Eigen::MatrixXd&)>;
  [[nodiscard]] RunSums run_sums(const std::vector<const Information*>& cases, const std::vector<Eigen::Matrix3d>& m_cs,
                                 double noise_gain, const Eigen::VectorXd& sign, const Eigen::VectorXd& theta,
                                 const CornerWeights& weights, const CaseTransform& transform) const;
  /// The fitted terms of `at` and, per turn parameter of mounting `m`, the fitted prediction's
  /// derivative by it (turn_derivative_gram), as rows of the transforms.
  void turn_derivative_transforms(const StatFit& at, std::span<const procedure::TurnParameter> parameters, std::size_t m,
                                  const Eigen::Matrix3d& m_cs, const CornerWeights& weights, double step,
                                  Eigen::MatrixXd& with_b, Eigen::MatrixXd& with_f) const;
  /// Factor statistics of output-multiplied terms among `terms` (p_b sums, unwhitened).
  void factor_statistics(const std::vector<Eigen::Index>& terms, const std::vector<const Information*>& infos,
                         const std::vector<Eigen::Matrix3d>& m_cs, std::vector<Eigen::Index>& positions,
                         Eigen::MatrixXd& factor_gram, Eigen::VectorXd& factor_sum) const;

  const LiveBasis& basis_;
  std::vector<Eigen::Index> model_, sensitivities_;
  dataset::SensorKind sensor_;
  CornerGrid grid_;
  bool static_option_ = true;
  SolverOptions options_;
  Eigen::Index bias_ = -1;
  std::vector<Eigen::Index> factor_of_;   // per basis term: its denominator factor's term index (-1: none)
};

using procedure::rotation_vector;

}  // namespace inertia::online
