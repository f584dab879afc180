#pragma once
// Batch unified least squares (ULS) after Zhu & Billings: plain LS for polynomial terms, the sigma^2 bias correction
// (R - s^2 Psi) theta = r + s^2 psi for output-multiplied (rational denominator) terms, and
// extended least squares for MA noise lags. Works on plain Eigen matrices; term names only
// travel along as labels so that errors and results can name them.
//
// Model and sign convention. A column listed in OutputMultiplied holds
// c_j(k) = y(k) p_b,j(k). The model is
//     y(k) = a(k) / b(k) + e(k),   a(k) = sum_num theta_i phi_i(k),   b(k) = 1 + sum_den theta_j p_b,j(k)
// and is fitted in its linear form
//     y(k) = sum_num theta_i phi_i(k) - sum_den theta_j c_j(k) + zeta(k),   zeta(k) = b(k) e(k).
// theta_j of an output-multiplied column is therefore its denominator coefficient, with the sign
// it has in b: for a gyro y (1 + eps T) = S0 w the column "y*T" gets theta = eps.
// The normalising denominator term p_b,1 is the constant 1 (b = 1 + ...).
// The sigma^2 correction assumes the noise is additive on the output reading (y = a/b + e); if
// the implicit equation itself carries the noise (y b = a + v) the correction is not the right
// one (a modelling caution), and products of the output with *known* reference signals
// are ordinary polynomial terms that need no correction at all.
#include <Eigen/Dense>

#include <algorithm>
#include <cstddef>
#include <functional>
#include <optional>

#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace inertia::ident {

using Index = Eigen::Index;

/// Which columns of a regression matrix are output-multiplied (rational denominator) terms.
struct OutputMultiplied {
  std::vector<Index> columns;  ///< indices into the regression matrix, each at most once
  /// N x columns.size(): p_b,j(k), the factor the output multiplies. Empty: taken as
  /// c_j(k) / y(k), which needs y(k) != 0 at every sample (std::invalid_argument otherwise).
  Eigen::MatrixXd factors;
};

enum class CovarianceKind {
  Auto,       ///< Classical without output-multiplied columns, Sandwich with them.
  Classical,  ///< s^2 (Phi' Phi)^-1, s^2 = sum eps^2 / (N - p).
  Sandwich,   ///< M^-1 S M^-1, the sandwich (M = R - s^2 Psi); rational models.
};

struct UlsOptions {
  int noise_lags = 0;               ///< n_e: columns e[k-1] .. e[k-n_e] appended (ELS)
  int max_iterations = 50;          ///< sigma^2 fixed-point iterations
  int max_noise_iterations = 100;   ///< ELS outer iterations (residuals rebuilt each time)
  double tolerance = 1e-8;          ///< relative change of theta and sigma^2 that ends an iteration
  /// PD guard: sigma^2 lambda_max([R^-1]_bb D) is clamped to this, so the
  /// corrected matrix R - sigma^2 Psi keeps at least (1 - max_correction) of R in every direction.
  double max_correction = 0.95;
  /// Identifiability threshold on the RMS-scaled Gram matrix R_s = S^-1 Phi'Phi S^-1 / N, whose
  /// diagonal is 1: when lambda_min / lambda_max < min_rcond (i.e. cond(Phi_s) > 1e5 by default)
  /// the term set cannot be estimated to better than ~6 digits and IdentifiabilityError is thrown.
  double min_rcond = 1e-10;
  /// A column is named in a near-dependence when |v_j| >= null_vector_share * max|v| for the
  /// null-space eigenvector v of R_s (in scaled units, so shares compare like with like).
  double null_vector_share = 0.1;
  CovarianceKind covariance = CovarianceKind::Auto;

  [[nodiscard]] bool is_valid(std::string* why) const;
};

/// Thrown when the columns of a fit are (nearly) linearly dependent; names the columns.
/// Example: a_i^2, a_p^2, a_o^2 and the bias on rotation-table data (a_i^2 + a_p^2 + a_o^2 = g^2).
class IdentifiabilityError : public std::runtime_error {
 public:
  IdentifiabilityError(const std::string& message, std::vector<std::string> labels, double rcond)
      : std::runtime_error(message), labels_(std::move(labels)), rcond_(rcond) {}
  [[nodiscard]] const std::vector<std::string>& labels() const noexcept { return labels_; }
  [[nodiscard]] double rcond() const noexcept { return rcond_; }

 private:
  std::vector<std::string> labels_;
  double rcond_;
};

