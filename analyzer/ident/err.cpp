#include "analyzer/ident/err.hpp"

#include <algorithm>
#include <stdexcept>

namespace inertia::ident {
namespace {

// Copies the lower triangle onto the upper one (after a SYRK rankUpdate), element by element so
// no aliasing question arises.
void mirror_lower(Eigen::MatrixXd& m) {
  for (Eigen::Index j = 1; j < m.cols(); ++j)
    for (Eigen::Index i = 0; i < j; ++i) m(i, j) = m(j, i);
}
}  // namespace

ErrGram::ErrGram(Eigen::Index terms) : gram_(Eigen::MatrixXd::Zero(terms + 1, terms + 1)) {}

void ErrGram::add(const Eigen::Ref<const Eigen::MatrixXd>& phi_block,
                  const Eigen::Ref<const Eigen::VectorXd>& y_block) {
  const Eigen::Index p = terms();
  if (phi_block.cols() != p || y_block.size() != phi_block.rows())
    throw std::invalid_argument("ErrGram::add: block sizes do not match");
  // SYRK on the lower triangle (half the flops of a GEMM), then mirror so users see a full matrix.
  gram_.topLeftCorner(p, p).selfadjointView<Eigen::Lower>().rankUpdate(phi_block.transpose());
  gram_.row(p).head(p) += (phi_block.transpose() * y_block).transpose();
  gram_(p, p) += y_block.squaredNorm();
  mirror_lower(gram_);
  samples_ += phi_block.rows();
}

ErrGram ErrGram::from_data(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                           const Eigen::Ref<const Eigen::VectorXd>& y) {
  ErrGram g(phi.cols());
  g.add(phi, y);
  return g;
}

ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& gram, const ErrOptions& options) {
  const Eigen::Index p = gram.rows() - 1;
  if (p < 0 || gram.cols() != p + 1) throw std::invalid_argument("err_rank: Gram matrix not square");
  Eigen::MatrixXd g = gram;  // working copy, Schur-complemented in place
  const Eigen::VectorXd energy0 = gram.diagonal().head(p);
  std::vector<bool> used(static_cast<std::size_t>(p), false);
  ErrRanking out;
  const double total = g(p, p);
  out.reference_energy = total;
  std::vector<double> errs;

  auto dependent = [&](Eigen::Index j) {
    return !(g(j, j) > options.dependence_tolerance * energy0[j]) || !(energy0[j] > 0.0);
  };
  auto select = [&](Eigen::Index m, double reference) {
    const double err = reference > 0.0 ? g(m, p) * g(m, p) / (g(m, m) * reference) : 0.0;
    out.order.push_back(m);
    errs.push_back(err);
    used[static_cast<std::size_t>(m)] = true;
    // Orthogonalize every remaining column (and Y) against column m: rank-1 Schur update.
    const Eigen::VectorXd col = g.col(m) / std::sqrt(g(m, m));
    g.noalias() -= col * col.transpose();
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
  if (options.reference == ErrReference::AfterForced) out.reference_energy = g(p, p);
  const double reference = out.reference_energy;
  const Eigen::Index limit = options.max_terms < 0 ? p : std::min(options.max_terms, p);
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
      const double err = g(j, p) * g(j, p) / (g(j, j) * (reference > 0.0 ? reference : 1.0));
      if (err > best_err) {
        best_err = err;
        best = j;
      }
    }
    if (best < 0) break;
    select(best, reference);
  }
  std::sort(out.dependent.begin(), out.dependent.end());
  out.err = Eigen::Map<const Eigen::VectorXd>(errs.data(), static_cast<Eigen::Index>(errs.size()));
  const std::size_t first = options.reference == ErrReference::AfterForced ? out.forced_count : 0;
  out.unexplained = 1.0 - out.err.tail(out.err.size() - static_cast<Eigen::Index>(first)).sum();
  return out;
}

ErrRanking err_rank(const Eigen::Ref<const Eigen::MatrixXd>& phi,
                    const Eigen::Ref<const Eigen::VectorXd>& y, const ErrOptions& options) {
  return err_rank(ErrGram::from_data(phi, y).matrix(), options);
}

Eigen::MatrixXd bias_corrected_gram(const Eigen::Ref<const Eigen::MatrixXd>& gram,
                                    std::span<const Eigen::Index> output_multiplied,
                                    const Eigen::Ref<const Eigen::MatrixXd>& factors,
                                    double sigma2) {
  const Eigen::Index p = gram.rows() - 1;
  const Eigen::Index q = static_cast<Eigen::Index>(output_multiplied.size());
  if (factors.cols() != q) throw std::invalid_argument("bias_corrected_gram: factors must be N x q");
  Eigen::MatrixXd g = gram;
  const Eigen::MatrixXd ff = factors.transpose() * factors;
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
