#pragma once
// Significance tests and information criteria of the paper's section 2.7 (equations 9-11) and
// residual diagnostics. All functions are pure and thread-safe; none is real-time (they allocate).
#include <Eigen/Dense>
#include <limits>

#include <algorithm>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace inertia::ident {

/// Two-sided tail probability P(|T| >= |t|) of Student's t with `dof` degrees of freedom
/// (boost::math::students_t; dof may be fractional, e.g. an effective sample size).
double student_t_two_sided_p(double t, double dof);

/// The multiplier of an sd for a two-sided interval of `level` (0.95: t_{0.975}) with Student's t
/// on `dof` degrees of freedom; the normal's for infinite dof.
double student_t_interval_factor(double level, double dof);

struct ParameterTTest {
  Eigen::VectorXd t;        ///< theta_j / sd_j (equation 11)
  Eigen::VectorXd p_value;  ///< two-sided, Student's t with dof degrees of freedom
  double dof = 0.0;         ///< N - p - 1, as equation 11 states (one less than the usual N - p:
                            ///< slightly conservative, immaterial for N >> p)
};
/// Equation 11 for every parameter. An sd of 0 gives t = +-inf and p = 0 (or p = 1 for theta 0).
ParameterTTest parameter_t_test(const Eigen::Ref<const Eigen::VectorXd>& theta,
                                const Eigen::Ref<const Eigen::VectorXd>& std_dev,
                                Eigen::Index samples);

/// Which term leaves a model, by the rule algorithm 2's step 9, the post-selection inference and
/// the live estimate share: of the terms whose p-value exceeds `threshold`, the one with the
/// largest; none when every term passes. One at a time, refitting in between: correlated terms
/// share their variance, and removing both members of a pair at once can remove a real effect.
/// A NaN p-value marks a term that never leaves (a sensitivity, the bias, a term the test does not
/// weigh).
[[nodiscard]] std::optional<std::size_t> term_to_prune(std::span<const double> p_values, double threshold);

/// Equation 9: AIC = N ln(sigma_e^2) + 2 p with sigma_e^2 = sum e^2 / N, the maximum-likelihood
/// variance the criterion is derived from (the mean is not removed: a residual offset is a model
/// defect and must cost). Compare only models fitted to the same N samples.
double aic(const Eigen::Ref<const Eigen::VectorXd>& residuals, Eigen::Index parameters);
double aic_from_variance(double sigma2_ml, Eigen::Index samples, Eigen::Index parameters);

/// Equation 10: p_AIC,m = exp((AIC_min - AIC_m) / 2) (1 for the best model). NaN entries
/// (models that failed) stay NaN and are ignored for the minimum.
Eigen::VectorXd relative_likelihood(const Eigen::Ref<const Eigen::VectorXd>& aic_values);

struct ResidualMeanTest {
  double mean = 0.0;
  double std_error = 0.0;            ///< s / sqrt(N_eff)
  double t = 0.0;
  double p_value = 1.0;              ///< p_res: two-sided, Student's t with N_eff - 1 dof
  double lag1_autocorrelation = 0.0;
  double effective_samples = 0.0;    ///< N_eff
};
/// p_res of section 2.7: t-test of "residual mean = 0". With effective_size (default) N is
/// replaced by N_eff = N (1 - r1) / (1 + r1), r1 the lag-1 autocorrelation, clamped to [2, N].
/// Why: model residuals of dynamic sensors are autocorrelated, and the variance of the mean of an
/// AR(1) series is s^2 (1 + r1) / (N (1 - r1)) for large N; the naive s^2 / N makes the test reject
/// a zero-mean AR(1) with r1 = 0.9 about 65% of the time instead of 5% (test
/// Statistics.ResidualMeanTestFalseAlarmRate). We prefer this one-parameter form to a Newey-West long-run
/// variance because it needs no bandwidth choice and is exact for the AR(1) residuals that
/// dominate in practice; N_eff never exceeds N (negative r1 would claim more information than
/// the samples hold; clamping keeps the test conservative).
/// r1 comes from the successive differences (von Neumann's ratio): r1 = 1 - (D / P) / (2 SS / N),
/// D the sum of squared differences of neighbouring residuals within a stretch of contiguous rows,
/// P the number of such pairs, SS the energy about the mean. Differences are what sums give: the
/// normal equations of the successively differenced rows hold D for any coefficients, so the live
/// estimator, which keeps no rows, tests by the same numbers (select_model on NormalEquations).
/// `stretch_starts`: the first row of each stretch after the first (the stacked cases; empty: one
/// stretch). A pair across stretches would pair the end of one case with the start of another.
ResidualMeanTest residual_mean_test(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                    std::span<const Eigen::Index> stretch_starts = {}, bool effective_size = true);
/// The same test from the residual's sums: mean, energy about the mean (SS) over `samples` rows,
/// and the successive differences' energy D over `pairs` pairs (pairs 0: r1 is not known, N_eff = N).
ResidualMeanTest residual_mean_test(double mean, double centred_energy, Eigen::Index samples,
                                    double difference_energy, Eigen::Index pairs);
