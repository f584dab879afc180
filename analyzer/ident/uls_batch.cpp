#include "analyzer/ident/uls_batch.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <optional>
#include <ranges>
#include <vector>

#include <Eigen/Eigenvalues>

#include "analyzer/ident/row_products.hpp"
#include "analyzer/ident/symmetric.hpp"

namespace inertia::ident {
namespace {

std::string format_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// Position of `column` in rational.columns, or -1.
Index factor_index(const OutputMultiplied& rational, Index column) {
  const auto it = std::find(rational.columns.begin(), rational.columns.end(), column);
  return it == rational.columns.end() ? -1 : static_cast<Index>(it - rational.columns.begin());
}

/// The fit's linear form for the coefficients `theta` of phi's `columns`: b(k) = 1 + the
/// output-multiplied terms' theta_j p_b,j(k), and zeta(k) = y b - a, a(k) the other terms' sum
/// (ident/uls.hpp); the residual is zeta / b. factor_of(j): the index in `factors` of the j-th
/// column's output factor p_b,j, or -1 for a column that does not multiply the output.
struct LinearForm {
  Eigen::VectorXd zeta;
  Eigen::VectorXd b;   // empty where no column is output-multiplied: b = 1 on every row
  std::vector<Index> factor_of;
};

LinearForm linear_form(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                       std::span<const Index> columns, const Eigen::Ref<const Eigen::VectorXd>& theta,
                       const OutputMultiplied& rational, const Eigen::Ref<const Eigen::MatrixXd>& factors) {
  const Index n = phi.rows();
  const auto p = static_cast<Index>(columns.size());
  // Row blocks outermost: the block's accumulators stay in cache while each column segment
  // streams through once, so the pass reads every column once instead of re-reading three
  // N-vectors per column (the selection runs this once per candidate model; at N = 1e6 it is
  // memory-bound).
  std::vector<Index> fidx(static_cast<std::size_t>(p), -1);
  for (Index j = 0; j < p; ++j) fidx[static_cast<std::size_t>(j)] = factor_index(rational, columns[j]);
  constexpr Index kResidualBlock = 1024;
  if (std::all_of(fidx.begin(), fidx.end(), [](Index f) { return f < 0; })) {
    // A polynomial fit: zeta = y - Phi theta, each block's prediction summed in cache and taken
    // from y once (the same sums, in the same order, as below).
    Eigen::VectorXd zeta(n);
    Eigen::VectorXd prediction(std::min(kResidualBlock, n));
    for (Index k0 = 0; k0 < n; k0 += kResidualBlock) {
      const Index rows = std::min(kResidualBlock, n - k0);
      auto block = prediction.head(rows);
      block.setZero();
      for (Index j = 0; j < p; ++j) block.noalias() += theta(j) * phi.col(columns[j]).segment(k0, rows);
      zeta.segment(k0, rows) = y.segment(k0, rows) - block;
    }
    return {std::move(zeta), Eigen::VectorXd(), std::move(fidx)};
  }
  Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
  Eigen::VectorXd lin = Eigen::VectorXd::Zero(n);  // minus the output-multiplied terms' theta_j c_j
  for (Index k0 = 0; k0 < n; k0 += kResidualBlock) {
    const Index rows = std::min(kResidualBlock, n - k0);
    auto a_blk = a.segment(k0, rows);
    auto b_blk = b.segment(k0, rows);
    auto lin_blk = lin.segment(k0, rows);
    for (Index j = 0; j < p; ++j) {
      const Index c = columns[j];
      const double th = theta(j);
      const Index f = fidx[static_cast<std::size_t>(j)];
      if (f < 0) {
        a_blk.noalias() += th * phi.col(c).segment(k0, rows);
      } else {
        b_blk.noalias() += th * factors.col(f).segment(k0, rows);
        lin_blk.noalias() -= th * phi.col(c).segment(k0, rows);
      }
    }
  }
  lin += a;
  return {y - lin, std::move(b), std::move(fidx)};
}

// Rows per block in the data passes that build p x p products, so the temporaries stay small
// (a few MB) whatever N is.
constexpr Index kBlockRows = 4096;

/// Anderson mixing (type II, undamped) for a fixed point v = F(v) of a few coefficients: from
/// the iterate v_k and its image F(v_k), the next iterate F(v_k) - dF gamma, gamma the least
/// squares fit of the step g_k = F(v_k) - v_k by the last `depth` steps' differences dG (dF the
/// images' differences). A step larger than the smallest one seen starts the history again.
class AndersonMixing {
 public:
  explicit AndersonMixing(Index depth) : depth_(depth) {}

  void reset() {
    steps_.clear();
    images_.clear();
    smallest_ = std::numeric_limits<double>::infinity();
  }

