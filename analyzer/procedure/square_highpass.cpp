#include "analyzer/procedure/square_highpass.hpp"

#include <algorithm>

#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <span>
#include <vector>

#include "analyzer/ident/row_products.hpp"
#include "analyzer/procedure/corner_search.hpp"
#include "common/parallel.hpp"

namespace inertia::procedure {

bool is_square_term(const ident::Term& term) {
  const auto& f = term.factors();
  return f.size() == 1 && f[0].power == 2 && f[0].function == ident::FactorFunction::Plain &&
         (f[0].variable == ident::Variable::Ai || f[0].variable == ident::Variable::Ap ||
          f[0].variable == ident::Variable::Ao);
}

HighpassCoefficients highpass_coefficients(double corner_rad_s, double sample_period_s) {
  const double c = corner_rad_s / std::tan(corner_rad_s * sample_period_s / 2.0);
  return {(c - corner_rad_s) / (c + corner_rad_s), c / (c + corner_rad_s)};
}

namespace {

/// The recursion on W columns side by side, its memory in registers (locals the stores into the
/// columns cannot alias).
template <std::size_t W>
void highpass_chains(double* const* columns, Eigen::Index rows, const HighpassCoefficients* coefficients, HighpassState* states) {
  double p[W], g[W], h[W], previous[W];
  for (std::size_t i = 0; i < W; ++i) {
    if (!states[i].started) states[i] = {columns[i][0], 0.0, true};
    p[i] = coefficients[i].p;
    g[i] = coefficients[i].g;
    h[i] = states[i].output;
    previous[i] = states[i].previous_input;
  }
  for (Eigen::Index k = 0; k < rows; ++k) {
    for (std::size_t i = 0; i < W; ++i) {
      const double input = columns[i][k];
      h[i] = p[i] * h[i] + g[i] * (input - previous[i]);
      previous[i] = input;
      columns[i][k] = h[i];
    }
  }
  for (std::size_t i = 0; i < W; ++i) states[i] = {previous[i], h[i], true};
}

/// The recursion on `columns` (each `rows` long, filtered in place), column i with
/// coefficients[i] and continued from states[i] (updated). One column's recursion is a chain of
/// dependent multiply-adds, so up to four run side by side, sample by sample, to keep the
/// pipeline full. Every filter of this file runs here: a column's arithmetic is the same whichever
/// columns run beside it.
void highpass_side_by_side(std::span<double* const> columns, Eigen::Index rows, std::span<const HighpassCoefficients> coefficients,
                           std::span<HighpassState> states) {
  if (rows <= 0) return;
  std::size_t i = 0;
  for (; i + 4 <= columns.size(); i += 4) highpass_chains<4>(&columns[i], rows, &coefficients[i], &states[i]);
  switch (columns.size() - i) {
    case 3: highpass_chains<3>(&columns[i], rows, &coefficients[i], &states[i]); break;
    case 2: highpass_chains<2>(&columns[i], rows, &coefficients[i], &states[i]); break;
    case 1: highpass_chains<1>(&columns[i], rows, &coefficients[i], &states[i]); break;
    default: break;
  }
}

/// The high pass on `columns` of `x`, case by case, side by side.
void highpass_columns_side_by_side(Eigen::MatrixXd& x, std::span<const Eigen::Index> columns, const std::vector<CaseRows>& layout,
                                   const dataset::Dataset& data, double corner_rad_s) {
  const auto n = columns.size();
  std::vector<double*> col(n);
  std::vector<HighpassState> states(n);
  for (const CaseRows& rows : layout) {
    if (rows.rows <= 0) continue;
    const std::vector<HighpassCoefficients> coefficients(n, highpass_coefficients(corner_rad_s, data.cases.at(rows.case_index).sample_period_s));
    for (std::size_t i = 0; i < n; ++i) col[i] = x.col(columns[i]).data() + rows.begin;
    std::fill(states.begin(), states.end(), HighpassState{});   // each case starts settled
    highpass_side_by_side(col, rows.rows, coefficients, states);
  }
}

}  // namespace

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s,
                       HighpassState& state) {
  double* const column = x.data();
  const HighpassCoefficients coefficients = highpass_coefficients(corner_rad_s, sample_period_s);
  highpass_side_by_side(std::span<double* const>(&column, 1), x.size(), std::span<const HighpassCoefficients>(&coefficients, 1),
                        std::span<HighpassState>(&state, 1));
}

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s) {
  HighpassState state;
  highpass_in_place(x, corner_rad_s, sample_period_s, state);
}

