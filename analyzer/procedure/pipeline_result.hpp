#pragma once
// What the characterization procedure finds: per mounting (blocks 5-6) and for the batch model
// (blocks 7-11). The stages of pipeline.hpp fill it; the report and the model file read it.
#include <Eigen/Dense>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/ident/statistics.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "common/frames.hpp"

namespace inertia::procedure {

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
  double known_bias_sd = 0.0;               // its sd (in the angles' sd)
  /// The sd of this mounting's bias (its selected model's honest inference), which a mounting that
  /// takes the bias (mounting_rules.hpp) receives with it. None: the model has no bias.
  std::optional<double> bias_sd;
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
  /// The part of angles_sd a held twist's tolerance adds (relative_twists.hpp): a
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
  /// Whether the batch's rows went through `whitening` (filters_rows). If not (ULS's
  /// output-multiplied terms), fit.residuals are unfiltered and the innovation is `whitening`
  /// applied to them (batch_innovation).
  bool rows_filtered = true;
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

}  // namespace inertia::procedure