/// The test from the residual's mean, variance (about the mean, N - 1 divisor) and effective
/// sample count.
ResidualMeanTest residual_mean_test(double mean, double variance, double effective_samples);
/// Calls f(begin, end) for each stretch [begin, end) of the rows [0, n) that `stretch_starts` (the
/// first row of each stretch after the first, ascending) cut. Throws std::invalid_argument when
/// they are not ascending within [0, n].
template <class F>
void for_each_stretch(Eigen::Index n, std::span<const Eigen::Index> stretch_starts, F&& f) {
  Eigen::Index begin = 0;
  for (const Eigen::Index start : stretch_starts) {
    if (start < begin || start > n) throw std::invalid_argument("stretch starts out of order or beyond the rows");
    f(begin, start);
    begin = start;
  }
  f(begin, n);
}
/// D of `residuals`: the squared differences of neighbours within each stretch (as above), and
/// their number.
struct SuccessiveDifferences {
  double energy = 0.0;
  Eigen::Index pairs = 0;
};
[[nodiscard]] SuccessiveDifferences successive_differences(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                                           std::span<const Eigen::Index> stretch_starts = {});

/// Offsets between clusters that the noise model does not explain, and what they do to a
/// least-squares estimate (a variance-components model: y = X theta + u_g + e, u_g ~ N(0, tau^2)
/// one per cluster, e white with variance sigma^2).
/// Why: a bench's cases and phases are not exchangeable samples: a tumble's pose carries its
/// placement error, a slow drift or 1/f noise below an AR model's reach shifts a whole phase, and
/// the classical covariance takes every sample as independent information, so a term that only
/// moves between clusters (a square that is constant within each static pose) looks determined
/// by thousands of samples when it is determined by a handful of cluster means. Here such terms
/// are tested against the scatter of the cluster means, on their degrees of freedom, as a
/// lack-of-fit test against replicates does.
///   r = rank of the cluster-mean design (G x p), dof = G - r between-cluster degrees of freedom;
///   tau_g^2 = tau_0^2 + tau_1^2 q_g: an offset common to all clusters plus one that grows with
///   the cluster's `loading` q_g (mean over its rows; a pose's placement tilt moves the output in
///   proportion to the specific force across the input axis, so q = a_p^2 + a_o^2 there);
///   tau_0, tau_1 by non-negative least squares (method of moments) of the residual cluster means'
///   squares less what the noise puts there, on [1 q_g], scaled by G / dof for the offsets the fit
///   absorbed; on fewer than 4 dof, where the two cannot be told apart, tau_1 alone when the
///   loading varies (a placement's tilt), fitted to the exact share each residual mean keeps,
///   ((D - P)_gh / n_g)^2 (placements are independent pose to pose). With Z the cluster
///   indicators, S = X'Z, H the fit's projection, D = diag(n_g) and P = S'(X'X)^-1 S, the
///   noise's part of the residual's cluster sums Z'(I - H)e is exact: sigma^2 (D - P) for white
///   noise;
///   V = sigma^2 (X'X)^-1 + (X'X)^-1 (sum_g tau_g^2 s_g s_g') (X'X)^-1,  s_g = X_g' 1,
/// the covariance of the (ordinary, here AR-whitened) least-squares estimate under that model.
/// With a coloured noise model (the whitened residual is not white where the AR model stops
/// following the sensor's noise: noise/coloured_noise.hpp) its meat X'RX replaces sigma^2 X'X,
/// and R's part of the cluster sums is Z'RZ - S'(X'X)^-1 X'RZ - (..)' + S'(X'X)^-1 X'RX (X'X)^-1 S:
/// noise common to a case's clusters (flicker below one cycle per phase) moves their means
/// together, and the fit's bias takes that out of the residual's means, so it is not subtracted
/// from their scatter. The offsets are then what that noise model does not explain.
struct ColouredNoise {
  Eigen::MatrixXd meat;                 ///< X'RX (p x p), R the residual's covariance
  std::vector<int> cluster_ids;         ///< ascending: the order of the columns below
  Eigen::MatrixXd cross;                ///< X'RZ (p x G)
  Eigen::MatrixXd sums_covariance;      ///< Z'RZ (G x G): the covariance of the clusters' noise sums
  /// R holds offsets of a stated size besides the noise (the cases' placements): a complete model
  /// of the clusters' scatter, so offsets are estimated beyond it only where the residual's
  /// cluster sums reject it (chi-square on their covariance under R, kStatedOffsetsLevel). With
  /// few clusters the moments' estimate of an excess that is not there is as large as the stated
  /// offsets themselves, and it would weigh every cluster alike.
  bool stated_offsets = false;
};
/// The level at which the residual's cluster sums reject R's stated offsets (ColouredNoise).
inline constexpr double kStatedOffsetsLevel = 0.05;
struct ClusterOffsets {
  int clusters = 0;                 ///< G
  int between_dof = 0;              ///< G - r; <= 0: the offsets cannot be told from the model
  double tau2 = 0.0;                ///< mean variance of the cluster offsets (0 when dof <= 0)
  double tau2_common = 0.0, tau2_per_loading = 0.0;   ///< tau_0^2, tau_1^2
  /// With stated offsets in R (ColouredNoise::stated_offsets): the p-value of the residual's
  /// cluster sums under R; NaN otherwise.
  double stated_offsets_p = std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixXd within;           ///< the noise's part: sigma^2 (X'X)^-1, or (X'X)^-1 X'RX (X'X)^-1
  Eigen::MatrixXd classical;        ///< sigma^2 (X'X)^-1: what a fit that takes the residual as white reports
  Eigen::MatrixXd covariance;       ///< V above (p x p); with dof <= 0 `within` only
  /// Per cluster (ascending id) when the estimate weighed the clusters' means by what their offsets
  /// leave of them (random_effects_fit; then `within` and `covariance` are that estimate's); empty:
  /// least squares.
  Eigen::VectorXd weights;
};
/// What cluster_offsets reads of a regression's rows, per cluster in ascending id order. Sums add
/// over rows, so the batch builds them from its rows (from_rows) and the live estimator from the
/// runs it keeps (online/information.hpp): both then take the offsets by the same rule.
struct ClusterSums {
  std::vector<int> ids;        ///< ascending
  Eigen::MatrixXd columns;     ///< S = X'Z (p x G): each cluster's column sums
  Eigen::VectorXd residuals;   ///< each cluster's residual sum
  Eigen::VectorXd rows;        ///< n_g
  Eigen::VectorXd loading;     ///< each cluster's mean loading q_g; empty: none (tau_1 = 0)
  /// cluster: one id per row (rows of one id need not be contiguous); loading: one value per row or empty.
  static ClusterSums from_rows(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::VectorXd>& residuals,
                               const std::vector<int>& cluster, const Eigen::VectorXd& loading = Eigen::VectorXd());
};
/// A tall matrix read a block of rows at a time, for what needs all of its rows but not at once:
/// `fill(begin, block)` writes rows [begin, begin + block.rows()) of it into `block`.
struct RowBlocks {
  static constexpr Eigen::Index kRows = 4096;   // the rows of the blocks its readers ask for
  Eigen::Index rows = 0;
  Eigen::Index cols = 0;
  std::function<void(Eigen::Index, Eigen::Ref<Eigen::MatrixXd>)> fill;
};
/// The regression's Gram as cluster_offsets reads it.
struct GramFactor {
  Eigen::MatrixXd inverse_factor;   ///< B (p x p) with (X'X)^-1 = B'B: sandwiches B'(B M B')B stay semidefinite
  Eigen::VectorXd column_rms;       ///< sqrt(diag(X'X) / N): the scale at which a column's cluster means count
  /// From the rows, through the QR of the columns scaled to unit norm (X's condition, not its square).
  static GramFactor from_rows(const Eigen::Ref<const Eigen::MatrixXd>& x);
  /// The same from X by blocks of rows (two passes: the columns' norms, then the QR).
  static GramFactor from_blocks(const RowBlocks& x);
  /// From X'X over `rows` rows, through the eigen decomposition of the Gram scaled to unit diagonal,
  /// where only the statistics are kept.
  static GramFactor from_gram(const Eigen::Ref<const Eigen::MatrixXd>& gram, double rows);
};
/// sums: of the regression columns in the linear form of the fit and of that fit's residuals;
/// sigma2 its white-noise variance. `estimated_elsewhere`: parameters fitted to the same cluster
/// means outside this model (a mounting's angles, estimated in an earlier stage), taken off the
/// between-cluster dof.
ClusterOffsets cluster_offsets(const ClusterSums& sums, const GramFactor& gram, double sigma2, int estimated_elsewhere = 0,
                               const ColouredNoise* noise = nullptr);