void highpass_columns(Eigen::MatrixXd& x, const std::vector<Eigen::Index>& columns, const std::vector<CaseRows>& layout,
                      const dataset::Dataset& data, double corner_rad_s) {
  // The columns split into one contiguous share per thread (parallel::jobs()), each share side by
  // side; a column's arithmetic does not depend on its share.
  const auto n = static_cast<long>(columns.size());
  const int threads = parallel::threads_for(n);
#ifdef _OPENMP
#pragma omp parallel for schedule(static, 1) num_threads(threads)
#endif
  for (int t = 0; t < threads; ++t) {
    const long begin = n * t / threads, end = n * (t + 1) / threads;
    highpass_columns_side_by_side(x, std::span<const Eigen::Index>(columns).subspan(static_cast<std::size_t>(begin), static_cast<std::size_t>(end - begin)),
                                  layout, data, corner_rad_s);
  }
}

double max_corner(const std::vector<CaseRows>& layout, const dataset::Dataset& data) {
  double smallest_nyquist = std::numeric_limits<double>::infinity();
  for (const CaseRows& rows : layout) {
    const double period = data.cases.at(rows.case_index).sample_period_s;
    if (!(period > 0.0)) return 0.0;   // no sample period: no filter (the search keeps static squares)
    smallest_nyquist = std::min(smallest_nyquist, std::numbers::pi / period);
  }
  return 0.9 * smallest_nyquist;
}

SquareCornerSearch::SquareCornerSearch(const StackedRegression& s, std::vector<Eigen::Index> squares,
                                       const dataset::Dataset& data)
    : s_(s), squares_(std::move(squares)), data_(data) {
  gram_ = ident::gram(s.phi);
  xty_ = ident::cross_product(s.phi, s.y);
  yy_ = s.y.squaredNorm();
  for (std::size_t c = 0; c < s.cases.size(); ++c) {
    const CaseRows& rows = s.cases[c];
    for (Eigen::Index k0 = 0; k0 < rows.rows; k0 += kBlockRows)
      blocks_.push_back({c, rows.begin + k0, std::min(kBlockRows, rows.rows - k0), k0 == 0});
  }
}

SquareCornerSearch::BlockFilter SquareCornerSearch::block_filter(std::size_t corners) const {
  const std::size_t count = corners * squares_.size();
  BlockFilter filter{Eigen::MatrixXd(kBlockRows, static_cast<Eigen::Index>(count)), std::vector<double*>(count),
                     std::vector<HighpassCoefficients>(count), SIZE_MAX};
  for (std::size_t k = 0; k < count; ++k) filter.columns[k] = filter.out.col(static_cast<Eigen::Index>(k)).data();
  return filter;
}

void SquareCornerSearch::filter_block(const Block& block, std::span<const double> corners_rad_s, std::span<HighpassState> state,
                                      BlockFilter& filter) const {
  const std::size_t n = squares_.size();
  if (block.layout_index != filter.layout_index) {
    const double period = data_.cases.at(s_.cases[block.layout_index].case_index).sample_period_s;
    for (std::size_t c = 0; c < corners_rad_s.size(); ++c)
      std::fill_n(filter.coefficients.begin() + static_cast<std::ptrdiff_t>(c * n), n, highpass_coefficients(corners_rad_s[c], period));
    filter.layout_index = block.layout_index;
  }
  for (std::size_t c = 0; c < corners_rad_s.size(); ++c) {
    for (std::size_t i = 0; i < n; ++i)
      filter.out.col(static_cast<Eigen::Index>(c * n + i)).head(block.rows) = s_.phi.col(squares_[i]).segment(block.begin, block.rows);
  }
  highpass_side_by_side(filter.columns, block.rows, filter.coefficients, state);
}

