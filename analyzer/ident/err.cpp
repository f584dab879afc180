#include "analyzer/ident/err.hpp"

#include <algorithm>
#include <stdexcept>

#include "analyzer/ident/row_products.hpp"

namespace inertia::ident {

ErrGram::ErrGram(Eigen::Index terms) : gram_(Eigen::MatrixXd::Zero(terms + 1, terms + 1)) {}

void ErrGram::add(const Eigen::Ref<const Eigen::MatrixXd>& phi_block,
                  const Eigen::Ref<const Eigen::VectorXd>& y_block) {
  const Eigen::Index p = terms();
  if (phi_block.cols() != p || y_block.size() != phi_block.rows())
    throw std::invalid_argument("ErrGram::add: block sizes do not match");
  // SYRK on the lower triangle (half the flops of a GEMM), then mirror so users see a full matrix.
  gram_.topLeftCorner(p, p) += ident::gram(phi_block);
  gram_.row(p).head(p) += ident::cross_product(phi_block, y_block).transpose();
  gram_(p, p) += y_block.squaredNorm();
  gram_.col(p).head(p) = gram_.row(p).head(p).transpose();
  samples_ += phi_block.rows();
}

ErrGram ErrGram::from_data(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                           const Eigen::Ref<const Eigen::VectorXd>& y) {
  ErrGram g(phi.cols());
  g.add(phi, y);
  return g;
}

namespace {

// Forward orthogonal ranking on inner products, left-looking: orthogonalizing against the
// selected columns needs only the Gram columns of those columns, G(:, m) for each selected m, so
// the rest of G is never formed. `diagonal` is diag(G) over the candidates, `y_column` is G(:, Y)
// (length p + 1, Y'Y last), and `gram_column(m)` returns G(:, m) (length p + 1). Column j of `l`
// is the selected column's G column after the Schur complements of the earlier selections,
// divided by the square root of its pivot: the Cholesky factor of G restricted to the selection.
template <class GramColumn>
ErrRanking rank_on_columns(const Eigen::VectorXd& diagonal, const Eigen::VectorXd& y_column,
                           GramColumn&& gram_column, const ErrOptions& options) {
  const Eigen::Index p = diagonal.size();
  Eigen::VectorXd energy = diagonal;    // G(j, j) after the Schur complements so far
  Eigen::VectorXd toward_y = y_column;  // G(j, Y) likewise, and G(Y, Y) last
  const Eigen::Index limit = options.max_terms < 0 ? p : std::min(options.max_terms, p);
  Eigen::MatrixXd l(p + 1, std::max<Eigen::Index>(limit, static_cast<Eigen::Index>(options.forced.size())));
  Eigen::Index selected = 0;
  std::vector<bool> used(static_cast<std::size_t>(p), false);
  ErrRanking out;
  const double total = y_column(p);
  out.reference_energy = total;
  std::vector<double> errs;

  const auto explained = [&](Eigen::Index j) { return toward_y[j] * toward_y[j] / energy[j]; };
  auto dependent = [&](Eigen::Index j) {
    return !(energy[j] > options.dependence_tolerance * diagonal[j]) || !(diagonal[j] > 0.0);
  };
  auto select = [&](Eigen::Index m, double reference) {
    const double err = reference > 0.0 ? toward_y[m] * toward_y[m] / (energy[m] * reference) : 0.0;
    out.order.push_back(m);
    errs.push_back(err);
    used[static_cast<std::size_t>(m)] = true;
    Eigen::VectorXd col = gram_column(m);
    col.noalias() -= l.leftCols(selected) * l.row(m).head(selected).transpose();
    col /= std::sqrt(energy[m]);
    energy -= col.head(p).cwiseAbs2();
    toward_y -= col * col(p);
    l.col(selected++) = col;
    // A column whose preferred form this is, and which explains next to nothing once it is in,
    // has nothing of its own: it is not ranked.
    if (options.preferred.empty() || options.tie_energy <= 0.0) return;
    for (Eigen::Index j = 0; j < p; ++j) {
      if (options.preferred[static_cast<std::size_t>(j)] != m || used[static_cast<std::size_t>(j)]) continue;
      if (!dependent(j) && explained(j) >= options.tie_energy) continue;
      out.dependent.push_back(j);
      used[static_cast<std::size_t>(j)] = true;
    }
  };

  for (Eigen::Index m : options.forced) {
    if (m < 0 || m >= p) throw std::invalid_argument("err_rank: forced column out of range");
    if (used[static_cast<std::size_t>(m)]) continue;
    if (dependent(m)) {
      out.dependent.push_back(m);
      used[static_cast<std::size_t>(m)] = true;
      continue;
    }
    select(m, total);
  }
  out.forced_count = out.order.size();
  if (options.reference == ErrReference::AfterForced) out.reference_energy = toward_y(p);
  const double reference = out.reference_energy;
  while (static_cast<Eigen::Index>(out.order.size()) < limit) {
    Eigen::Index best = -1;
    double best_err = -1.0;
    for (Eigen::Index j = 0; j < p; ++j) {
      if (used[static_cast<std::size_t>(j)]) continue;
      if (dependent(j)) {
        out.dependent.push_back(j);
        used[static_cast<std::size_t>(j)] = true;
        continue;
      }
      const double err = toward_y[j] * toward_y[j] / (energy[j] * (reference > 0.0 ? reference : 1.0));
      if (err > best_err) {
        best_err = err;
        best = j;
      }
    }
    if (best < 0) break;
    if (!options.preferred.empty()) {
      const Eigen::Index alternative = options.preferred[static_cast<std::size_t>(best)];
      if (alternative >= 0 && !used[static_cast<std::size_t>(alternative)] && !dependent(alternative) &&
          explained(best) - explained(alternative) < options.tie_energy)
        best = alternative;
    }
    select(best, reference);
  }
  std::sort(out.dependent.begin(), out.dependent.end());
  out.err = Eigen::Map<const Eigen::VectorXd>(errs.data(), static_cast<Eigen::Index>(errs.size()));
  const std::size_t first = options.reference == ErrReference::AfterForced ? out.forced_count : 0;
  out.unexplained = 1.0 - out.err.tail(out.err.size() - static_cast<Eigen::Index>(first)).sum();
  return out;
}

}  // namespace

ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& gram, const ErrOptions& options) {
  const Eigen::Index p = gram.rows() - 1;
  if (p < 0 || gram.cols() != p + 1) throw std::invalid_argument("err_rank: Gram matrix not square");
  return rank_on_columns(gram.diagonal().head(p), gram.col(p),
                         [&](Eigen::Index m) -> Eigen::VectorXd { return gram.col(m); }, options);
}

ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                    const Eigen::Ref<const Eigen::VectorXd>& y, const ErrOptions& options) {
  const Eigen::Index p = phi.cols();
  if (y.size() != phi.rows()) throw std::invalid_argument("err_rank: phi and y differ in length");
  const Eigen::Index wanted = std::max<Eigen::Index>(options.max_terms, static_cast<Eigen::Index>(options.forced.size()));
  // The Gram matrix is one level-3 SYRK; the left-looking ranking costs one memory-bound pass
  // per selected term, so the passes win while few of many terms are wanted: 3.5 (k + 1) <= p.
  // The timings of both (peer_frols_compare, bench_ident_err) are in docs/validation.md,
  // 'Evidence behind choices in the code'.
  if (options.max_terms < 0 || 7 * (wanted + 1) > 2 * p) return err_rank(ErrGram::from_data(phi, y).matrix(), options);
  Eigen::VectorXd y_column(p + 1);
  y_column.head(p) = ident::cross_product(phi, y);
  y_column(p) = y.squaredNorm();
  return rank_on_columns(phi.colwise().squaredNorm().transpose(), y_column,
                         [&](Eigen::Index m) -> Eigen::VectorXd {
                           Eigen::VectorXd col(p + 1);
                           col.head(p) = ident::cross_product(phi, phi.col(m));
                           col(p) = y_column(m);
                           return col;
                         },
                         options);
}

