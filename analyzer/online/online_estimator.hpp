#pragma once
// The live half of the analyzer (design.md: "`online` subscribes, fuses the references into ground
// truth and runs the recursive ULS per sensor under test, publishing estimates"): one estimator per
// sensor under test, fed with fused chunks of consecutive samples as they arrive, answering at any
// time with the coefficients, their standard deviations and the misalignment they imply.
//
// Model: the terms of a model file (a characterization's model.toml), else the paper's complete
// static model (eq. 4 with r = 0: bias, scale factor, squares and cross-couplings; gyros: bias,
// scale factor and g-sensitivity). Two linear cross-axis terms (a_p, a_o for accelerometers, w_p,
// w_o for gyros) are always estimated beside them: their ratio to the scale factor is the small
// rotation of the sensitive axis from the model's M_C^S, i.e. the live misalignment (about p and
// o; the rotation about the sensitive axis itself does not change a single-axis output and is
// reported as 0).
//
// The recursive ULS starts from the prior P0 = c I on columns scaled by their RMS over the first
// chunk (not from a batch initialization): the first samples of a test are usually a dwell, where
// the squares and the bias are collinear, and the prior keeps the estimator defined until the
// motion separates them. Without the scaling, columns of 1 and (30 m/s^2)^2 under one P0 lose
// digits in the first updates that an unforgetting RLS never recovers. With forgetting = 1 the
// estimate is the batch least-squares answer on the same samples up to the prior's weight 1/c.
#include <Eigen/Dense>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/ident/uls_recursive.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::online {

struct OnlineOptions {
  ident::RecursiveUlsOptions uls;   ///< forgetting factor, P0, ...
  /// Convergence: the samples that arrived since the previous snapshot moved every coefficient by
  /// less than this many of its own standard deviations, and at least min_samples_per_term *
  /// terms samples were used. A snapshot with no new samples keeps the previous verdict.
  double converged_sigmas = 2.0;
  int min_samples_per_term = 100;
};

/// The live answer for one sensor (what model_estimate_t carries).
struct OnlineSnapshot {
  std::vector<std::string> terms;            // canonical names, in estimation order
  Eigen::VectorXd values, std_devs;
  double residual_variance = 0.0;
  Eigen::Vector3d misalignment_rad = Eigen::Vector3d::Zero();   // about i, p, o of F_S
  std::int64_t samples_used = 0;
  bool converged = false;
};

class OnlineEstimator {
 public:
  /// `model`: terms, m_cs and the square high pass of a prior characterization; nullopt: the
  /// default model of `sensor`. Throws InputError when a term needs a variable the live stream
  /// cannot provide (lagged terms are accepted; e lags are not: the live estimator has no
  /// residual history across gaps).
  OnlineEstimator(dataset::SensorKind sensor, const std::optional<model::ModelFile>& model, double t_ref,
                  const OnlineOptions& options);

  /// The default term list of a sensor kind (without the two cross-axis terms).
  static std::vector<ident::Term> default_terms(dataset::SensorKind sensor);

  /// Feeds consecutive samples of one case: `chunk.a_e` (and w_e, temp when the model needs
  /// them), `chunk.y`, `chunk.m_ec`, `chunk.sample_period_s`. `continues_previous` = the first
  /// sample directly follows the last one fed (same case, no gap); otherwise lagged terms and the
  /// high-pass state restart, and the first max-lag samples only fill the history.
  /// Throws InputError when a column the terms need is missing.
  void push(const dataset::CaseData& chunk, bool continues_previous);

  /// The current estimate. Allocates; call at the publishing rate, not per sample.
  [[nodiscard]] OnlineSnapshot snapshot();

  [[nodiscard]] const std::vector<ident::Term>& terms() const { return terms_; }

 private:
  dataset::SensorKind sensor_;
  double t_ref_;
  OnlineOptions options_;
  frames::Dcm m_cs_;
  std::optional<double> square_highpass_rad_s_;
  std::vector<ident::Term> terms_;
  Eigen::Index scale_term_ = -1, cross_p_ = -1, cross_o_ = -1;   // positions in terms_
  Eigen::Index max_lag_ = 0;
  std::vector<Eigen::Index> output_multiplied_;
  std::optional<ident::UlsRecursive> uls_;   // created on the first rows, scaled by their column RMS
  dataset::CaseData history_;       // the last max_lag_ samples, for lagged terms across chunks
  bool has_history_ = false;
  Eigen::VectorXd highpass_state_;  // per square term: previous input and output (2 per term)
  Eigen::VectorXd factors_;         // p_b of each output-multiplied column, per sample
  std::optional<Eigen::VectorXd> previous_values_;   // at the previous snapshot with new samples
  std::int64_t previous_samples_ = 0;
  bool converged_ = false;
};

}  // namespace inertia::online
