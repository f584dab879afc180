#include "analyzer/ident/row_products.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "analyzer/ident/symmetric.hpp"
#include "common/parallel.hpp"

namespace inertia::ident {
namespace {

/// Up to this many columns of B, A'B is formed one column at a time.
constexpr Eigen::Index kNarrowColumns = 4;

/// The sum over the row blocks [k0, k0 + rows) of block(k0, rows, part), each part a zero
/// out_rows x out_cols matrix the block adds into, added in block order.
template <class Block>
Eigen::MatrixXd summed_over_blocks(Eigen::Index rows, Eigen::Index out_rows, Eigen::Index out_cols, const Block& block) {
  const Eigen::Index blocks = std::max<Eigen::Index>(1, (rows + kProductBlockRows - 1) / kProductBlockRows);
  std::vector<Eigen::MatrixXd> parts(static_cast<std::size_t>(blocks));
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(parallel::threads_for(blocks))
#endif
  for (Eigen::Index k = 0; k < blocks; ++k) {
    Eigen::MatrixXd& part = parts[static_cast<std::size_t>(k)];
    part.setZero(out_rows, out_cols);
    const Eigen::Index k0 = k * kProductBlockRows;
    block(k0, std::min(kProductBlockRows, rows - k0), part);
  }
  Eigen::MatrixXd out = std::move(parts.front());
  for (std::size_t k = 1; k < parts.size(); ++k) out += parts[k];
  return out;
}

}  // namespace

Eigen::MatrixXd cross_product(const Eigen::Ref<const Eigen::MatrixXd>& a, const Eigen::Ref<const Eigen::MatrixXd>& b) {
  if (a.rows() != b.rows()) throw std::invalid_argument("cross_product: the factors' rows differ");
  return summed_over_blocks(a.rows(), a.cols(), b.cols(), [&](Eigen::Index k0, Eigen::Index rows, Eigen::MatrixXd& part) {
    if (b.cols() <= kNarrowColumns) {
      for (Eigen::Index j = 0; j < b.cols(); ++j)
        part.col(j).noalias() += a.middleRows(k0, rows).transpose() * b.col(j).segment(k0, rows);
    } else {
      part.noalias() += a.middleRows(k0, rows).transpose() * b.middleRows(k0, rows);
    }
  });
}

Eigen::MatrixXd gram(const Eigen::Ref<const Eigen::MatrixXd>& a) {
  Eigen::MatrixXd out = summed_over_blocks(a.rows(), a.cols(), a.cols(), [&](Eigen::Index k0, Eigen::Index rows, Eigen::MatrixXd& part) {
    part.selfadjointView<Eigen::Lower>().rankUpdate(a.middleRows(k0, rows).transpose());
  });
  mirror_lower(out);
  return out;
}

}  // namespace inertia::ident