Eigen::MatrixXd bias_corrected_gram(const Eigen::Ref<const Eigen::MatrixXd>& gram,
                                    std::span<const Eigen::Index> output_multiplied,
                                    const Eigen::Ref<const Eigen::MatrixXd>& factors,
                                    double sigma2) {
  const Eigen::Index p = gram.rows() - 1;
  const Eigen::Index q = static_cast<Eigen::Index>(output_multiplied.size());
  if (factors.cols() != q) throw std::invalid_argument("bias_corrected_gram: factors must be N x q");
  Eigen::MatrixXd g = gram;
  const Eigen::MatrixXd ff = ident::gram(factors);
  const Eigen::VectorXd fs = factors.colwise().sum().transpose();
  for (Eigen::Index a = 0; a < q; ++a) {
    const Eigen::Index ca = output_multiplied[static_cast<std::size_t>(a)];
    if (ca < 0 || ca >= p) throw std::invalid_argument("bias_corrected_gram: column out of range");
    g(ca, p) -= sigma2 * fs[a];
    g(p, ca) = g(ca, p);
    for (Eigen::Index b = 0; b < q; ++b)
      g(ca, output_multiplied[static_cast<std::size_t>(b)]) -= sigma2 * ff(a, b);
  }
  g(p, p) -= sigma2 * static_cast<double>(factors.rows());
  return g;
}

}  // namespace inertia::ident