/// The same from the rows: x the columns, residuals, cluster one id per row, loading one value per row (empty: none).
ClusterOffsets cluster_offsets(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::VectorXd>& residuals,
                               double sigma2, const std::vector<int>& cluster, int estimated_elsewhere = 0,
                               const Eigen::VectorXd& loading = Eigen::VectorXd(), const ColouredNoise* noise = nullptr);

/// Whether a column lives between the clusters: less than kClusterLevelShare of its sum of
/// squares `energy` varies within them (`between`: the sum over clusters of (cluster sum)^2 / rows,
/// what the clusters' means hold). A static pose's terms are such: they are determined by the
/// clusters' means alone, and told apart from the clusters' offsets only by the clusters left
/// over. The share leaves room for what a whitened constant column gains at each phase's start
/// (the whitening's transient) and for the reference's noise, both orders of magnitude below a
/// column that moves within a phase (half of its energy or more).
inline constexpr double kClusterLevelShare = 1e-2;
[[nodiscard]] inline bool cluster_level(double energy, double between) {
  return energy > 0.0 && energy - between < kClusterLevelShare * energy;
}

/// Per column j < energy.size() of `sums`: cluster_level(energy(j), sum over clusters of
/// (cluster sum)^2 / rows), with `energy` the columns' sums of squares.
[[nodiscard]] std::vector<bool> phase_level_columns(const ClusterSums& sums, const Eigen::Ref<const Eigen::VectorXd>& energy);