void SquareCornerSearch::block_products(std::size_t b, std::span<const double> corners_rad_s, std::span<HighpassState> state,
                                        BlockFilter& filter, std::span<FilteredProducts> out) const {
  const auto n = static_cast<Eigen::Index>(squares_.size());
  const Eigen::Index p = s_.phi.cols();
  const Block& block = blocks_[b];
  filter_block(block, corners_rad_s, state, filter);
  for (std::size_t c = 0; c < corners_rad_s.size(); ++c) {
    const auto filtered = filter.out.middleCols(static_cast<Eigen::Index>(c) * n, n).topRows(block.rows);
    FilteredProducts& part = out[c];
    for (Eigen::Index j = 0; j < p; ++j) {
      const auto column = s_.phi.col(j).segment(block.begin, block.rows);
      for (Eigen::Index i = 0; i < n; ++i) part.cross(i, j) = filtered.col(i).dot(column);
    }
    part.gram.noalias() = filtered.transpose() * filtered;
    part.y.noalias() = filtered.transpose() * s_.y.segment(block.begin, block.rows);
  }
}

std::vector<SquareCornerSearch::FilteredProducts> SquareCornerSearch::filtered_products(std::span<const double> corners_rad_s) const {
  const auto n = static_cast<Eigen::Index>(squares_.size());
  const Eigen::Index p = s_.phi.cols();
  const std::size_t m = corners_rad_s.size();
  const std::size_t count = static_cast<std::size_t>(n);
  const std::size_t blocks = blocks_.size();
  const auto zero = [&] { return FilteredProducts{Eigen::MatrixXd::Zero(n, p), Eigen::MatrixXd::Zero(n, n), Eigen::VectorXd::Zero(n)}; };
  // Each block's products on their own, added to the sums in block order: the same bits on any
  // number of threads and corners. The threads form a window of blocks side by side, then one adds
  // them. A block's filter continues from the state the block before it left, so with more than
  // one thread those states are found first, a window at a time, by running the filter alone (cheap
  // next to the products, and the same arithmetic, so the same values), the corners split into one
  // share per thread, each share's chains side by side. Memory: the window's, whatever the record. A case's first block starts settled. The corners
  // share each block's pass: its columns are read from memory once for all of them, and every
  // corner's squares are filtered side by side.
  const std::size_t window_blocks = std::min(blocks, kWindowBlocks);
  const int threads = parallel::threads_for(static_cast<long>(window_blocks));
  std::vector<FilteredProducts> window(window_blocks * m);
  for (FilteredProducts& part : window) part = zero();
  std::vector<FilteredProducts> sums(m, zero());
  const auto add_in_order = [&](std::size_t parts) {
    for (std::size_t k = 0; k < parts; ++k) {
      for (std::size_t c = 0; c < m; ++c) {
        const FilteredProducts& part = window[k * m + c];
        sums[c].cross += part.cross;
        sums[c].gram += part.gram;
        sums[c].y += part.y;
      }
    }
  };
  if (threads > 1) {
    // Per window: the states each of its blocks starts from, one chain per share of the corners
    // carried on from the window before; then the window's products side by side; then the sums.
    const auto state_at = [&](std::size_t k, std::size_t c) { return (k * m + c) * count; };
    std::vector<HighpassState> start(window_blocks * m * count);
    const auto shares = static_cast<long>(std::min<std::size_t>(static_cast<std::size_t>(threads), m));
    const auto share_first = [&](long share) { return m * static_cast<std::size_t>(share) / static_cast<std::size_t>(shares); };
    std::vector<BlockFilter> share_filters;
    std::vector<std::vector<HighpassState>> carried;
    for (long share = 0; share < shares; ++share) {
      const std::size_t corners = share_first(share + 1) - share_first(share);
      share_filters.push_back(block_filter(corners));
      carried.emplace_back(corners * count);
    }
#ifdef _OPENMP
#pragma omp parallel num_threads(threads)
#endif
    {
      BlockFilter filter = block_filter(m);
      for (std::size_t first = 0; first < blocks; first += window_blocks) {
        const std::size_t last = std::min(blocks, first + window_blocks);
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
        for (long share = 0; share < shares; ++share) {
          const std::size_t c0 = share_first(share);
          const std::span<const double> corners = corners_rad_s.subspan(c0, share_first(share + 1) - c0);
          std::vector<HighpassState>& chain = carried[static_cast<std::size_t>(share)];
          for (std::size_t b = first; b < last; ++b) {
            if (blocks_[b].starts_case) std::fill(chain.begin(), chain.end(), HighpassState{});
            std::copy(chain.begin(), chain.end(), start.begin() + static_cast<std::ptrdiff_t>(state_at(b - first, c0)));
            filter_block(blocks_[b], corners, chain, share_filters[static_cast<std::size_t>(share)]);
          }
        }
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 4)
#endif
        for (long b = static_cast<long>(first); b < static_cast<long>(last); ++b) {
          const auto block = static_cast<std::size_t>(b);
          block_products(block, corners_rad_s, std::span<HighpassState>(start).subspan(state_at(block - first, 0), m * count), filter,
                         std::span<FilteredProducts>(window).subspan((block - first) * m, m));
        }
#ifdef _OPENMP
#pragma omp single
#endif
        add_in_order(last - first);
      }
    }
  } else {
    BlockFilter filter = block_filter(m);
    std::vector<HighpassState> carried(m * count);
    for (std::size_t b = 0; b < blocks; ++b) {
      if (blocks_[b].starts_case) std::fill(carried.begin(), carried.end(), HighpassState{});
      block_products(b, corners_rad_s, carried, filter, std::span<FilteredProducts>(window).first(m));
      add_in_order(1);
    }
  }
  return sums;
}

