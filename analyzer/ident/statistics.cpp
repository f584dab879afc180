#include "analyzer/ident/statistics.hpp"

#include <map>
#include <stdexcept>

#include <boost/math/distributions/binomial.hpp>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace inertia::ident {
namespace {

constexpr double kBand95 = 1.959963984540054;  // two-sided 95% normal quantile

// Largest outside-count consistent with whiteness: 99% quantile of Binomial(L, 0.05).
int allowed_outside(int lags) {
  if (lags <= 0) return 0;
  const boost::math::binomial_distribution<double> dist(lags, 0.05);
  int c = 0;
  while (c < lags && boost::math::cdf(dist, c) < 0.99) ++c;
  return c;
}

void finish_check(CorrelationCheck& check, double samples) {
  const int lags = static_cast<int>(check.values.size());
  check.outside = static_cast<int>((check.values.array().abs() > check.band).count());
  check.allowed = allowed_outside(lags);
  // Family-wise 1% band for the largest lag (Bonferroni over the lags): catches a few strong lags
  // (AR(1), an input leaking at one lag) that the count alone lets through.
  const boost::math::normal_distribution<double> normal;
  check.max_band = boost::math::quantile(boost::math::complement(normal, 0.005 / std::max(lags, 1))) /
                   std::sqrt(samples);
  const double largest = lags > 0 ? check.values.cwiseAbs().maxCoeff() : 0.0;
  check.pass = check.outside <= check.allowed && largest <= check.max_band;
}

}  // namespace

