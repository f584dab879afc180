#pragma once
// The live half of the analyzer (docs/design.md: "`online` subscribes, fuses the references into ground
// truth and runs the recursive ULS per sensor under test, publishing estimates"): one estimator
// per sensor under test, fed the fused rows as the stream assembler makes them final, answering
// at any time with the same answer the batch procedure gives on the same rows.
//
// Recursive least squares in information form: the estimator updates the sufficient statistics
// of the regression (information.hpp) with every row, per segment, case and mounting, in a basis
// of case-frame monomials (live_basis.hpp) from which the statistics of the model for any
// mounting misalignment follow exactly. At each snapshot it runs the procedure on them
// (live_solver.hpp): algorithm 1 per mounting to its fixed point, the batch model over all
// mountings, the squares' corner, the ULS bias correction of output-multiplied terms. The cost of
// a row is O(b^2) for b basis columns (plus the noise filter), the cost of a snapshot does not
// depend on the number of rows.
//
// Model: the terms of a model file (a characterization's model.toml, with its squares' corner),
// else the paper's complete static model (eq. 4 with r = 0: bias, scale factor, squares and
// cross-couplings; gyros: bias, scale factor and g-sensitivity), with the squares' corner searched
// on a log grid of corners as the batch pipeline searches it. The two cross-axis terms (a_p, a_o;
// w_p, w_o) are left to the misalignment: each mounting's own M_C^S takes them.
//
// Noise: the first noise_window_s of rows are kept; then an autoregressive noise model is fitted
// to the residuals of the fit on them (AIC order up to whitening_max_order, as the batch) and
// every row from the first one on enters the statistics through it (GLS, honest sd under 1/f
// noise). A stream that ends before its window fills (end_of_stream) has the model fitted on every
// row it brought, so a window at least as long as a record fits the noise on the whole record, as
// the batch does. Models with output-multiplied terms keep white noise (the ULS correction is derived for
// white noise on the output).
//
// Converged: defined in docs/live-estimates.md ("Converged"); see OnlineSnapshot::converged.
#include <Eigen/Dense>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/fusion/stream_assembler.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/online/information.hpp"
#include "analyzer/online/live_basis.hpp"
#include "analyzer/online/live_solver.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::online {

struct OnlineOptions {
  int unit_axis = -1;                 ///< the sensor's axis in its [[unit]] (config::nominal_m_ec); -1: none
  double forgetting = 1.0;            ///< lambda in (0, 1]: every row's weight decays by lambda per row
  double noise_window_s = 2.0;        ///< rows that fit the noise model (s of sensor samples)
  int whitening_max_order = 120;      ///< largest AR order of the noise model (0: white)
  /// An open segment counts once it is this long, and `online`'s assembler drops shorter ones
  /// (the offline default: a piece of a case cut by lost samples).
  double min_segment_s = fusion::AssemblerOptions{}.min_segment_s;
  /// Convergence: family-wise level of the leave-one-out test (Bonferroni over the cases or phases
  /// left out and the terms).
  double convergence_alpha = 0.01;
  double convergence_interval_s = 1.0;   ///< stream time between two convergence tests
  bool structure_table = true;        ///< ERR and t of the candidate terms not in the model
  bool temperature_candidates = false;   ///< include T terms among the candidates (the bench has temperature)
  double nominal_sample_period_s = 0.0;  ///< the bench's; bounds the squares' corner grid below Nyquist
  /// The bench's test plan, for grouping its cases into mountings as the batch does
  /// (procedure::group_mountings: a tumble's unlabelled poses share one). Empty: each case is
  /// grouped on its own label as it arrives (a gyroscope's cases are one mounting either way).
  std::vector<procedure::MountingKey> plan;
  SolverOptions solver;
};

struct MountingEstimate {
  std::string name;
  std::vector<std::string> cases;
  bool determined = false;
  Eigen::Matrix3d m_cs = Eigen::Matrix3d::Identity();
  Eigen::Vector3d angles_rad = Eigen::Vector3d::Zero();     // rotation of F_S from the nominal case frame, about i, p, o
  Eigen::Vector3d angles_sd_rad = Eigen::Vector3d::Zero();  // i: NaN (a single axis does not see it)
  std::int64_t samples = 0;
  std::string note;
};

struct CandidateEstimate {
  std::string term;
  std::string effect;                 // physical name (docs/design.md)
  double err = 0.0, value = 0.0, sd = 0.0, t = 0.0;
  bool significant = false;
};

/// The live answer for one sensor (what model_estimate_t carries).
struct OnlineSnapshot {
  std::vector<std::string> terms;            // canonical names of the model's terms
  Eigen::VectorXd values, std_devs, t;       // NaN where the data does not determine the term yet
  std::vector<std::string> undetermined;     // those terms
  std::vector<std::string> plan_undetermined;   // of those, the ones this plan cannot determine (no mounting aligned)
  std::vector<std::string> confounded;   // of those, left out: constant within each phase, no phase to spare (placement)
  std::vector<std::string> insignificant;   // of those, left out of the default model: not significant (LiveEstimate)
  double residual_variance = 0.0;            // of the (whitened) residual
  std::vector<MountingEstimate> mountings;
  std::int64_t samples_used = 0;             // rows in the estimate
  std::int64_t cases_used = 0;
  /// Honest convergence (docs/live-estimates.md): every term determined, at least two cases, and leaving any one
  /// case out moves no coefficient by more than the noise allows (z of the nested difference below
  /// the Bonferroni bound at convergence_alpha).
  bool converged = false;
  std::string convergence;                   // why not, or the largest leave-one-out z
  int noise_order = 0;                       // AR order of the noise model (0: white or not yet fitted)
  bool noise_model_fitted = false;
  /// A white model's (output-multiplied terms) variance scale: the residual's long-run variance
  /// over its variance (procedure::unfiltered_long_run_ratio); 1 when whitened.
  double long_run_variance_factor = 1.0;
  std::optional<double> corner_rad_s;        // squares' high pass (none: static)
  std::vector<CandidateEstimate> structure;  // candidates not in the model, by ERR
};

class OnlineEstimator {
 public:
  /// `model`: terms, m_cs and squares' corner of a prior characterization; nullopt: the default
  /// model of `sensor`. Throws InputError when a term needs what the live stream cannot provide
  /// (e lags: the live estimator keeps no residual history).
  OnlineEstimator(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model, double t_ref,
                  const OnlineOptions& options);
  ~OnlineEstimator();
  OnlineEstimator(const OnlineEstimator&) = delete;
  OnlineEstimator& operator=(const OnlineEstimator&) = delete;

  /// The default term list of a sensor kind; `temperature` (a plan with thermal cases): with the
  /// bias's and the scale factor's temperature coefficients (T, a_i*T or w_i*T).
  static std::vector<ident::Term> default_terms(dataset::SensorKind sensor, bool temperature = false);

  /// Rows of one segment of test case `tc` (chunks of a segment arrive in order).
  void push(const fusion::FusedChunk& chunk, const config::TestCase& tc);
  /// The segment ended; not kept: its rows leave the estimate.
  void end_segment(const fusion::SegmentEnd& end);

  /// The stream ended (a replayed log's end): the noise model, if the window never filled, is
  /// fitted on the rows there are. Rows pushed after it enter through that model.
  void end_of_stream();

  /// The current estimate. Allocates; call at the publishing rate, not per row.
  [[nodiscard]] OnlineSnapshot snapshot();

  [[nodiscard]] std::vector<std::string> terms() const;
  [[nodiscard]] std::int64_t rows_pushed() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inertia::online