/// The column a near-dependence takes out of a fit: of `labels` (the fit's columns in the order
/// they were ranked: forced first, then by ERR), the last one the error names that `kept` (an
/// index into `labels`) does not protect; none when it names protected columns only. The batch,
/// the live solver and diagnose leave columns by this one rule, refit, and name what left.
[[nodiscard]] std::optional<std::size_t> column_to_leave(const IdentifiabilityError& e, const std::vector<std::string>& labels,
                                                         const std::function<bool(std::size_t)>& kept);

struct UlsResult {
  std::vector<std::string> labels;  ///< process labels, then "e[k-1]" .. "e[k-n_e]"
  Index process_terms = 0;          ///< the first process_terms entries are the process parameters;
                                    ///< simulate with those only (noise terms set to zero)
  Eigen::VectorXd theta;
  Eigen::MatrixXd covariance;
  Eigen::VectorXd std_dev;
  /// eps(k) = y(k) - (a(k) + noise terms) / b(k): one-step-ahead residual, the quantity the
  /// model predicts; for b == 1 the usual LS residual.
  Eigen::VectorXd residuals;
  double sigma2 = 0.0;             ///< noise variance of the ULS ratio estimator sum zeta^2 / sum b^2
  double residual_variance = 0.0;  ///< sum eps^2 / (N - p), p counting noise terms too
  int iterations = 0;              ///< sigma^2 iterations, summed over ELS passes
  int noise_iterations = 0;        ///< ELS passes (0 without noise lags)
  /// |theta - theta of the pass before| / |theta| after the last ELS pass: what the coefficients
  /// still moved by when the passes stopped (converged: below UlsOptions::tolerance).
  double noise_last_change = 0.0;
  bool converged = false;
  double condition_number = 0.0;   ///< lambda_max / lambda_min of the RMS-scaled Phi'Phi
  CovarianceKind covariance_kind = CovarianceKind::Classical;

  [[nodiscard]] Eigen::VectorXd process_theta() const { return theta.head(process_terms); }
  /// The process terms' labels (the noise lags' left out): ident::parse_terms makes them terms.
  [[nodiscard]] std::vector<std::string> process_labels() const {
    return {labels.begin(), labels.begin() + std::min<std::ptrdiff_t>(process_terms, static_cast<std::ptrdiff_t>(labels.size()))};
  }
};

/// The sign each column takes in ULS's linear form: -1 for an output-multiplied column (its
/// coefficient multiplies the output, which moves to the regression's side), +1 otherwise. A
/// prediction from the coefficients, a case offset read against them, reads the columns so.
[[nodiscard]] Eigen::VectorXd linear_form_signs(Index columns, std::span<const Index> output_multiplied_columns);

/// Sufficient statistics of the linear form in RMS-scaled units.
/// Column j of the linear form is phi_lin,j = sign_j * phi_j (sign -1 for output-multiplied
/// columns), scaled: phi_s,j = phi_lin,j / scale_j. Built in one O(N p^2) pass; every subset fit
/// afterwards costs O(p^3) and no data pass, so trying many candidate models reuses one object.
struct UlsStatistics {
  Index samples = 0;
  Eigen::VectorXd scale;           ///< RMS of each column (0 for an all-zero column)
  Eigen::MatrixXd gram;            ///< R_s = Phi_s' Phi_s
  Eigen::VectorXd cross;           ///< r_s = Phi_s' y
  double yy = 0.0;                 ///< y'y
  std::vector<Index> denominator;  ///< positions (in 0..p) of output-multiplied columns, ascending
  Eigen::MatrixXd den_gram;        ///< D_s = sum p_b,s p_b,s'  (q x q), p_b,s = p_b / scale
  Eigen::VectorXd den_sum;         ///< d_s = sum p_b,s
  double s11 = 0.0;                ///< sum p_b,1^2 = N