double student_t_two_sided_p(double t, double dof) {
  if (std::isnan(t) || !(dof > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (std::isinf(t)) return 0.0;
  const boost::math::students_t dist(dof);
  return 2.0 * boost::math::cdf(boost::math::complement(dist, std::abs(t)));
}

double student_t_interval_factor(double level, double dof) {
  const double upper = 0.5 * (1.0 + level);
  if (!std::isfinite(dof)) return boost::math::quantile(boost::math::normal_distribution<double>(), upper);
  return boost::math::quantile(boost::math::students_t(dof), upper);
}

ParameterTTest parameter_t_test(const Eigen::Ref<const Eigen::VectorXd>& theta,
                                const Eigen::Ref<const Eigen::VectorXd>& std_dev,
                                Eigen::Index samples) {
  if (theta.size() != std_dev.size())
    throw std::invalid_argument("t-test: theta and std_dev differ in size");
  ParameterTTest out;
  const Eigen::Index p = theta.size();
  out.dof = static_cast<double>(samples - p - 1);
  out.t.resize(p);
  out.p_value.resize(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    if (std_dev[j] > 0.0) {
      out.t[j] = theta[j] / std_dev[j];
    } else {
      out.t[j] = theta[j] == 0.0 ? 0.0 : std::copysign(std::numeric_limits<double>::infinity(), theta[j]);
    }
    out.p_value[j] = student_t_two_sided_p(out.t[j], out.dof);
  }
  return out;
}

std::optional<std::size_t> term_to_prune(std::span<const double> p_values, double threshold) {
  std::optional<std::size_t> worst;
  for (std::size_t j = 0; j < p_values.size(); ++j) {
    if (!(p_values[j] > threshold)) continue;   // NaN too
    if (!worst || p_values[j] > p_values[*worst]) worst = j;
  }
  return worst;
}

double term_test_dof(const ClusterOffsets& offsets, Eigen::Index j, const TermTest& test) {
  const bool determined = j < offsets.covariance.rows() && j < offsets.within.rows();
  const bool offsets_dominate =
      determined && offsets.tau2 > 0.0 && offsets.covariance(j, j) > 2.0 * offsets.within(j, j);
  const bool between_only = test.phase_level && offsets.clusters >= 2 && offsets.between_dof >= 1;
  if (!(offsets_dominate || between_only)) return test.samples_dof;
  const double between_dof = std::max(1, offsets.between_dof);
  if (offsets.weights.size() == 0 || !determined) return between_dof;
  const double v = offsets.covariance(j, j), w = offsets.within(j, j), o = std::max(0.0, v - w);
  return std::clamp(v * v / (o * o / between_dof + w * w / test.samples_dof), between_dof,
                    std::max(between_dof, test.samples_dof));
}

bool saturated_by_clusters(const ClusterOffsets& offsets, std::span<const TermTest> tests) {
  return offsets.clusters >= 2 && offsets.between_dof <= 0 &&
         std::any_of(tests.begin(), tests.end(), [](const TermTest& t) { return t.phase_level && t.removable; });
}

std::optional<TermLeaving> term_leaving(const ClusterOffsets& offsets, std::span<const TermTest> tests, double threshold) {
  const bool saturated = saturated_by_clusters(offsets, tests);
  std::vector<double> p_values(tests.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> dof(tests.size(), 0.0);
  for (std::size_t j = 0; j < tests.size(); ++j) {
    const TermTest& test = tests[j];
    if (!test.removable) continue;
    dof[j] = term_test_dof(offsets, static_cast<Eigen::Index>(j), test);
    if (!saturated) p_values[j] = student_t_two_sided_p(test.t, dof[j]);
    else if (test.phase_level) p_values[j] = 1.0 / (1.0 + std::abs(test.t));   // ranks by |t|: the weakest leaves
  }
  const std::optional<std::size_t> leaves =
      term_to_prune(p_values, saturated ? -std::numeric_limits<double>::infinity() : threshold);
  if (!leaves) return std::nullopt;
  return TermLeaving{*leaves, saturated, dof[*leaves]};
}

double aic_from_variance(double sigma2_ml, Eigen::Index samples, Eigen::Index parameters) {
  if (!(sigma2_ml > 0.0)) return -std::numeric_limits<double>::infinity();
  return static_cast<double>(samples) * std::log(sigma2_ml) + 2.0 * static_cast<double>(parameters);
}

double aic(const Eigen::Ref<const Eigen::VectorXd>& residuals, Eigen::Index parameters) {
  const Eigen::Index n = residuals.size();
  return aic_from_variance(residuals.squaredNorm() / static_cast<double>(n), n, parameters);
}

Eigen::VectorXd relative_likelihood(const Eigen::Ref<const Eigen::VectorXd>& aic_values) {
  double best = std::numeric_limits<double>::infinity();
  for (double a : aic_values)
    if (!std::isnan(a)) best = std::min(best, a);
  Eigen::VectorXd out(aic_values.size());
  for (Eigen::Index i = 0; i < aic_values.size(); ++i)
    out[i] = std::isnan(aic_values[i]) ? aic_values[i] : std::exp((best - aic_values[i]) / 2.0);
  return out;
}

SuccessiveDifferences successive_differences(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                             std::span<const Eigen::Index> stretch_starts) {
  SuccessiveDifferences out;
  for_each_stretch(residuals.size(), stretch_starts, [&](Eigen::Index begin, Eigen::Index end) {
    if (end - begin < 2) return;
    const Eigen::Index pairs = end - begin - 1;
    out.energy += (residuals.segment(begin + 1, pairs) - residuals.segment(begin, pairs)).squaredNorm();
    out.pairs += pairs;
  });
  return out;
}

ResidualMeanTest residual_mean_test(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                    std::span<const Eigen::Index> stretch_starts, bool effective_size) {
  const Eigen::Index n = residuals.size();
  if (n < 3) throw std::invalid_argument("residual mean test needs at least 3 samples");
  const double mean = residuals.mean();
  const double ss = (residuals.array() - mean).square().sum();
  if (!effective_size) return residual_mean_test(mean, ss / static_cast<double>(n - 1), static_cast<double>(n));
  const SuccessiveDifferences d = successive_differences(residuals, stretch_starts);
  return residual_mean_test(mean, ss, n, d.energy, d.pairs);
}

ResidualMeanTest residual_mean_test(double mean, double centred_energy, Eigen::Index samples, double difference_energy,
                                    Eigen::Index pairs) {
  if (samples < 3) throw std::invalid_argument("residual mean test needs at least 3 samples");
  const auto n = static_cast<double>(samples);
  const double ss = std::max(centred_energy, 0.0);
  const double r1 = ss > 0.0 && pairs > 0 ? 1.0 - (std::max(difference_energy, 0.0) / static_cast<double>(pairs)) / (2.0 * ss / n) : 0.0;
  const double clamped = std::clamp(r1, -0.999, 0.999);
  const double n_eff = std::clamp(n * (1.0 - clamped) / (1.0 + clamped), 2.0, n);
  ResidualMeanTest out = residual_mean_test(mean, ss / (n - 1.0), n_eff);
  out.lag1_autocorrelation = r1;
  return out;
}

ResidualMeanTest residual_mean_test(double mean, double variance, double effective_samples) {
  if (!(effective_samples >= 2.0)) throw std::invalid_argument("residual mean test needs at least 2 effective samples");
  ResidualMeanTest out;
  out.mean = mean;
  out.effective_samples = effective_samples;
  out.std_error = std::sqrt(std::max(variance, 0.0) / effective_samples);
  if (out.std_error > 0.0) {
    out.t = out.mean / out.std_error;
    out.p_value = student_t_two_sided_p(out.t, effective_samples - 1.0);
  } else {
    // Constant residual: exactly zero is a perfect fit, anything else a certain offset.
    out.t = out.mean == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
    out.p_value = out.mean == 0.0 ? 1.0 : 0.0;
  }
  return out;
}

CorrelationCheck residual_autocorrelation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                          int max_lag) {
  const Eigen::Index n = residuals.size();
  if (max_lag < 1 || max_lag >= n) throw std::invalid_argument("autocorrelation: bad max_lag");
  const Eigen::VectorXd c = residuals.array() - residuals.mean();
  const double ss = c.squaredNorm();
  CorrelationCheck out;
  out.lags = Eigen::VectorXd::LinSpaced(max_lag, 1.0, max_lag);
  out.values.resize(max_lag);
  for (int tau = 1; tau <= max_lag; ++tau)
    out.values[tau - 1] = ss > 0.0 ? c.head(n - tau).dot(c.tail(n - tau)) / ss : 0.0;
  out.band = kBand95 / std::sqrt(static_cast<double>(n));
  finish_check(out, static_cast<double>(n));
  return out;
}

CorrelationCheck residual_input_correlation(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                            const Eigen::Ref<const Eigen::VectorXd>& input,
                                            int max_lag) {
  const Eigen::Index n = residuals.size();
  if (input.size() != n) throw std::invalid_argument("cross-correlation: sizes differ");
  if (max_lag < 0 || max_lag >= n) throw std::invalid_argument("cross-correlation: bad max_lag");
  const Eigen::VectorXd e = residuals.array() - residuals.mean();
  const Eigen::VectorXd u = input.array() - input.mean();
  const double norm = std::sqrt(e.squaredNorm() * u.squaredNorm());
  CorrelationCheck out;
  const int count = 2 * max_lag + 1;
  out.lags = Eigen::VectorXd::LinSpaced(count, -max_lag, max_lag);
  out.values.resize(count);
  for (int i = 0; i < count; ++i) {
    const int tau = i - max_lag;
    const Eigen::Index m = n - std::abs(tau);
    // tau > 0: e_k with u_{k-tau}; tau < 0: e_k with u_{k+|tau|}.
    const double s = tau >= 0 ? e.tail(m).dot(u.head(m)) : e.head(m).dot(u.tail(m));
    out.values[i] = norm > 0.0 ? s / norm : 0.0;
  }
  out.band = kBand95 / std::sqrt(static_cast<double>(n));
  finish_check(out, static_cast<double>(n));
  return out;
}

WhitenessReport residual_whiteness(const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                   const Eigen::Ref<const Eigen::MatrixXd>& inputs, int max_lag) {
  WhitenessReport out;
  out.autocorrelation = residual_autocorrelation(residuals, max_lag);
  out.pass = out.autocorrelation.pass;
  for (Eigen::Index j = 0; j < inputs.cols(); ++j) {
    out.cross.push_back(residual_input_correlation(residuals, inputs.col(j), max_lag));
    out.pass = out.pass && out.cross.back().pass;
  }
  return out;
}

namespace {
/// Between-cluster dof from which the offsets' common and loading parts are both estimated.
constexpr int kTwoComponentDof = 4;

/// B with (X'X)^-1 = B'B, from the QR of X with its columns scaled to unit norm: X S^-1 = Q R P'
/// gives B = R^-T P' S^-1. A sandwich B'(B M B')B then stays positive semidefinite for a
/// semidefinite meat M where (X'X)^-1 M (X'X)^-1 through an LDLT of X'X, whose condition is the
/// square of X's, can give negative variances, read as a t of infinity, on nearly dependent
/// columns (on a tumble, sign(a_i) and a_i*abs(a_i) differ from a_i only in the poses with the
/// input axis level; docs/validation.md, 'Evidence behind choices in the code').
Eigen::MatrixXd inverse_gram_factor(const RowBlocks& x, Eigen::VectorXd scale) {
  const Eigen::Index p = x.cols;
  for (Eigen::Index j = 0; j < p; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  // The triangular factor of X S^-1 by blocks of rows, each block's QR taken under the factor so
  // far: the QR of the whole to rounding (a tall-skinny QR), holding one block, not a copy of X.
  // The column pivoting then acts on that p x p factor, whose columns have X S^-1's norms.
  const Eigen::Index n = x.rows;
  Eigen::MatrixXd stacked = Eigen::MatrixXd::Zero(std::min(n, RowBlocks::kRows) + p, p);
  Eigen::Index held = 0;   // rows of the factor so far at the top of `stacked`
  for (Eigen::Index k0 = 0; k0 < n; k0 += RowBlocks::kRows) {
    const Eigen::Index rows = std::min(RowBlocks::kRows, n - k0);
    x.fill(k0, stacked.middleRows(held, rows));
    stacked.middleRows(held, rows) *= scale.cwiseInverse().asDiagonal();
    const Eigen::HouseholderQR<Eigen::MatrixXd> block(stacked.topRows(held + rows));
    held = std::min(held + rows, p);
    stacked.topRows(held) = block.matrixQR().topRows(held).triangularView<Eigen::Upper>();
  }
  stacked.middleRows(held, p - held).setZero();   // fewer rows than columns: the missing ones are zero
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(stacked.topRows(p));
  Eigen::MatrixXd r = qr.matrixR().topLeftCorner(p, p).triangularView<Eigen::Upper>();
  // A dependent column gets an enormous variance, not an infinite one (as an LDLT of X'X gives).
  const double floor = p > 0 ? 1e-15 * std::abs(r(0, 0)) : 0.0;
  for (Eigen::Index j = 0; j < p; ++j)
    if (std::abs(r(j, j)) < floor) r(j, j) = std::copysign(floor, r(j, j));
  const Eigen::MatrixXd b = r.transpose().triangularView<Eigen::Lower>().solve(
      Eigen::MatrixXd(qr.colsPermutation().transpose() * Eigen::MatrixXd::Identity(p, p)));
  return b * scale.cwiseInverse().asDiagonal();
}

/// (X'X)^-1 M (X'X)^-1 with B from inverse_gram_factor.
Eigen::MatrixXd sandwich(const Eigen::MatrixXd& b, const Eigen::MatrixXd& meat) {
  // B M B' = C C' (its eigenvalues below zero, rounding of a semidefinite meat, dropped), and the
  // sandwich the Gram of B'C: semidefinite by construction, where B'(B M B')B, on a nearly
  // dependent design (B's entries large), cancels to rounding noise of either sign.
  Eigen::MatrixXd inner = b * meat * b.transpose();
  inner = 0.5 * (inner + inner.transpose()).eval();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(inner);
  const Eigen::MatrixXd c = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  const Eigen::MatrixXd bc = b.transpose() * c;
  return bc * bc.transpose();
}
}  // namespace

ClusterSums ClusterSums::from_rows(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::VectorXd>& residuals,
                                  const std::vector<int>& cluster, const Eigen::VectorXd& loading) {
  const Eigen::Index n = x.rows(), p = x.cols();
  if (residuals.size() != n || static_cast<Eigen::Index>(cluster.size()) != n || (loading.size() != 0 && loading.size() != n))
    throw std::invalid_argument("cluster_offsets: x, residuals, loading and cluster ids differ in length");
  struct Part {
    Eigen::VectorXd column_sums;
    double residual_sum = 0.0, loading_sum = 0.0, rows = 0.0;
  };
  std::map<int, Part> parts;
  for (Eigen::Index begin = 0; begin < n;) {   // runs of one id as blocks
    Eigen::Index end = begin + 1;
    while (end < n && cluster[static_cast<std::size_t>(end)] == cluster[static_cast<std::size_t>(begin)]) ++end;
    auto [it, fresh] = parts.try_emplace(cluster[static_cast<std::size_t>(begin)]);
    if (fresh) it->second.column_sums = Eigen::VectorXd::Zero(p);
    it->second.column_sums += x.middleRows(begin, end - begin).colwise().sum().transpose();
    it->second.residual_sum += residuals.segment(begin, end - begin).sum();
    if (loading.size() != 0) it->second.loading_sum += loading.segment(begin, end - begin).sum();
    it->second.rows += static_cast<double>(end - begin);
    begin = end;
  }
  ClusterSums out;
  const auto g_count = static_cast<Eigen::Index>(parts.size());
  out.columns.resize(p, g_count);
  out.residuals.resize(g_count);
  out.rows.resize(g_count);
  if (loading.size() != 0) out.loading.resize(g_count);
  for (const auto& [id, part] : parts) {
    const auto g = static_cast<Eigen::Index>(out.ids.size());
    out.ids.push_back(id);
    out.columns.col(g) = part.column_sums;
    out.residuals(g) = part.residual_sum;
    out.rows(g) = part.rows;
    if (loading.size() != 0) out.loading(g) = part.loading_sum / part.rows;
  }
  return out;
}

GramFactor GramFactor::from_rows(const Eigen::Ref<const Eigen::MatrixXd>& x) {
  const RowBlocks blocks{x.rows(), x.cols(), [&](Eigen::Index begin, Eigen::Ref<Eigen::MatrixXd> block) {
                           block = x.middleRows(begin, block.rows());
                         }};
  const Eigen::VectorXd norms = x.colwise().norm().transpose();
  GramFactor out;
  out.inverse_factor = inverse_gram_factor(blocks, norms);
  out.column_rms = norms / std::sqrt(static_cast<double>(std::max<Eigen::Index>(x.rows(), 1)));
  return out;
}

GramFactor GramFactor::from_blocks(const RowBlocks& x) {
  Eigen::VectorXd squares = Eigen::VectorXd::Zero(x.cols);
  Eigen::MatrixXd block(std::min(x.rows, RowBlocks::kRows), x.cols);
  for (Eigen::Index k0 = 0; k0 < x.rows; k0 += RowBlocks::kRows) {
    const Eigen::Index rows = std::min(RowBlocks::kRows, x.rows - k0);
    x.fill(k0, block.topRows(rows));
    squares += block.topRows(rows).colwise().squaredNorm().transpose();
  }
  const Eigen::VectorXd norms = squares.cwiseSqrt();
  GramFactor out;
  out.inverse_factor = inverse_gram_factor(x, norms);
  out.column_rms = norms / std::sqrt(static_cast<double>(std::max<Eigen::Index>(x.rows, 1)));
  return out;
}

GramFactor GramFactor::from_gram(const Eigen::Ref<const Eigen::MatrixXd>& gram, double rows) {
  const Eigen::Index p = gram.rows();
  if (gram.cols() != p) throw std::invalid_argument("GramFactor: the Gram is not square");
  Eigen::VectorXd scale = gram.diagonal().cwiseMax(0.0).cwiseSqrt();
  for (Eigen::Index j = 0; j < p; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  const Eigen::MatrixXd scaled = scale.cwiseInverse().asDiagonal() * gram * scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (scaled + scaled.transpose()));
  // The floor of inverse_gram_factor's R diagonal, squared: a dependent column gets an enormous
  // variance, not an infinite one.
  Eigen::VectorXd lambda = eig.eigenvalues();
  const double floor = p > 0 ? 1e-30 * std::max(lambda.maxCoeff(), 0.0) : 0.0;
  for (Eigen::Index k = 0; k < p; ++k) lambda(k) = std::max(lambda(k), floor > 0.0 ? floor : 1.0);
  GramFactor out;
  out.inverse_factor = lambda.cwiseSqrt().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose() * scale.cwiseInverse().asDiagonal();
  out.column_rms = gram.diagonal().cwiseMax(0.0).cwiseSqrt() / std::sqrt(std::max(rows, 1.0));
  return out;
}

std::vector<bool> phase_level_columns(const ClusterSums& sums, const Eigen::Ref<const Eigen::VectorXd>& energy) {
  if (energy.size() > sums.columns.rows()) throw std::invalid_argument("phase_level_columns: more energies than columns");
  std::vector<bool> out(static_cast<std::size_t>(energy.size()));
  for (Eigen::Index j = 0; j < energy.size(); ++j) {
    double between = 0.0;
    for (Eigen::Index g = 0; g < sums.columns.cols(); ++g)
      if (sums.rows(g) > 0.0) between += sums.columns(j, g) * sums.columns(j, g) / sums.rows(g);
    out[static_cast<std::size_t>(j)] = cluster_level(energy(j), between);
  }
  return out;
}

ClusterOffsets cluster_offsets(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::VectorXd>& residuals,
                               double sigma2, const std::vector<int>& cluster, int estimated_elsewhere,
                               const Eigen::VectorXd& loading, const ColouredNoise* noise) {
  return cluster_offsets(ClusterSums::from_rows(x, residuals, cluster, loading), GramFactor::from_rows(x), sigma2,
                         estimated_elsewhere, noise);
}

ClusterOffsets cluster_offsets(const ClusterSums& cs, const GramFactor& gram, double sigma2, int estimated_elsewhere,
                               const ColouredNoise* noise) {
  const Eigen::Index p = gram.inverse_factor.rows();
  const auto g_count = static_cast<Eigen::Index>(cs.ids.size());
  if (noise != nullptr && (noise->meat.rows() != p || noise->meat.cols() != p))
    throw std::invalid_argument("cluster_offsets: the coloured noise's meat is not p x p");
  if (gram.inverse_factor.cols() != p || gram.column_rms.size() != p || cs.columns.rows() != p || cs.columns.cols() != g_count ||
      cs.residuals.size() != g_count || cs.rows.size() != g_count || (cs.loading.size() != 0 && cs.loading.size() != g_count))
    throw std::invalid_argument("cluster_offsets: the clusters' sums and the Gram differ in size");
  const Eigen::VectorXd& rows = cs.rows;
  const Eigen::MatrixXd& sums = cs.columns;
  const std::vector<int>& ids = cs.ids;
  ClusterOffsets out;
  out.clusters = static_cast<int>(g_count);
  const Eigen::MatrixXd means = (sums * rows.cwiseInverse().asDiagonal()).transpose();
  const Eigen::VectorXd mean_square = cs.residuals.cwiseQuotient(rows).cwiseAbs2();
  const Eigen::VectorXd q = cs.loading.size() != 0 ? cs.loading : Eigen::VectorXd::Zero(g_count);
  if (noise != nullptr && (noise->cluster_ids != ids || noise->cross.rows() != p || noise->cross.cols() != g_count ||
                           noise->sums_covariance.rows() != g_count || noise->sums_covariance.cols() != g_count))
    throw std::invalid_argument("cluster_offsets: the coloured noise's clusters are not the rows'");
  // Rank of the cluster-mean design, each column scaled by its RMS over the rows: a column whose
  // phase means are nothing against its own size (a vibration about zero) adds no rank.
  Eigen::VectorXd scale = gram.column_rms;
  for (Eigen::Index j = 0; j < p; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(means * scale.cwiseInverse().asDiagonal());
  const Eigen::VectorXd& sv = svd.singularValues();
  int rank = 0;
  for (Eigen::Index k = 0; k < sv.size(); ++k)
    if (sv(k) > 1e-6 * sv(0)) ++rank;
  out.between_dof = out.clusters - rank - estimated_elsewhere;
  const Eigen::MatrixXd& factor = gram.inverse_factor;
  const Eigen::MatrixXd inverse = factor.transpose() * factor;
  out.classical = sigma2 * inverse;
  out.within = noise != nullptr ? sandwich(factor, noise->meat) : out.classical;
  out.covariance = out.within;
  if (out.between_dof > 0) {
    // What the noise puts in the squares of the residual's cluster sums Z'(I - H)e, with the
    // share the fit took out of them: noise common to a case's phases (flicker below one cycle
    // per phase) is taken out by the bias, and is not the offsets' to explain.
    const Eigen::MatrixXd inverse_sums = inverse * sums;   // (X'X)^-1 S
    Eigen::VectorXd noise_part(g_count);
    if (noise != nullptr) {
      const Eigen::MatrixXd absorbed = inverse_sums.transpose() * noise->cross;   // S'(X'X)^-1 X'RZ
      noise_part = (noise->sums_covariance - absorbed - absorbed.transpose() + inverse_sums.transpose() * noise->meat * inverse_sums)
                       .diagonal();
    } else {
      noise_part = sigma2 * (rows - (sums.transpose() * inverse_sums).diagonal());   // sigma^2 (D - P)
    }
    const Eigen::VectorXd excess = mean_square - noise_part.cwiseQuotient(rows.cwiseAbs2());
    bool explained = false;
    if (noise != nullptr && noise->stated_offsets) {
      const Eigen::MatrixXd absorbed = inverse_sums.transpose() * noise->cross;
      const Eigen::MatrixXd kept = noise->sums_covariance - absorbed - absorbed.transpose() +
                                   inverse_sums.transpose() * noise->meat * inverse_sums;   // of Z'(I - H)e under R
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (kept + kept.transpose()));
      const double floor = 1e-9 * std::max(0.0, eig.eigenvalues().maxCoeff());
      double statistic = 0.0;
      int dof = 0;
      const Eigen::VectorXd along = eig.eigenvectors().transpose() * cs.residuals;
      for (Eigen::Index k = 0; k < g_count; ++k) {
        if (!(eig.eigenvalues()(k) > floor)) continue;
        statistic += along(k) * along(k) / eig.eigenvalues()(k);
        ++dof;
      }
      dof = std::min(dof, out.between_dof);
      if (dof > 0) {
        out.stated_offsets_p = boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), statistic));
        explained = out.stated_offsets_p >= kStatedOffsetsLevel;
      }
    }
    // The offsets' share the fit absorbed: G / dof on the whole. The exact share, (D - P)^2, takes
    // each phase's offset as independent of its neighbours'. Flicker below one cycle per case
    // makes a case's offsets move together, and the exact share then understates the bias's sd
    // far more than G / dof does (plan-check on sim-paper-daq; docs/validation.md, 'Evidence
    // behind choices in the code').
    const double inflate = static_cast<double>(out.clusters) / static_cast<double>(out.between_dof);
    // Non-negative least squares of excess on [1 q]: both, or the better single one. On fewer
    // than kTwoComponentDof between-cluster dof the residual means are one point in a space of 2
    // or 3 dimensions, which either shape fits, and the split is noise: on a tumble (6 poses,
    // 2 dof) the common part can take most of it and overstate the scale factor's sd many times.
    // There the offsets are taken as the placements': a small tilt moves a pose's output in
    // proportion to the specific force across the input axis, and an offset common to the poses
    // beyond the noise's (the static law below one cycle per case) would be a turn-on
    // repeatability these few dof cannot tell from it. The figures on sim-tumble over seeds:
    // docs/validation.md, 'Evidence behind choices in the code'.
    double t0 = std::max(0.0, excess.mean()), t1 = 0.0;
    bool exact_share = false;
    const bool varying = cs.loading.size() != 0 && out.between_dof >= 2 && (q.array() - q.mean()).abs().maxCoeff() > 0.0;
    if (varying) {
      Eigen::MatrixXd a(g_count, 2);
      a.col(0).setOnes();
      a.col(1) = q;
      const Eigen::Vector2d both = a.colPivHouseholderQr().solve(excess);
      const double only1 = std::max(0.0, q.dot(excess) / q.squaredNorm());
      const auto misfit = [&](double c0, double c1) { return (excess - a * Eigen::Vector2d(c0, c1)).squaredNorm(); };
      const bool placements_only = out.between_dof < kTwoComponentDof && only1 > 0.0;
      if (!placements_only && both(0) >= 0.0 && both(1) >= 0.0) {
        t0 = both(0);
        t1 = both(1);
      } else if (placements_only || misfit(0.0, only1) < misfit(t0, 0.0)) {
        t0 = 0.0;
        t1 = only1;
      }
      if (placements_only) {
        // A placement is an act of its own, independent pose to pose, so the share of each offset
        // the fit absorbed is the exact one: a cluster's residual mean is ((D - P) u)_g / n_g, and
        // E[m_g^2] = tau_1^2 sum_h ((D - P)_gh / n_g)^2 q_h. On a tumble the poses with the input
        // axis level keep 0.28 of their offsets' variance in their residual means, not the 1/3 of
        // G / dof = 3, which would take the angles' variance low (test
        // Statistics.ClusterOffsetsOfPlacementsAreUnbiasedOnATumble; docs/validation.md, 'Evidence
        // behind choices in the code').
        const Eigen::MatrixXd kept_share = Eigen::MatrixXd(rows.asDiagonal()) - sums.transpose() * inverse_sums;   // D - P
        const Eigen::VectorXd reach = kept_share.cwiseAbs2() * q;
        const Eigen::VectorXd per_mean = reach.cwiseQuotient(rows.cwiseAbs2());
        t1 = std::max(0.0, per_mean.dot(excess) / per_mean.squaredNorm());
        exact_share = true;
      }
    }
    out.tau2_common = explained ? 0.0 : inflate * t0;
    out.tau2_per_loading = explained ? 0.0 : exact_share ? t1 : inflate * t1;
    Eigen::MatrixXd between = Eigen::MatrixXd::Zero(p, p);
    double total = 0.0;
    for (Eigen::Index g = 0; g < g_count; ++g) {
      const double tau_g = out.tau2_common + out.tau2_per_loading * q(g);
      total += tau_g;
      between.noalias() += tau_g * sums.col(g) * sums.col(g).transpose();
    }
    out.tau2 = total / static_cast<double>(g_count);
    out.covariance += sandwich(factor, between);
  }
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose()).eval();
  return out;
}