  [[nodiscard]] Eigen::VectorXd next(const Eigen::VectorXd& v, const Eigen::VectorXd& fv) {
    const Eigen::VectorXd g = fv - v;
    const double norm = g.norm();
    if (!(norm <= smallest_)) reset();
    smallest_ = std::min(smallest_, norm);
    steps_.push_back(g);
    images_.push_back(fv);
    if (static_cast<Index>(steps_.size()) > depth_ + 1) {
      steps_.erase(steps_.begin());
      images_.erase(images_.begin());
    }
    const auto m = static_cast<Index>(steps_.size()) - 1;
    if (m == 0) return fv;
    Eigen::MatrixXd dg(g.size(), m), df(g.size(), m);
    for (Index j = 0; j < m; ++j) {
      dg.col(j) = steps_[std::size_t(j + 1)] - steps_[std::size_t(j)];
      df.col(j) = images_[std::size_t(j + 1)] - images_[std::size_t(j)];
    }
    const Eigen::VectorXd gamma = dg.colPivHouseholderQr().solve(g);
    return gamma.allFinite() ? Eigen::VectorXd(fv - df * gamma) : fv;
  }

 private:
  Index depth_;
  std::vector<Eigen::VectorXd> steps_, images_;
  double smallest_ = std::numeric_limits<double>::infinity();
};

/// True when 1 + c_1 q^-1 + ... + c_n q^-n has every root strictly inside the unit circle, so
/// its inverse filter is stable.
bool minimum_phase(const Eigen::VectorXd& c) {
  const Index n = c.size();
  if (n == 0) return true;
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(n, n);
  companion.row(0) = -c.transpose();
  for (Index i = 1; i < n; ++i) companion(i, i - 1) = 1.0;
  const Eigen::VectorXcd roots = Eigen::EigenSolver<Eigen::MatrixXd>(companion, false).eigenvalues();
  return roots.allFinite() && roots.cwiseAbs().maxCoeff() < 1.0;
}

/// The residuals the ELS passes converge to for the coefficients of one pass: the noise columns
/// e[k-i] built from the residuals themselves, eps(k) = (zeta_0(k) - sum_i c_i eps(k - i)) / b(k),
/// with zeta_0 = y b - a the process terms' part of the fit's linear form (linear_form) and the
/// residuals before the first row zero, as the passes take them. A plain pass turns the residuals
/// by C(q) - 1 once, so its error shrinks only by |C - 1| per pass, slowest at the frequencies
/// where that is near 1 (docs/validation.md has the passes it took); these residuals are that
/// fixed point for the coefficients at hand, and only the coefficients are left to settle. None
/// when C(q) is not minimum phase: the recursion would grow, and a plain pass is taken instead.
std::optional<Eigen::VectorXd> self_consistent_residuals(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                                         const Eigen::Ref<const Eigen::VectorXd>& y, Index p,
                                                         const OutputMultiplied& rational, const Eigen::MatrixXd& factors,
                                                         const Eigen::VectorXd& theta) {
  const Index n = x.rows(), n_e = theta.size() - p;
  const Eigen::VectorXd c = theta.tail(n_e);
  if (!minimum_phase(c)) return std::nullopt;
  std::vector<Index> columns(static_cast<std::size_t>(p));
  std::iota(columns.begin(), columns.end(), Index{0});
  const LinearForm form = linear_form(x, y, columns, theta.head(p), rational, factors);
  const Eigen::VectorXd& zeta = form.zeta;
  const Eigen::VectorXd& b = form.b;
  Eigen::VectorXd eps(n);
  // A chain of dependent steps, so its latency is its cost: without output-multiplied terms b is
  // 1 (linear_form leaves it empty) and the division is left out of the chain.
  const bool divides = b.size() > 0;
  for (Index k = 0; k < n; ++k) {
    double value = zeta(k);
    for (Index i = 1; i <= n_e && i <= k; ++i) value -= c(i - 1) * eps(k - i);
    eps(k) = divides ? value / b(k) : value;
  }
  if (!eps.allFinite()) return std::nullopt;
  return eps;
}

}  // namespace

bool UlsOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& s) {
    if (why != nullptr) *why = s;
    return false;
  };
  if (noise_lags < 0) return fail("noise_lags = " + std::to_string(noise_lags) + " is negative");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (max_noise_iterations < 1) return fail("max_noise_iterations must be >= 1");
  if (!(tolerance > 0.0)) return fail("tolerance must be > 0");
  if (!(max_correction > 0.0 && max_correction < 1.0))
    return fail("max_correction = " + format_double(max_correction) + " is outside (0, 1)");
  if (!(min_rcond > 0.0 && min_rcond < 1.0))
    return fail("min_rcond = " + format_double(min_rcond) + " is outside (0, 1)");
  if (!(null_vector_share > 0.0 && null_vector_share <= 1.0))
    return fail("null_vector_share is outside (0, 1]");
  return true;
}

