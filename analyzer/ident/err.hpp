#pragma once
// Error reduction ratio (paper equation 8) and forward orthogonal ranking (FROLS),
// computed on the Gram matrix G = [Phi Y]'[Phi Y] instead of the data:
//   ERR_j = (q_j'Y)^2 / (q_j'q_j  Y'Y) = G(j,Y)^2 / (G(j,j) G(Y,Y))   after orthogonalization,
// and orthogonalizing against a selected column m is the Schur complement
//   G <- G - G(:,m) G(m,:) / G(m,m),
// which is modified Gram-Schmidt carried out on inner products (Zhu & Billings 1996 idea).
// One O(N p^2) pass builds G; ranking is O(p^2 k) for k terms and touches no data, so the memory of a ranking
// or of any number of re-rankings (other forced sets, other sigma^2 corrections) is the (p+1)^2
// Gram matrix, independent of N and of how many candidate models are tried.
// Hazard: working on G squares the condition number; the dependence guard below (relative
// residual energy < 1e-10, i.e. an angle below ~1e-5 rad to the selected span) keeps the ranking
// away from that regime. Parameters are never taken from the ranking: refit with ULS.
#include <Eigen/Dense>

#include <span>
#include <string>
#include <vector>

namespace inertia::ident {

/// (p+1) x (p+1) Gram matrix of [Phi Y]; Y is the last row/column. Accumulates in row blocks so
/// data of any length can stream through it (memory O(p^2)).
class ErrGram {
 public:
  explicit ErrGram(Eigen::Index terms);
  /// Adds rows: phi_block is rows x terms, y_block rows. Not real-time (blocked SYRK).
  void add(const Eigen::Ref<const Eigen::MatrixXd>& phi_block,
           const Eigen::Ref<const Eigen::VectorXd>& y_block);
  static ErrGram from_data(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                           const Eigen::Ref<const Eigen::VectorXd>& y);
  [[nodiscard]] Eigen::Index terms() const { return gram_.rows() - 1; }
  [[nodiscard]] Eigen::Index samples() const { return samples_; }
  [[nodiscard]] const Eigen::MatrixXd& matrix() const { return gram_; }
  [[nodiscard]] Eigen::MatrixXd& matrix() { return gram_; }

 private:
  Eigen::MatrixXd gram_;
  Eigen::Index samples_ = 0;
};

enum class ErrReference {
  Total,        ///< equation 8 as printed: ERR relative to Y'Y (uncentered)
  AfterForced,  ///< relative to the energy left after the forced terms; forcing the bias gives
                ///< ERR relative to the centered sum of squares sum (y - mean)^2, which keeps a large
                ///< DC level (1 g on an accelerometer axis) from making every other ERR look tiny
};

struct ErrOptions {
  std::vector<Eigen::Index> forced;  ///< selected first, in this order (e.g. the bias column)
  ErrReference reference = ErrReference::Total;
  /// A candidate whose energy orthogonal to the selected ones falls below this fraction of its
  /// own energy is dependent: never selected, listed in ErrRanking::dependent.
  double dependence_tolerance = 1e-10;
  Eigen::Index max_terms = -1;  ///< stop after this many terms (-1: rank every candidate)
  /// Per candidate column, the column that takes its step when the two explain the output alike
  /// (-1: none; empty: no column has one): when j ranks best and preferred[j] is still a candidate
  /// whose explained energy G(k,Y)^2 / G(k,k), after the columns selected so far, falls short of
  /// j's by less than tie_energy. When preferred[j] is selected and j then explains less than
  /// tie_energy beyond the selection, j is dependent (what another column takes from it later
  /// does not count). rank_identifiable gives a lagged term its unlagged form.
  std::vector<Eigen::Index> preferred;
  double tie_energy = 0.0;
};

struct ErrRanking {
  std::vector<Eigen::Index> order;    ///< candidate columns, forced ones first, then by ERR
  Eigen::VectorXd err;                ///< ERR of order[i] at the step it was selected
  std::size_t forced_count = 0;       ///< order[0 .. forced_count) are the forced terms
  std::vector<Eigen::Index> dependent;  ///< candidates rejected by the dependence guard
  double reference_energy = 0.0;      ///< the denominator of ERR (Y'Y, or what forced terms left)
  /// 1 - sum ERR over the terms measured against reference_energy (all terms for Total, the
  /// non-forced ones for AfterForced): the unexplained fraction.
  double unexplained = 1.0;
};

/// Forward orthogonal ranking on a Gram matrix (G = [Phi Y]'[Phi Y], possibly bias-corrected).
/// Candidates with non-positive diagonal (possible after a bias correction) count as dependent.
ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& gram, const ErrOptions& options);
/// The same ranking on data. With options.max_terms small against p (FROLS with a fixed model
/// length) it forms only the Gram columns of the selected terms, one pass over phi each, instead
/// of the whole Gram matrix: O(N p k) rather than O(N p^2).
ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                    const Eigen::Ref<const Eigen::VectorXd>& y, const ErrOptions& options);

/// Bias-corrected Gram matrix for output-multiplied candidates. Column c listed in
/// `output_multiplied` holds y(k) p_b(k) as given (not negated); `factors` holds p_b (N x q, same
/// order). With y = y0 + e the inner products are inflated by the noise:
///   (c_i, c_j) -= sigma2 sum p_i p_j,  (c_i, Y) -= sigma2 sum p_i,  (Y, Y) -= sigma2 N,
/// numerator/numerator and numerator/denominator entries need no correction. sigma2 comes from a
/// preliminary ULS fit. The corrected matrix need not be positive semi-definite, so cumulative
/// ERR may exceed 1; confirm the structure with ULS and t-tests.
Eigen::MatrixXd bias_corrected_gram(const Eigen::Ref<const Eigen::MatrixXd>& gram,
                                    std::span<const Eigen::Index> output_multiplied,
                                    const Eigen::Ref<const Eigen::MatrixXd>& factors, double sigma2);

}  // namespace inertia::ident