/// The random-effects (feasible GLS) estimate under offsets `cluster_offsets` estimated: each
/// cluster's mean keeps the share w_g = m_g / (m_g + tau_g^2) of its information, m_g = v_g / n_g^2
/// the variance the noise puts in it (v_g: of its sum), the rest of the estimate coming from within
/// the clusters, as the quasi-demeaning of Fuller and Battese (1974) does for white noise:
///   x~_k = x_k - lambda_g mean_g(x),  lambda_g = 1 - sqrt(w_g),  theta = (X~'X~)^-1 X~'y~.
/// Why: least squares weighs every cluster's mean alike. When the offsets differ between clusters
/// (a tumble's placement tilt moves the poses with the input axis level and hardly those with it
/// vertical) the estimate takes in the scattered clusters' offsets, which the classical
/// (up + down) / 2 of the same data leaves out (test
/// Statistics.RandomEffectsCoverageAndGainWhereOffsetsReachSomeClusters measures the gain). Its
/// covariance is the sandwich under the same model,
///   V = A^-1 (X2' R X2 + sum_g tau_g^2 (w_g n_g mean_g(x))(..)') A^-1,  A = X~'X~,
///   X2 = x_k - (1 - w_g) mean_g(x) (the transform applied twice),
/// which holds whatever the weights, so weights from an estimated tau cost efficiency, not honesty.
/// x: all columns whose joint covariance is wanted; the first `estimated` are fitted to y (the rest
/// are parameters estimated elsewhere whose uncertainty joins V, as in cluster_offsets).
/// tau2 and noise_sum_variance: per cluster in ascending id order; noise_times(M) = R M.
struct RandomEffectsFit {
  Eigen::VectorXd theta;        ///< the first `estimated` columns' coefficients
  Eigen::VectorXd weights;      ///< w_g per cluster, ascending id
  Eigen::MatrixXd covariance;   ///< V (all columns of x)
  Eigen::MatrixXd within;       ///< the noise's part, A^-1 X2'RX2 A^-1
};
/// `known_offset_variance` (per cluster; empty: none): the variance of each cluster's mean from a
/// known part of R (a case's stated placement: noise_times holds it, noise_sum_variance does not),
/// which weighs with tau2.
RandomEffectsFit random_effects_fit(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Index estimated,
                                    const Eigen::Ref<const Eigen::VectorXd>& y, const std::vector<int>& cluster,
                                    const Eigen::VectorXd& tau2, const Eigen::VectorXd& noise_sum_variance,
                                    const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& noise_times,
                                    const Eigen::VectorXd& known_offset_variance = Eigen::VectorXd());