Eigen::VectorXd linear_form_signs(Index columns, std::span<const Index> output_multiplied_columns) {
  Eigen::VectorXd sign = Eigen::VectorXd::Ones(columns);
  for (const Index c : output_multiplied_columns) {
    if (c < 0 || c >= columns) throw std::invalid_argument("linear_form_signs: an output-multiplied column outside the columns");
    sign[c] = -1.0;
  }
  return sign;
}

UlsStatistics UlsStatistics::from_data(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                       const Eigen::Ref<const Eigen::VectorXd>& y,
                                       std::span<const Index> output_multiplied_columns,
                                       const Eigen::Ref<const Eigen::MatrixXd>& factors) {
  const Index n = phi.rows();
  const Index p = phi.cols();
  UlsStatistics s;
  s.samples = n;
  // SYRK (half the flops of a GEMM): the only O(N p^2) work of a polynomial fit.
  const Eigen::MatrixXd g = ident::gram(phi);
  const Eigen::VectorXd sign = linear_form_signs(p, output_multiplied_columns);
  s.scale = (g.diagonal() / static_cast<double>(std::max<Index>(n, 1))).cwiseSqrt();
  const Eigen::VectorXd inv =
      (s.scale.array() > 0.0).select(sign.array() / s.scale.array(), sign.array()).matrix();
  s.gram = inv.asDiagonal() * g * inv.asDiagonal();
  s.cross = inv.asDiagonal() * ident::cross_product(phi, y);
  s.yy = y.squaredNorm();
  s.s11 = static_cast<double>(n);
  // Denominator positions ascending; factors follow output_multiplied_columns' order.
  std::vector<std::pair<Index, Index>> den;  // (position, factor column)
  for (std::size_t t = 0; t < output_multiplied_columns.size(); ++t)
    den.emplace_back(output_multiplied_columns[t], static_cast<Index>(t));
  std::sort(den.begin(), den.end());
  const Index q = static_cast<Index>(den.size());
  Eigen::MatrixXd f(n, q);
  Eigen::VectorXd fscale(q);
  for (Index a = 0; a < q; ++a) {
    s.denominator.push_back(den[a].first);
    f.col(a) = factors.col(den[a].second);
    const double sc = s.scale[den[a].first];
    fscale[a] = sc > 0.0 ? 1.0 / sc : 1.0;
  }
  s.den_gram = fscale.asDiagonal() * ident::gram(f) * fscale.asDiagonal();
  s.den_sum = fscale.asDiagonal() * f.colwise().sum().transpose();
  return s;
}

UlsStatistics UlsStatistics::from_gram(const Eigen::Ref<const Eigen::MatrixXd>& augmented, Index samples,
                                       std::span<const Index> output_multiplied_columns,
                                       const Eigen::Ref<const Eigen::MatrixXd>& factor_gram,
                                       const Eigen::Ref<const Eigen::VectorXd>& factor_sum) {
  const Index p = augmented.rows() - 1;
  const Index q = static_cast<Index>(output_multiplied_columns.size());
  if (augmented.cols() != p + 1 || p < 0) throw std::invalid_argument("UlsStatistics::from_gram: the Gram matrix is not square");
  if (q > 0 && (factor_gram.rows() != q || factor_gram.cols() != q || factor_sum.size() != q))
    throw std::invalid_argument("UlsStatistics::from_gram: factor statistics must be q x q and q");
  UlsStatistics s;
  s.samples = samples;
  const Eigen::MatrixXd g = augmented.topLeftCorner(p, p);
  const Eigen::VectorXd sign = linear_form_signs(p, output_multiplied_columns);
  s.scale = (g.diagonal().cwiseMax(0.0) / static_cast<double>(std::max<Index>(samples, 1))).cwiseSqrt();
  const Eigen::VectorXd inv =
      (s.scale.array() > 0.0).select(sign.array() / s.scale.array(), sign.array()).matrix();
  s.gram = inv.asDiagonal() * g * inv.asDiagonal();
  s.cross = inv.asDiagonal() * augmented.col(p).head(p);
  s.yy = augmented(p, p);
  s.s11 = static_cast<double>(samples);
  std::vector<std::pair<Index, Index>> den;
  for (std::size_t t = 0; t < output_multiplied_columns.size(); ++t)
    den.emplace_back(output_multiplied_columns[t], static_cast<Index>(t));
  std::sort(den.begin(), den.end());
  s.den_gram.resize(q, q);
  s.den_sum.resize(q);
  for (Index a = 0; a < q; ++a) {
    s.denominator.push_back(den[a].first);
    const double sa = s.scale[den[a].first] > 0.0 ? 1.0 / s.scale[den[a].first] : 1.0;
    s.den_sum[a] = sa * factor_sum[den[a].second];
    for (Index b = 0; b < q; ++b) {
      const double sb = s.scale[den[b].first] > 0.0 ? 1.0 / s.scale[den[b].first] : 1.0;
      s.den_gram(a, b) = sa * sb * factor_gram(den[a].second, den[b].second);
    }
  }
  return s;
}