double SquareCornerSearch::rss(std::optional<double> corner_rad_s) const {
  if (!corner_rad_s || squares_.empty()) return rss_with(nullptr);
  return rss(std::span<const double>(&*corner_rad_s, 1)).front();
}

std::vector<double> SquareCornerSearch::rss(std::span<const double> corners_rad_s) const {
  std::vector<double> out;
  if (squares_.empty()) {
    out.assign(corners_rad_s.size(), rss_with(nullptr));
    return out;
  }
  for (const FilteredProducts& filtered : filtered_products(corners_rad_s)) out.push_back(rss_with(&filtered));
  return out;
}

double SquareCornerSearch::rss_with(const FilteredProducts* filtered) const {
  Eigen::MatrixXd g = gram_;
  Eigen::VectorXd v = xty_;
  if (filtered != nullptr) {
    // Only the squares' rows and columns of the Gram matrix, and their entries of X'y, change.
    const auto n = static_cast<Eigen::Index>(squares_.size());
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index a = squares_[static_cast<std::size_t>(i)];
      g.row(a) = filtered->cross.row(i);
      g.col(a) = filtered->cross.row(i).transpose();
      v(a) = filtered->y(i);
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = 0; j < n; ++j) g(squares_[static_cast<std::size_t>(i)], squares_[static_cast<std::size_t>(j)]) = filtered->gram(i, j);
    }
  }
  // Scaled pseudo-inverse (dependent columns are harmless here: only the residual counts).
  const Eigen::VectorXd d = g.diagonal().cwiseMax(std::numeric_limits<double>::min()).cwiseSqrt();
  const Eigen::MatrixXd gs = d.cwiseInverse().asDiagonal() * g * d.cwiseInverse().asDiagonal();
  const Eigen::VectorXd vs = d.cwiseInverse().asDiagonal() * v;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gs);
  const double cut = 1e-12 * eig.eigenvalues().maxCoeff();
  double explained = 0.0;
  for (Eigen::Index k = 0; k < eig.eigenvalues().size(); ++k) {
    const double lambda = eig.eigenvalues()(k);
    if (lambda > cut) {
      const double proj = eig.eigenvectors().col(k).dot(vs);
      explained += proj * proj / lambda;
    }
  }
  return yy_ - explained;
}

std::optional<double> SquareCornerSearch::best(double lo, double hi) const {
  if (!(lo > 0.0) || !(hi >= lo)) return std::nullopt;
  if (hi == lo) return lo;   // a given corner (a model's): used as given
  std::vector<double> nodes(kGridCorners);
  const double l0 = std::log(lo), l1 = std::log(hi);
  for (int i = 0; i < kGridCorners; ++i) nodes[static_cast<std::size_t>(i)] = std::exp(l0 + (l1 - l0) * i / (kGridCorners - 1));
  // The nodes' residuals in one pass over the rows; the refinement between them is sequential.
  const std::vector<double> at_node = rss(std::span<const double>(nodes));
  const double at_static = rss(std::nullopt);
  return least_residual_corner(nodes, true, [&](std::optional<double> corner) {
           if (!corner) return at_static;
           const auto node = std::find(nodes.begin(), nodes.end(), *corner);
           return node != nodes.end() ? at_node[static_cast<std::size_t>(node - nodes.begin())] : rss(corner);
         }).corner_rad_s;
}

}  // namespace inertia::procedure