/// The same estimate from statistics alone, under white noise of variance sigma2 (R = sigma2 I, so
/// a cluster's noise sum has variance sigma2 n_g): gram = [X y]'[X y] over every row, sums.columns
/// the clusters' column sums, y_sums their output sums. The quasi-demeaned Gram follows from them:
///   X~'X~ = X'X - sum_g (2 l_g - l_g^2) n_g m_g m_g',   X~'y~ likewise with the output's means,
///   X2'X2 = X'X - sum_g (2 (1 - w_g) - (1 - w_g)^2) n_g m_g m_g',   m_g the cluster's column means.
/// With `sums_covariance` (C = Z'RZ, the covariance of the clusters' noise sums: a noise whose
/// colour moves the clusters together) the clusters' means take C's diagonal, and X2'RX2 is
/// taken on them, what varies within a cluster meeting the noise as white (sigma2):
///   X2'RX2 = sigma2 (X2'X2 - S2 N^-1 S2') + S2 N^-1 C N^-1 S2',   S2 = X2'Z (column g: w_g S_g),
/// exact where every column is constant within the clusters (the weighed case: static poses).
RandomEffectsFit random_effects_fit(const Eigen::Ref<const Eigen::MatrixXd>& gram, const ClusterSums& sums,
                                    const Eigen::VectorXd& y_sums, Eigen::Index estimated, const Eigen::VectorXd& tau2,
                                    double sigma2, const Eigen::MatrixXd* sums_covariance = nullptr);

/// Offset variances, or weights, that differ between clusters by less than this factor leave
/// least squares as it is (weighed_by_offsets).
inline constexpr double kDistinctOffsets = 10.0;
/// Whether the clusters' means are weighed by what their offsets leave of them, and the weighed
/// estimate when they are: each cluster's offset variance is the offsets' common part plus their
/// part per unit loading times its mean loading (`loading`, per cluster; empty: none), and `fit`
/// (random_effects_fit on rows or on statistics) weighs by them. None, where least squares with
/// the offsets' sandwich stands:
///  - fewer than 2 clusters, or a cluster whose noise sum has no variance;
///  - an offset alike in every cluster (within kDistinctOffsets): the weights would only trade the
///    means against what varies within the clusters, which in static phases is the whitening's
///    transients and the reference's noise, and the weighed fit's covariance can come out
///    indefinite (docs/validation.md, 'Evidence behind choices in the code');
///  - dependent weighed columns, weights alike (the offsets small against the noise in every
///    cluster), or a covariance that is not one.
/// `known_offset_variance` (per cluster; empty: none): offsets of a stated variance besides the
/// estimated ones, the variance of each cluster's mean (a case's stated placement, which the
/// estimated offsets then do not hold); they weigh with them (`fit` is given the estimated ones).
std::optional<RandomEffectsFit> weighed_by_offsets(const ClusterOffsets& offsets, const Eigen::VectorXd& loading,
                                                   const Eigen::VectorXd& noise_sum_variance,
                                                   const std::function<RandomEffectsFit(const Eigen::VectorXd& tau2)>& fit,
                                                   const Eigen::VectorXd& known_offset_variance = Eigen::VectorXd());

/// A test level over a family of `candidates` (Bonferroni): alpha / candidates. A term picked as
/// the best of the candidates left has an optimistic p-value of its own; the family's level
/// bounds the probability of keeping any spurious term by alpha. Algorithm 2's step 9, the
/// inference after it and the live estimate all test at alpha over their search space.
[[nodiscard]] inline double family_threshold(double alpha, std::size_t candidates) {
  return alpha / static_cast<double>(std::max<std::size_t>(candidates, 1));
}