UlsStatistics UlsStatistics::subset(std::span<const Index> positions) const {
  UlsStatistics s;
  const Index m = static_cast<Index>(positions.size());
  s.samples = samples;
  s.yy = yy;
  s.s11 = s11;
  s.scale.resize(m);
  s.gram.resize(m, m);
  s.cross.resize(m);
  std::vector<Index> old_den;
  for (Index i = 0; i < m; ++i) {
    const Index pi = positions[i];
    s.scale[i] = scale[pi];
    s.cross[i] = cross[pi];
    for (Index j = 0; j < m; ++j) s.gram(i, j) = gram(pi, positions[j]);
    const auto it = std::find(denominator.begin(), denominator.end(), pi);
    if (it != denominator.end()) {
      s.denominator.push_back(i);
      old_den.push_back(static_cast<Index>(it - denominator.begin()));
    }
  }
  const Index q = static_cast<Index>(old_den.size());
  s.den_gram.resize(q, q);
  s.den_sum.resize(q);
  for (Index a = 0; a < q; ++a) {
    s.den_sum[a] = den_sum[old_den[a]];
    for (Index b = 0; b < q; ++b) s.den_gram(a, b) = den_gram(old_den[a], old_den[b]);
  }
  return s;
}

UlsSolution solve_uls(const UlsStatistics& stats, const std::vector<std::string>& labels,
                      const UlsOptions& options) {
  const Index p = stats.terms();
  const double n = static_cast<double>(stats.samples);
  UlsSolution out;
  out.theta = Eigen::VectorXd::Zero(p);
  if (p == 0) {
    out.zeta_energy = stats.yy;
    out.sigma2 = stats.yy / std::max(n, 1.0);
    out.condition_number = 1.0;
    out.converged = true;
    return out;
  }
  auto label = [&labels](Index j) {
    return j < static_cast<Index>(labels.size()) ? labels[j] : "column " + std::to_string(j);
  };
  for (Index j = 0; j < p; ++j) {
    if (!(stats.scale[j] > 0.0)) {
      throw IdentifiabilityError("unidentifiable term set: '" + label(j) + "' is identically zero",
                                 {label(j)}, 0.0);
    }
  }
  // Unit-diagonal correlation-like matrix: its eigenvalues measure collinearity directly.
  const Eigen::MatrixXd unit = stats.gram / n;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(unit);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double lmax = lambda[p - 1];
  const double rcond = lmax > 0.0 ? std::max(lambda[0], 0.0) / lmax : 0.0;
  out.condition_number = rcond > 0.0 ? 1.0 / rcond : std::numeric_limits<double>::infinity();
  if (!(rcond >= options.min_rcond)) {
    // Name every column that carries weight in a null-space direction (there may be several).
    std::vector<bool> involved(static_cast<std::size_t>(p), false);
    std::string vectors;
    for (Index k = 0; k < p && !(lambda[k] > options.min_rcond * lmax); ++k) {
      const Eigen::VectorXd v = eig.eigenvectors().col(k);
      const double vmax = v.cwiseAbs().maxCoeff();
      std::string combo;
      for (Index j = 0; j < p; ++j) {
        if (std::abs(v[j]) >= options.null_vector_share * vmax) {
          involved[static_cast<std::size_t>(j)] = true;
          combo += (combo.empty() ? "" : " + ") + format_double(v[j]) + "*(" + label(j) + ")";
        }
      }
      vectors += (vectors.empty() ? "" : "; ") + combo + " ~ 0";
    }
    std::vector<std::string> names;
    std::string list;
    for (Index j = 0; j < p; ++j) {
      if (involved[static_cast<std::size_t>(j)]) {
        names.push_back(label(j));
        list += (list.empty() ? "" : ", ") + label(j);
      }
    }
    throw IdentifiabilityError("unidentifiable term set: {" + list +
                                   "} are linearly dependent (reciprocal condition " +
                                   format_double(rcond) + " < " + format_double(options.min_rcond) +
                                   " of the RMS-scaled Phi'Phi; scaled null vector " + vectors + ")",
                               std::move(names), rcond);
  }
  // R_s^-1 from the eigen-decomposition (already computed, and well conditioned past the check).
  const Eigen::MatrixXd r_inv = eig.eigenvectors() * lambda.cwiseInverse().asDiagonal() *
                                eig.eigenvectors().transpose() / n;
  Eigen::VectorXd theta = r_inv * stats.cross;
  const Eigen::VectorXd inv_scale = stats.scale.cwiseInverse();
  out.gram_inverse = inv_scale.asDiagonal() * r_inv * inv_scale.asDiagonal();

  const std::vector<Index>& den = stats.denominator;
  const Index q = static_cast<Index>(den.size());
  auto zeta_energy = [&stats](const Eigen::VectorXd& th) {
    return std::max(stats.yy - 2.0 * th.dot(stats.cross) + th.dot(stats.gram * th), 0.0);
  };
  if (q == 0) {
    // Polynomial model: Psi = 0, the correction vanishes and ULS is LS (b == 1, sum b^2 = N).
    out.zeta_energy = zeta_energy(theta);
    out.sigma2 = out.zeta_energy / stats.s11;
    out.iterations = 1;
    out.converged = true;
    out.corrected_inverse = out.gram_inverse;
    out.theta = inv_scale.cwiseProduct(theta);
    return out;
  }
  // PD guard: only the q x q block of R^-1 D matters.
  Eigen::MatrixXd r_inv_bb(q, q);
  for (Index a = 0; a < q; ++a)
    for (Index b = 0; b < q; ++b) r_inv_bb(a, b) = r_inv(den[a], den[b]);
  const Eigen::EigenSolver<Eigen::MatrixXd> guard(r_inv_bb * stats.den_gram, false);
  const double rho = guard.eigenvalues().real().maxCoeff();
  const double sigma2_max =
      rho > 0.0 ? options.max_correction / rho : std::numeric_limits<double>::infinity();

  Eigen::MatrixXd m(p, p);
  Eigen::VectorXd rhs(p);
  Eigen::VectorXd theta_b(q);
  Eigen::LDLT<Eigen::MatrixXd> ldlt(p);
  double sigma2 = 0.0;
  for (int it = 1; it <= options.max_iterations; ++it) {
    for (Index a = 0; a < q; ++a) theta_b[a] = theta[den[a]];
    const double b_energy =
        stats.s11 + 2.0 * theta_b.dot(stats.den_sum) + theta_b.dot(stats.den_gram * theta_b);
    double sigma2_new = b_energy > 0.0 ? zeta_energy(theta) / b_energy : 0.0;
    sigma2_new = std::clamp(sigma2_new, 0.0, sigma2_max);
    m = stats.gram;
    rhs = stats.cross;
    for (Index a = 0; a < q; ++a) {
      rhs[den[a]] += sigma2_new * stats.den_sum[a];
      for (Index b = 0; b < q; ++b) m(den[a], den[b]) -= sigma2_new * stats.den_gram(a, b);
    }
    ldlt.compute(m);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) {
      throw std::runtime_error("ULS: corrected normal matrix R - sigma^2 Psi is not positive "
                               "definite at sigma^2 = " + format_double(sigma2_new));
    }
    const Eigen::VectorXd theta_new = ldlt.solve(rhs);
    const bool small_step = (theta_new - theta).norm() <= options.tolerance * theta_new.norm();
    const bool small_sigma = std::abs(sigma2_new - sigma2) <= options.tolerance * sigma2_new;
    theta = theta_new;
    sigma2 = sigma2_new;
    out.iterations = it;
    if (small_step && small_sigma) {
      out.converged = true;
      break;
    }
  }
  out.sigma2 = sigma2;
  out.zeta_energy = zeta_energy(theta);
  const Eigen::MatrixXd m_inv = ldlt.solve(Eigen::MatrixXd::Identity(p, p));
  out.corrected_inverse = inv_scale.asDiagonal() * m_inv * inv_scale.asDiagonal();
  out.theta = inv_scale.cwiseProduct(theta);
  return out;
}