  /// Statistics of all columns of phi. factors: N x q, p_b for each output-multiplied column in
  /// the order of `columns` (see denominator_factors()).
  static UlsStatistics from_data(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                 const Eigen::Ref<const Eigen::VectorXd>& y,
                                 std::span<const Index> output_multiplied_columns,
                                 const Eigen::Ref<const Eigen::MatrixXd>& factors);
  /// The same statistics from accumulated products instead of data (the live estimator keeps
  /// them, analyzer/online): `augmented` = [Phi y]'[Phi y] ((p+1) x (p+1), y last, as ErrGram
  /// holds it) over `samples` rows; for output-multiplied columns `factor_gram` = sum p_b p_b'
  /// (q x q) and `factor_sum` = sum p_b, in the order of `output_multiplied_columns`.
  static UlsStatistics from_gram(const Eigen::Ref<const Eigen::MatrixXd>& augmented, Index samples,
                                 std::span<const Index> output_multiplied_columns = {},
                                 const Eigen::Ref<const Eigen::MatrixXd>& factor_gram = Eigen::MatrixXd(),
                                 const Eigen::Ref<const Eigen::VectorXd>& factor_sum = Eigen::VectorXd());
  /// The statistics of a subset of the columns (positions into this object), O(p^2).
  [[nodiscard]] UlsStatistics subset(std::span<const Index> positions) const;
  [[nodiscard]] Index terms() const { return gram.rows(); }
};

/// The result of a ULS solve on statistics alone (no residuals, no covariance).
struct UlsSolution {
  Eigen::VectorXd theta;           ///< unscaled
  Eigen::MatrixXd gram_inverse;    ///< (Phi'Phi)^-1, unscaled: classical covariance / s^2
  Eigen::MatrixXd corrected_inverse;  ///< (Phi'Phi - sigma^2 Psi)^-1, unscaled (sandwich)
  double sigma2 = 0.0;
  /// sum zeta^2 at theta from the statistics (yy - 2 theta'r + theta'R theta). Cancellation costs
  /// log10(y'y / sum zeta^2) digits (1e10 for 1 g against 1e-4 noise leaves 6): enough for t-tests,
  /// not for AIC, which finish_uls computes from the residuals themselves.
  double zeta_energy = 0.0;
  double condition_number = 0.0;
  int iterations = 0;
  bool converged = false;
};

/// ULS on statistics: identifiability check, LS start, ratio sigma^2
/// estimator, PD guard, corrected solve, iterate. labels[j] names column j of `stats` in errors.
/// Throws IdentifiabilityError (names the dependent columns) or std::runtime_error when the
/// corrected matrix is not positive definite.
UlsSolution solve_uls(const UlsStatistics& stats, const std::vector<std::string>& labels,
                      const UlsOptions& options);

/// p_b,j(k) for each output-multiplied column: rational.factors when given (checked for size),
/// else c_j(k) / y(k). Throws std::invalid_argument naming the column and sample when y(k) == 0.
Eigen::MatrixXd denominator_factors(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                    const Eigen::Ref<const Eigen::VectorXd>& y,
                                    const OutputMultiplied& rational,
                                    const std::vector<std::string>& labels);

/// Full batch ULS on the columns `columns` of phi (all columns when empty): ULS with ELS
/// noise lags, residuals and covariance. labels has one entry per column of phi.
/// Not real-time: allocates O(N) for residuals; one O(N p^2) Gram, then O(N p n_e) per ELS pass.
UlsResult uls_batch(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                    const Eigen::Ref<const Eigen::VectorXd>& y,
                    const std::vector<std::string>& labels, const OutputMultiplied& rational,
                    const UlsOptions& options, std::span<const Index> columns = {});

/// uls_batch's theta alone: without noise lags, from the statistics (no residuals, no covariance:
/// no O(N) buffers beyond what the statistics need), the same numbers; with noise lags, the ELS
/// fit's (the passes need the residuals).
Eigen::VectorXd uls_coefficients(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                                 const std::vector<std::string>& labels, const OutputMultiplied& rational,
                                 const UlsOptions& options, std::span<const Index> columns = {});

/// What a solution from solve_uls() fixes of a UlsResult over `columns` (positions into `labels`,
/// in solution order): the labels, theta, sigma^2, the iterations and the condition number. The
/// residuals and the covariance are the caller's: from the rows (finish_uls) or the statistics.
UlsResult solved_terms(const UlsSolution& solution, const std::vector<std::string>& labels, std::span<const Index> columns);

/// Residuals, covariance and the rest of a UlsResult for a model without noise lags whose
/// solution came from solve_uls() on statistics: one O(N p) pass (O(N p^2) for the sandwich).
/// columns: the columns of phi in the fit, in solution order; factors from denominator_factors().
UlsResult finish_uls(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                     const Eigen::Ref<const Eigen::VectorXd>& y,
                     const std::vector<std::string>& labels, std::span<const Index> columns,
                     const OutputMultiplied& rational, const Eigen::Ref<const Eigen::MatrixXd>& factors,
                     const UlsSolution& solution, const UlsOptions& options);

}  // namespace inertia::ident
