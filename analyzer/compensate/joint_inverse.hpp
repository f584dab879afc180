#pragma once
// Several outputs' models read backwards together. Each equation is one output's model
// (InverseModel, its compiled form), and some of its inputs are unknowns of the joint solve, each
// a linear combination of them: a unit's accelerometer along x reads (a_i, a_p, a_o) = M x, with x
// the specific force in the unit's frame and M its sensor frame seen from the unit's. Per sample,
// Newton's method on the D equations
//
//   g_m(x) = sum_a c_a term_a(x) - y_m(k) (1 + sum_b c_b p_b(x)) = 0,   m = 1..D,
//
// from the previous sample's estimate, then from the fallback starts. One output with its sensed
// input as the only unknown (D = 1) is InverseModel::compensate; a triad is D = 3, a unit's two
// triads D = 6 (the gyroscopes' g-sensitivity then reads the solved specific force).
//
// The dynamics, the squares' high pass and the range checks are InverseModel's (inverse_model.hpp),
// with each solved input read through its row: lagged solved inputs are the estimates already
// made, and before the first estimate the current x. Where every term is linear in the unknowns
// (each has at most one solved factor, plain and of power 1), g(x) = A x + b: one evaluation of
// A and b, and the root is x = -A^-1 b; where A is also the same at every sample (no term that
// varies from sample to sample reads a solved input, no square through the high pass), the
// samples are independent and solved a block at a time. Otherwise Newton stops by newton_converged
// (inverse_model.hpp): a step within the tolerance, or a next step predicted within it. At the
// root the terms' values are the last evaluation's moved along their slopes by the last step, and
// the Jacobian is the last one's: no evaluation after the step that converged.
//
// Uncertainty at the root, J the D x D Jacobian dg/dx, equations independent:
//   from the coefficients   cov_c = sum_m (a_m' C_m a_m) J^-1 e_m e_m' J^-T,  a_m = dg_m/dc_m;
//   from the output's noise cov_n = sum_m (s_m d_m)^2 J^-1 e_m e_m' J^-T,    d_m = 1 + sum_b c_b p_b,
// s_m the output's noise sd. Each unknown's standard uncertainty is the root of its diagonal.
#include <Eigen/Dense>

#include <utility>
#include <vector>

#include "analyzer/compensate/inverse_model.hpp"

namespace inertia::compensate {

/// One output's model in the joint solve: its inputs solved for, each a row over the unknowns.
/// The model's other inputs are known: read from the equation's record.
struct JointEquation {
  const InverseModel* model = nullptr;
  std::vector<std::pair<ident::Variable, Eigen::RowVectorXd>> solved;
};

struct JointCompensation {
  Eigen::Index first_row = 0;      // sample index of row 0 (the models' largest lag)
  Eigen::MatrixXd value;           // rows x unknowns, SI; NaN rows where not converged
  Eigen::MatrixXd u_coefficients;  // standard uncertainty from the coefficients' covariances
  Eigen::MatrixXd u_noise;         // standard uncertainty from the outputs' noise
  std::vector<SampleFlag> flag;
  Eigen::Index outside_range = 0, not_converged = 0;
  int most_iterations = 0;         // the most Newton steps any sample took, over all its starts
};

class JointInverse {
 public:
  /// As many equations as unknowns (1, 3 or 6); every fallback start has one value per unknown.
  /// Throws std::invalid_argument otherwise, or for a solved row of another length, or an
  /// equation that solves for no input it reads at the current sample.
  JointInverse(std::vector<JointEquation> equations, std::vector<Eigen::VectorXd> fallback_starts);

  [[nodiscard]] Eigen::Index unknowns() const { return unknowns_; }
  [[nodiscard]] Eigen::Index first_row() const { return first_row_; }
  [[nodiscard]] const std::vector<JointEquation>& equations() const { return equations_; }
  [[nodiscard]] const std::vector<Eigen::VectorXd>& fallback_starts() const { return fallback_starts_; }
  [[nodiscard]] double tolerance_scale() const { return tolerance_scale_; }
  /// Every term linear in the unknowns: Newton's first step is the root.
  [[nodiscard]] bool linear() const { return linear_; }

  /// `records[m]` holds equation m's output y and its known inputs; all of one length. Throws
  /// InputError for a missing input or records of different lengths, std::invalid_argument for a
  /// square high pass without a positive sample period.
  [[nodiscard]] JointCompensation compensate(const std::vector<const ident::SignalSet*>& records, double sample_period_s,
                                             const CompensationOptions& options = {}) const;

 private:
  template <int D>
  void solve(const std::vector<const ident::SignalSet*>& records, double sample_period_s, const CompensationOptions& options,
             JointCompensation& out) const;

  std::vector<JointEquation> equations_;
  std::vector<Eigen::VectorXd> fallback_starts_;
  Eigen::Index unknowns_ = 0;
  Eigen::Index first_row_ = 0;
  bool linear_ = true;   // every term is linear in the unknowns: Newton's first step is the root
  double tolerance_scale_ = 1.0;   // Newton stops when every step is at most kStepTolerance (|x| + this)
};

}  // namespace inertia::compensate