Eigen::MatrixXd denominator_factors(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                                    const Eigen::Ref<const Eigen::VectorXd>& y,
                                    const OutputMultiplied& rational,
                                    const std::vector<std::string>& labels) {
  const Index n = phi.rows();
  const Index q = static_cast<Index>(rational.columns.size());
  for (Index c : rational.columns) {
    if (c < 0 || c >= phi.cols())
      throw std::invalid_argument("output-multiplied column " + std::to_string(c) +
                                  " is outside the regression matrix");
  }
  if (rational.factors.size() > 0) {
    if (rational.factors.rows() != n || rational.factors.cols() != q)
      throw std::invalid_argument("output-multiplied factors must be N x q (" + std::to_string(n) +
                                  " x " + std::to_string(q) + ")");
    return rational.factors;
  }
  Eigen::MatrixXd f(n, q);
  for (Index t = 0; t < q; ++t) {
    const Index c = rational.columns[static_cast<std::size_t>(t)];
    for (Index k = 0; k < n; ++k) {
      if (y[k] == 0.0) {
        const std::string name =
            c < static_cast<Index>(labels.size()) ? labels[c] : "column " + std::to_string(c);
        throw std::invalid_argument("cannot recover the factor of output-multiplied term '" + name +
                                    "' at sample " + std::to_string(k) +
                                    " (y = 0); pass OutputMultiplied::factors");
      }
      f(k, t) = phi(k, c) / y[k];
    }
  }
  return f;
}

