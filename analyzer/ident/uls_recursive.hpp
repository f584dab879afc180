#pragma once
// Recursive ULS (notes §4.1-4.3): RLS with exponential forgetting and the exact running loss J,
// RELS noise lags built from a-posteriori residuals, and the exact recursive bias compensation
// for output-multiplied (rational denominator) terms through a q x q solve.
// Same model and sign convention as uls_batch.hpp: theta of an output-multiplied column is its
// denominator coefficient, b = 1 + sum theta_j p_b,j, and the regressor value passed in for such
// a column is c_j(k) = y(k) p_b,j(k), with p_b,j(k) passed separately as its factor.
//
// With forgetting = 1 and batch initialization, estimate() solves the same equation as
// uls_batch() on the same samples (test UlsRecursive.MatchesBatch*). With P0 = c I the prior adds
// P0^-1 = I / c to the scaled normal matrix (negligible once N >> 1/c).
#include "analyzer/ident/uls_batch.hpp"

#include <Eigen/Dense>

#include <string>
#include <vector>

namespace inertia::ident {

struct RecursiveUlsOptions {
  double forgetting = 1.0;          ///< lambda in (0, 1]; memory ~ 1/(1 - lambda) samples
  double initial_covariance = 1e6;  ///< P0 = initial_covariance * I on scaled regressors
  Index warmup = -1;                ///< samples before the compensation starts; -1: max(100, 10 p)
  /// Fixed-point steps (sigma^2 -> theta) per sample. Each is O(p^2 + q^3); from the previous
  /// sample's solution three steps leave an error far below the sample-to-sample change.
  int compensation_iterations = 3;
  double max_correction = 0.95;     ///< PD guard rho_max (notes §4.3 step 6)
  /// Covariance resetting (only with forgetting < 1): when trace(P) exceeds reset_trace, the
  /// estimator restarts with P = P0 and the current estimate as prior mean (all accumulators
  /// restart, so J, R, D, d stay consistent with P). Must exceed trace(P0); 0 disables.
  double reset_trace = 0.0;
  int noise_lags = 0;               ///< RELS: e[k-1] .. e[k-n_e] appended, a-posteriori residuals

  [[nodiscard]] bool is_valid(std::string* why) const;
};

struct RecursiveEstimate {
  Eigen::VectorXd theta;       ///< process terms, then noise terms (unscaled)
  Eigen::VectorXd std_dev;     ///< classical: sqrt(s^2 diag(P)); for rational terms this
                               ///< understates the spread (notes §6.1), use batch for t-tests
  double residual_variance = 0.0;  ///< s^2 = sum zeta^2 / (N_eff - p), N_eff = sum lambda^i
  double sigma2 = 0.0;             ///< ratio estimator sum zeta^2 / sum b^2
  double effective_samples = 0.0;
  Index samples = 0;
  bool compensating = false;       ///< past the warm-up with output-multiplied terms
};

class UlsRecursive {
 public:
  /// terms: process regressors per sample; output_multiplied: their positions (0..terms) that are
  /// output-multiplied columns; scale: RMS of each process column (empty: 1, or set by
  /// initialize()). All state is sized here; update() does not allocate.
  UlsRecursive(Index terms, std::vector<Index> output_multiplied, const RecursiveUlsOptions& options,
               Eigen::VectorXd scale = {});

  /// Batch initialization from a first block (n0 >= 10 p recommended): ULS/ELS on the block sets
  /// the scales, P = (Phi0'Phi0)^-1, the LS state, the accumulators and the residual history, so
  /// no prior remains. factors: n0 x q (p_b of each output-multiplied column). Allocates.
  void initialize(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                  const Eigen::Ref<const Eigen::MatrixXd>& factors);

  /// One sample: phi_row (terms), y, factors (q values, p_b of each output-multiplied column).
  /// Thread: the caller's. Real-time: no allocation, O(p^2 + q^3).
  void update(const Eigen::Ref<const Eigen::VectorXd>& phi_row, double y,
              const Eigen::Ref<const Eigen::VectorXd>& factors);

  /// The compensation iterated to convergence on the current state, then unscaled. Allocates.
  [[nodiscard]] RecursiveEstimate estimate() const;
  /// Per-sample estimate (scaled units divided out), as of the last update.
  [[nodiscard]] Eigen::VectorXd theta() const { return theta_.cwiseQuotient(scale_); }
  [[nodiscard]] Index samples() const { return count_; }
  [[nodiscard]] int resets() const { return resets_; }

 private:
  void reset_covariance();
  void compensate(int iterations, double tolerance);
  double zeta_energy();

  RecursiveUlsOptions options_;
  Index np_;           // process + noise terms
  Index terms_;        // process terms
  Index q_;
  std::vector<Index> den_;
  Eigen::VectorXd sign_, scale_;
  Eigen::MatrixXd p_, r_, d_mat_;  // P (RLS covariance), R = P^-1 (scaled), D
  Eigen::VectorXd theta_ls_, theta_, d_vec_, phi_, p_phi_, gain_, tmp_, history_;
  double j_ = 0.0, s11_ = 0.0, sigma2_ = 0.0;
  Index count_ = 0, warmup_ = 0;
  int resets_ = 0;
  // q x q workspace for the compensation (sized once; Eigen reuses the buffers).
  Eigen::MatrixXd pbb_, c_, a_, sym_;
  Eigen::VectorXd fb_, theta_b_, rhs_b_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
};

}  // namespace inertia::ident