/// One fitted term's test in the inference after a selection (the offline procedure's and the
/// live estimate's: procedure/post_selection_inference.hpp, online/live_estimate.hpp).
struct TermTest {
  double t = 0.0;             ///< estimate over its sd, the clusters' offsets in the sd
  double samples_dof = 0.0;   ///< the samples' dof (rows less parameters)
  bool phase_level = false;   ///< constant within every cluster (phase_level_columns)
  bool removable = true;      ///< may leave: not a sensitivity, the bias or a term the caller keeps
};

/// The dof of term j's test (`test`) once the clusters' offsets (`offsets`, cluster_offsets, with
/// the weighed estimate's `within` and `covariance` when it weighed) are in its covariance:
///  - the clusters' dof (between_dof, at least 1) for a term constant within each cluster, which
///    only the clusters' means determine whatever the offsets' estimate (on few dof that estimate
///    often comes out near 0), and for a term whose variance the offsets dominate (more than twice
///    the noise's part);
///  - weighed by clearly distinct offsets, the clusters' means carry the offsets' share of a term's
///    variance by their weights, and only that share is known on the clusters' dof: the
///    Welch-Satterthwaite dof of the two shares, between the clusters' dof and the samples';
///  - otherwise the samples' dof.
[[nodiscard]] double term_test_dof(const ClusterOffsets& offsets, Eigen::Index j, const TermTest& test);

/// Whether a model's terms at the level of the clusters' means are as many as the clusters (the
/// offsets cannot be told from them) and one of them may leave.
[[nodiscard]] bool saturated_by_clusters(const ClusterOffsets& offsets, std::span<const TermTest> tests);

/// Which term leaves a model after its selection, by the rule the offline inference and the live
/// estimate share: when saturated_by_clusters, the removable phase-level term with the smallest
/// |t|, whatever its test; otherwise term_to_prune of the removable terms' two-sided p-values
/// (Student's t on term_test_dof) at `threshold`. None when nothing leaves.
struct TermLeaving {
  std::size_t term = 0;     ///< index into the tests
  bool saturated = false;   ///< it left because the clusters were saturated
  double dof = 0.0;         ///< of its test
};
[[nodiscard]] std::optional<TermLeaving> term_leaving(const ClusterOffsets& offsets, std::span<const TermTest> tests,
                                                      double threshold);

/// fitness = p_res * p_AIC (section 2.7).
inline double fitness(double p_res, double p_aic) { return p_res * p_aic; }

struct CorrelationCheck {
  Eigen::VectorXd lags;       ///< the lag of each value (1..L for autocorrelation, -L..L cross)
  Eigen::VectorXd values;     ///< normalized correlation at each lag
  double band = 0.0;          ///< 95% band +-1.96 / sqrt(N) for a white residual
  int outside = 0;            ///< lags with |value| > band
  int allowed = 0;            ///< largest count consistent with whiteness (see below)
  double max_band = 0.0;      ///< family-wise 1% band for the largest |value|
  bool pass = false;
};
/// Normalized autocorrelation r(tau) = sum (e_k - m)(e_{k-tau} - m) / sum (e_k - m)^2,
/// tau = 1..max_lag, band +-1.96/sqrt(N). Verdict: under whiteness each lag falls outside with
/// probability 0.05, so the count is ~Binomial(L, 0.05); the check passes when the count is at
/// most its 99% quantile AND the largest |r| is inside the family-wise 1% band
/// z(1 - 0.005/L)/sqrt(N). The count alone lets a few strong lags through (AR(1) with 0.5 has
/// only 4 of 20 lags outside); the max test alone misses many moderate ones. A white residual
/// fails either part about 1% of the time, so the check about 2%.
CorrelationCheck residual_autocorrelation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                          int max_lag);
/// Normalized cross-correlation r(tau) = sum (e_k - m_e)(u_{k-tau} - m_u) / sqrt(sum..^2 sum..^2)
/// for tau = -max_lag..max_lag (tau > 0: input leads the residual), same band and verdict. Under
/// the null (white residual independent of u) the variance is 1/N whatever the colour of u.
CorrelationCheck residual_input_correlation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                            const Eigen::Ref<const Eigen::VectorXd>& input,
                                            int max_lag);

struct WhitenessReport {
  CorrelationCheck autocorrelation;
  std::vector<CorrelationCheck> cross;  ///< one per input column
  bool pass = false;                    ///< all checks pass
};
/// inputs: N x m, one column per input signal.
WhitenessReport residual_whiteness(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                   const Eigen::Ref<const Eigen::MatrixXd>& inputs, int max_lag);

}  // namespace inertia::ident