UlsResult solved_terms(const UlsSolution& solution, const std::vector<std::string>& labels, std::span<const Index> columns) {
  UlsResult out;
  out.process_terms = static_cast<Index>(columns.size());
  out.theta = solution.theta;
  out.sigma2 = solution.sigma2;
  out.iterations = solution.iterations;
  out.converged = solution.converged;
  out.condition_number = solution.condition_number;
  for (Index c : columns) out.labels.push_back(labels[static_cast<std::size_t>(c)]);
  return out;
}

UlsResult finish_uls(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                     const Eigen::Ref<const Eigen::VectorXd>& y,
                     const std::vector<std::string>& labels, std::span<const Index> columns,
                     const OutputMultiplied& rational,
                     const Eigen::Ref<const Eigen::MatrixXd>& factors, const UlsSolution& solution,
                     const UlsOptions& options) {
  const Index n = phi.rows();
  const Index p = static_cast<Index>(columns.size());
  UlsResult out = solved_terms(solution, labels, columns);

  const auto [zeta, b, fidx] = linear_form(phi, y, columns, solution.theta, rational, factors);
  // eps = zeta / b: for raw rows the same as y - a / b (there c_j = y p_b,j, so y b - a = zeta),
  // and still right for rows through the noise model's A(q) (prewhitening.hpp), where the filtered
  // c_j is not the filtered y times the (unfiltered) factor: y - a / b there leaves a misfit that
  // follows the output-multiplied columns, far above rounding on a noise-free gyro on a rate table
  // (docs/validation.md, 'Evidence behind choices in the code').
  out.residuals = b.size() == 0 ? zeta : Eigen::VectorXd(zeta.cwiseQuotient(b));
  const double dof = static_cast<double>(std::max<Index>(n - p, 1));
  out.residual_variance = out.residuals.squaredNorm() / dof;
  const bool rational_fit =
      std::any_of(fidx.begin(), fidx.end(), [](Index f) { return f >= 0; });
  CovarianceKind kind = options.covariance;
  if (kind == CovarianceKind::Auto)
    kind = rational_fit ? CovarianceKind::Sandwich : CovarianceKind::Classical;
  out.covariance_kind = kind;
  if (kind == CovarianceKind::Classical) {
    // The linear-form residual zeta is what the regression leaves; for b == 1 it equals eps.
    out.covariance = (zeta.squaredNorm() / dof) * solution.gram_inverse;
  } else {
    // The sandwich's meat: g_k = phi_lin(k) zeta(k) + sigma^2 [0; p_b(k) b(k)],  S = sum g g'.
    Eigen::MatrixXd s = Eigen::MatrixXd::Zero(p, p);
    Eigen::MatrixXd g(std::min(kBlockRows, n), p);
    for (Index k0 = 0; k0 < n; k0 += kBlockRows) {
      const Index rows = std::min(kBlockRows, n - k0);
      for (Index j = 0; j < p; ++j) {
        const Index c = columns[j];
        const Index f = fidx[static_cast<std::size_t>(j)];
        if (f < 0) {
          g.col(j).head(rows) = phi.col(c).segment(k0, rows).cwiseProduct(zeta.segment(k0, rows));
        } else {
          g.col(j).head(rows) =
              -phi.col(c).segment(k0, rows).cwiseProduct(zeta.segment(k0, rows)) +
              solution.sigma2 *
                  factors.col(f).segment(k0, rows).cwiseProduct(b.segment(k0, rows));
        }
      }
      s.selfadjointView<Eigen::Lower>().rankUpdate(g.topRows(rows).transpose());
    }
    mirror_lower(s);
    out.covariance = solution.corrected_inverse * s * solution.corrected_inverse;
  }
  out.std_dev = out.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  return out;
}

namespace {

/// uls_batch's problem, checked: the columns `columns` of phi (all when empty) in a compact copy
/// [Phi(:, cols), E] with room for the noise columns E, which the ELS passes rebuild in place.
/// Without noise terms, columns that are Phi's first p are used where they are (no copy of the
/// stack).
struct CompactProblem {
  Index p = 0;                        // process columns
  bool in_place = false;              // x is phi's first p columns, not a copy
  Eigen::MatrixXd x;                  // the copy (empty in place)
  std::vector<std::string> labels;    // of x's columns, noise columns included
  OutputMultiplied rational;          // x's output-multiplied columns
  Eigen::MatrixXd factors;            // their p_b, in rational's order