RandomEffectsFit random_effects_fit(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Index estimated,
                                    const Eigen::Ref<const Eigen::VectorXd>& y, const std::vector<int>& cluster,
                                    const Eigen::VectorXd& tau2, const Eigen::VectorXd& noise_sum_variance,
                                    const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& noise_times,
                                    const Eigen::VectorXd& known_offset_variance) {
  const Eigen::Index n = x.rows(), p = x.cols();
  if (y.size() != n || static_cast<Eigen::Index>(cluster.size()) != n || estimated < 1 || estimated > p)
    throw std::invalid_argument("random_effects_fit: x, y and cluster ids differ in length, or no column is estimated");
  std::map<int, Eigen::Index> order;   // id -> position (ascending)
  for (const int id : cluster) order.emplace(id, 0);
  Eigen::Index next = 0;
  for (auto& [id, g] : order) g = next++;
  if (tau2.size() != next || noise_sum_variance.size() != next ||
      (known_offset_variance.size() != 0 && known_offset_variance.size() != next))
    throw std::invalid_argument("random_effects_fit: tau2 and the noise's sum variances are not one per cluster");
  std::vector<Eigen::Index> group(static_cast<std::size_t>(n));
  Eigen::MatrixXd mean_x = Eigen::MatrixXd::Zero(next, p);
  Eigen::VectorXd mean_y = Eigen::VectorXd::Zero(next), rows = Eigen::VectorXd::Zero(next);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index g = order.at(cluster[static_cast<std::size_t>(k)]);
    group[static_cast<std::size_t>(k)] = g;
    mean_x.row(g) += x.row(k);
    mean_y(g) += y(k);
    rows(g) += 1.0;
  }
  mean_x.array().colwise() /= rows.array();
  mean_y.array() /= rows.array();
  RandomEffectsFit out;
  out.weights.resize(next);
  for (Eigen::Index g = 0; g < next; ++g) {
    const double m = noise_sum_variance(g) / (rows(g) * rows(g));
    if (!(m > 0.0) || !(tau2(g) >= 0.0)) throw std::invalid_argument("random_effects_fit: a cluster's noise or offset variance is not positive");
    out.weights(g) = m / (m + tau2(g) + (known_offset_variance.size() != 0 ? known_offset_variance(g) : 0.0));
  }
  Eigen::MatrixXd once(n, p), twice(n, p);   // X~ and X2
  Eigen::VectorXd y_once(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index g = group[static_cast<std::size_t>(k)];
    const double lambda = 1.0 - std::sqrt(out.weights(g));
    once.row(k) = x.row(k) - lambda * mean_x.row(g);
    twice.row(k) = x.row(k) - (1.0 - out.weights(g)) * mean_x.row(g);
    y_once(k) = y(k) - lambda * mean_y(g);
  }
  // Scaled to unit column norms: a bias and a square of a small input differ by orders.
  Eigen::VectorXd scale = once.colwise().norm().transpose();
  for (Eigen::Index j = 0; j < p; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  const Eigen::MatrixXd once_scaled = once * scale.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> fitted(once_scaled.leftCols(estimated));
  if (fitted.rank() < estimated) throw std::invalid_argument("random_effects_fit: the weighed columns are linearly dependent");
  out.theta = fitted.solve(y_once).cwiseQuotient(scale.head(estimated));
  const Eigen::MatrixXd b = GramFactor::from_rows(once).inverse_factor;
  const Eigen::MatrixXd noise_meat = twice.transpose() * noise_times(twice);
  Eigen::MatrixXd offsets_meat = Eigen::MatrixXd::Zero(p, p);
  for (Eigen::Index g = 0; g < next; ++g) {
    const Eigen::VectorXd sum = out.weights(g) * rows(g) * mean_x.row(g).transpose();   // X2' 1_g
    offsets_meat.noalias() += tau2(g) * sum * sum.transpose();
  }
  out.within = sandwich(b, noise_meat);
  out.covariance = out.within + sandwich(b, offsets_meat);
  return out;
}