  [[nodiscard]] Eigen::Ref<const Eigen::MatrixXd> process(const Eigen::Ref<const Eigen::MatrixXd>& phi) const {
    return in_place ? Eigen::Ref<const Eigen::MatrixXd>(phi.leftCols(p)) : Eigen::Ref<const Eigen::MatrixXd>(x.leftCols(p));
  }
};

CompactProblem compact_problem(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                               const std::vector<std::string>& labels, const OutputMultiplied& rational,
                               const UlsOptions& options, std::span<const Index> columns) {
  std::string why;
  if (!options.is_valid(&why)) throw std::invalid_argument("ULS options: " + why);
  if (static_cast<Index>(labels.size()) != phi.cols())
    throw std::invalid_argument("ULS: " + std::to_string(labels.size()) + " labels for " +
                                std::to_string(phi.cols()) + " columns");
  if (y.size() != phi.rows())
    throw std::invalid_argument("ULS: y has " + std::to_string(y.size()) + " samples, Phi " +
                                std::to_string(phi.rows()) + " rows");
  std::vector<Index> cols(columns.begin(), columns.end());
  if (cols.empty()) {
    cols.resize(static_cast<std::size_t>(phi.cols()));
    std::iota(cols.begin(), cols.end(), Index{0});
  }
  CompactProblem out;
  const Index p = out.p = static_cast<Index>(cols.size());
  const Index n_e = options.noise_lags;
  if (phi.rows() <= p + n_e)
    throw std::invalid_argument("ULS: " + std::to_string(phi.rows()) + " samples for " +
                                std::to_string(p + n_e) + " parameters");
  const Eigen::MatrixXd all_factors = denominator_factors(phi, y, rational, labels);
  const Index n = phi.rows();
  out.in_place = n_e == 0 && std::equal(cols.begin(), cols.end(), std::views::iota(Index{0}, p).begin());
  out.x.resize(out.in_place ? 0 : n, out.in_place ? 0 : p + n_e);
  std::vector<Index> xden_cols;  // columns of all_factors in out.rational's order
  for (Index j = 0; j < p; ++j) {
    const Index c = cols[static_cast<std::size_t>(j)];
    if (c < 0 || c >= phi.cols()) throw std::invalid_argument("ULS: column index out of range");
    if (!out.in_place) out.x.col(j) = phi.col(c);
    out.labels.push_back(labels[static_cast<std::size_t>(c)]);
    const Index f = factor_index(rational, c);
    if (f >= 0) {
      out.rational.columns.push_back(j);
      xden_cols.push_back(f);
    }
  }
  out.factors.resize(n, static_cast<Index>(xden_cols.size()));
  for (Index t = 0; t < out.factors.cols(); ++t) out.factors.col(t) = all_factors.col(xden_cols[static_cast<std::size_t>(t)]);
  for (Index i = 1; i <= n_e; ++i) out.labels.push_back("e[k-" + std::to_string(i) + "]");
  return out;
}

}  // namespace

Eigen::VectorXd uls_coefficients(const Eigen::Ref<const Eigen::MatrixXd>& phi, const Eigen::Ref<const Eigen::VectorXd>& y,
                                 const std::vector<std::string>& labels, const OutputMultiplied& rational,
                                 const UlsOptions& options, std::span<const Index> columns) {
  if (options.noise_lags > 0) return uls_batch(phi, y, labels, rational, options, columns).theta;
  const CompactProblem c = compact_problem(phi, y, labels, rational, options, columns);
  return solve_uls(UlsStatistics::from_data(c.process(phi), y, c.rational.columns, c.factors), c.labels, options).theta;
}