RandomEffectsFit random_effects_fit(const Eigen::Ref<const Eigen::MatrixXd>& gram, const ClusterSums& sums,
                                    const Eigen::VectorXd& y_sums, Eigen::Index estimated, const Eigen::VectorXd& tau2,
                                    double sigma2, const Eigen::MatrixXd* sums_covariance) {
  const Eigen::Index p = gram.rows() - 1, g_count = static_cast<Eigen::Index>(sums.ids.size());
  if (sums_covariance != nullptr && (sums_covariance->rows() != g_count || sums_covariance->cols() != g_count))
    throw std::invalid_argument("random_effects_fit: the clusters' noise sums' covariance is not one row and column per cluster");
  if (gram.cols() != p + 1 || sums.columns.rows() != p || sums.columns.cols() != g_count || sums.rows.size() != g_count ||
      y_sums.size() != g_count || tau2.size() != g_count || estimated < 1 || estimated > p)
    throw std::invalid_argument("random_effects_fit: the Gram, the clusters' sums and tau2 differ in size, or no column is estimated");
  if (!(sigma2 > 0.0)) throw std::invalid_argument("random_effects_fit: a cluster's noise or offset variance is not positive");
  RandomEffectsFit out;
  out.weights.resize(g_count);
  Eigen::MatrixXd once = gram;            // [X~ y~]'[X~ y~]
  Eigen::MatrixXd twice = gram.topLeftCorner(p, p);   // X2'X2
  Eigen::MatrixXd offsets_meat = Eigen::MatrixXd::Zero(p, p);
  Eigen::MatrixXd weighed_means(p, g_count);   // S2 N^-1: column g is w_g m_g
  for (Eigen::Index g = 0; g < g_count; ++g) {
    const double n = sums.rows(g);
    // The noise's variance of the cluster's mean.
    const double m = sums_covariance != nullptr ? (*sums_covariance)(g, g) / (n * n) : sigma2 / n;
    if (!(m > 0.0) || !(tau2(g) >= 0.0)) throw std::invalid_argument("random_effects_fit: a cluster's noise or offset variance is not positive");
    const double w = m / (m + tau2(g));
    out.weights(g) = w;
    Eigen::VectorXd mean(p + 1);
    mean.head(p) = sums.columns.col(g) / n;
    mean(p) = y_sums(g) / n;
    const double lambda = 1.0 - std::sqrt(w);
    once.noalias() -= (2.0 * lambda - lambda * lambda) * n * mean * mean.transpose();
    twice.noalias() -= (2.0 * (1.0 - w) - (1.0 - w) * (1.0 - w)) * n * mean.head(p) * mean.head(p).transpose();
    const Eigen::VectorXd sum = w * sums.columns.col(g);   // X2' 1_g
    offsets_meat.noalias() += tau2(g) * sum * sum.transpose();
    weighed_means.col(g) = sum / n;
  }
  // The weighed columns, scaled to unit diagonal: dependent where the smallest eigenvalue is at
  // rounding's level (a column's square-root condition beyond 1e12).
  const Eigen::MatrixXd a = once.topLeftCorner(p, p);
  const Eigen::MatrixXd ae = a.topLeftCorner(estimated, estimated);
  Eigen::VectorXd scale = ae.diagonal().cwiseMax(0.0).cwiseSqrt();
  for (Eigen::Index j = 0; j < estimated; ++j)
    if (!(scale(j) > 0.0)) scale(j) = 1.0;
  const Eigen::MatrixXd scaled = scale.cwiseInverse().asDiagonal() * ae * scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (scaled + scaled.transpose()));
  if (!(eig.eigenvalues().minCoeff() > 1e-24 * eig.eigenvalues().maxCoeff()))
    throw std::invalid_argument("random_effects_fit: the weighed columns are linearly dependent");
  const Eigen::VectorXd rhs = once.col(p).head(estimated).cwiseQuotient(scale);
  out.theta = (eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose() * rhs)
                  .cwiseQuotient(scale);
  const Eigen::MatrixXd b = GramFactor::from_gram(a, sums.rows.sum()).inverse_factor;
  // X2'RX2 with R white within a cluster and the clusters' sums of covariance S: X2 = D + M, D the
  // rows' deviations from their cluster's mean and M the weighed means, so the meat is
  // sigma2 D'D + W S W' (D'M = 0, M'M = W N W'), semidefinite as the sandwich takes it.
  Eigen::MatrixXd noise_meat = sigma2 * twice;
  if (sums_covariance != nullptr) {
    const Eigen::MatrixXd between = weighed_means * sums.rows.asDiagonal() * weighed_means.transpose();   // S2 N^-1 S2'
    noise_meat += weighed_means * *sums_covariance * weighed_means.transpose() - sigma2 * between;
  }
  out.within = sandwich(b, 0.5 * (noise_meat + noise_meat.transpose()));
  out.covariance = out.within + sandwich(b, offsets_meat);
  return out;
}