UlsResult uls_batch(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                    const Eigen::Ref<const Eigen::VectorXd>& y,
                    const std::vector<std::string>& labels, const OutputMultiplied& rational,
                    const UlsOptions& options, std::span<const Index> columns) {
  CompactProblem c = compact_problem(phi, y, labels, rational, options, columns);
  const Index p = c.p;
  const Index n_e = options.noise_lags;
  const Index n = phi.rows();
  Eigen::MatrixXd& x = c.x;
  const std::vector<std::string>& xlabels = c.labels;
  const OutputMultiplied& xr = c.rational;
  const Eigen::MatrixXd& xf = c.factors;
  std::vector<Index> xcols(static_cast<std::size_t>(p));
  std::iota(xcols.begin(), xcols.end(), Index{0});

  // Process-only fit first: it gives the residuals the noise columns are built from.
  const Eigen::Ref<const Eigen::MatrixXd> process = c.process(phi);
  UlsStatistics stats = UlsStatistics::from_data(process, y, xr.columns, xf);
  UlsSolution sol = solve_uls(stats, xlabels, options);
  UlsResult res = finish_uls(process, y, xlabels, xcols, xr, xf, sol, options);
  if (n_e == 0) return res;

  // ELS: rebuild e[k-i] from the current residuals and refit until stable. Only the noise columns
  // E change from pass to pass: the augmented Gram [Phi E y]'[Phi E y] keeps its Phi and y part,
  // formed once, and each pass forms E's rows and columns (O(N p n_e), not O(N p^2)).
  const Index a = p + n_e + 1;   // augmented size; y is the last column
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(a, a);
  {
    augmented.topLeftCorner(p, p) = ident::gram(x.leftCols(p));
    augmented.col(a - 1).head(p) = ident::cross_product(x.leftCols(p), y);
    augmented.row(a - 1).head(p) = augmented.col(a - 1).head(p).transpose();
    augmented(a - 1, a - 1) = y.squaredNorm();
  }
  const Eigen::MatrixXd factor_gram = ident::gram(xf);
  const Eigen::VectorXd factor_sum = xf.colwise().sum().transpose();
  xcols.resize(static_cast<std::size_t>(p + n_e));
  std::iota(xcols.begin(), xcols.end(), Index{0});
  Eigen::VectorXd previous = Eigen::VectorXd::Zero(p + n_e);
  previous.head(p) = res.theta;
  int total_iterations = res.iterations;
  bool converged = false;
  double last_change = 0.0;
  int pass = 0;
  Eigen::VectorXd residuals = res.residuals;   // what the pass's noise columns are built from
  AndersonMixing mixing(3);
  Eigen::VectorXd theta_in;   // the coefficients `residuals` are self-consistent for (none: a fit's own)
  for (pass = 1; pass <= options.max_noise_iterations; ++pass) {
    for (Index i = 1; i <= n_e; ++i) {
      x.col(p + i - 1).head(std::min(i, n)).setZero();  // residuals before the record: 0
      if (n > i) x.col(p + i - 1).tail(n - i) = residuals.head(n - i);
    }
    const auto e = x.middleCols(p, n_e);
    augmented.block(0, p, p, n_e) = ident::cross_product(x.leftCols(p), e);
    augmented.block(p, 0, n_e, p) = augmented.block(0, p, p, n_e).transpose();
    augmented.block(p, p, n_e, n_e) = ident::gram(e);
    augmented.col(a - 1).segment(p, n_e) = ident::cross_product(e, y);
    augmented.row(a - 1).segment(p, n_e) = augmented.col(a - 1).segment(p, n_e).transpose();
    stats = UlsStatistics::from_gram(augmented, n, xr.columns, factor_gram, factor_sum);
    sol = solve_uls(stats, xlabels, options);
    total_iterations += sol.iterations;
    const double change = (sol.theta - previous).norm() / std::max(sol.theta.norm(), std::numeric_limits<double>::min());
    const bool small = change <= options.tolerance;
    last_change = change;
    previous = sol.theta;
    // Only the pass that ends the fit needs its residuals and covariance (a pass over the rows):
    // the passes before it carry their coefficients alone.
    if (small && sol.converged) {
      res = finish_uls(x, y, xlabels, xcols, xr, xf, sol, options);
      converged = true;
      break;
    }
    if (pass == options.max_noise_iterations) {
      res = finish_uls(x, y, xlabels, xcols, xr, xf, sol, options);
      break;
    }
    // The next pass's residuals: self-consistent for coefficients mixed from the last passes'.
    const Eigen::VectorXd next = theta_in.size() == 0 ? sol.theta : mixing.next(theta_in, sol.theta);
    if (std::optional<Eigen::VectorXd> consistent = self_consistent_residuals(x, y, p, xr, xf, next)) {
      residuals = std::move(*consistent);
      theta_in = next;
    } else {
      residuals = finish_uls(x, y, xlabels, xcols, xr, xf, sol, options).residuals;   // a plain pass: this fit's own
      theta_in.resize(0);
      mixing.reset();
    }
  }
  res.process_terms = p;
  res.iterations = total_iterations;
  res.noise_iterations = std::min(pass, options.max_noise_iterations);
  res.noise_last_change = last_change;
  res.converged = converged;
  return res;
}

std::optional<std::size_t> column_to_leave(const IdentifiabilityError& e, const std::vector<std::string>& labels,
                                           const std::function<bool(std::size_t)>& kept) {
  std::optional<std::size_t> out;
  for (std::size_t j = 0; j < labels.size(); ++j)
    if (!kept(j) && std::find(e.labels().begin(), e.labels().end(), labels[j]) != e.labels().end()) out = j;
  return out;
}

}  // namespace inertia::ident