std::optional<RandomEffectsFit> weighed_by_offsets(const ClusterOffsets& offsets, const Eigen::VectorXd& loading,
                                                   const Eigen::VectorXd& noise_sum_variance,
                                                   const std::function<RandomEffectsFit(const Eigen::VectorXd& tau2)>& fit,
                                                   const Eigen::VectorXd& known_offset_variance) {
  const Eigen::Index g_count = noise_sum_variance.size();
  if (g_count < 2 || (loading.size() != 0 && loading.size() != g_count) ||
      (known_offset_variance.size() != 0 && known_offset_variance.size() != g_count))
    return std::nullopt;
  Eigen::VectorXd tau2(g_count);
  for (Eigen::Index g = 0; g < g_count; ++g) {
    tau2(g) = offsets.tau2_common + offsets.tau2_per_loading * (loading.size() != 0 ? loading(g) : 0.0);
    if (!(noise_sum_variance(g) > 0.0)) return std::nullopt;
  }
  const Eigen::VectorXd offset_variance = known_offset_variance.size() != 0 ? Eigen::VectorXd(tau2 + known_offset_variance) : tau2;
  if (!(offset_variance.maxCoeff() > kDistinctOffsets * offset_variance.minCoeff())) return std::nullopt;
  std::optional<RandomEffectsFit> out;
  try {
    out = fit(tau2);
  } catch (const std::invalid_argument&) {
    return std::nullopt;   // the weighed columns are dependent
  }
  if (!(out->weights.maxCoeff() > kDistinctOffsets * out->weights.minCoeff())) return std::nullopt;
  if (!out->covariance.allFinite() || (out->covariance.diagonal().array() < 0.0).any()) return std::nullopt;
  return out;
}

}  // namespace inertia::ident
