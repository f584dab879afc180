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

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s) {
  HighpassState state;
  highpass_in_place(x, corner_rad_s, sample_period_s, state);
}

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s,
                       HighpassState& state) {
  if (x.size() == 0) return;
  const auto [p, g] = highpass_coefficients(corner_rad_s, sample_period_s);
  if (!state.started) {
    state = {x(0), 0.0, true};
  }
  double h = state.output, previous = state.previous_input;
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    const double input = x(k);
    h = p * h + g * (input - previous);
    previous = input;
    x(k) = h;
  }
  state.previous_input = previous;
  state.output = h;
}

namespace {

void highpass_columns_side_by_side(Eigen::MatrixXd& x, std::span<const Eigen::Index> columns, const std::vector<CaseRows>& layout,
                                   const dataset::Dataset& data, double corner_rad_s) {
  // The columns run side by side, sample by sample: one column's recursion is a chain of
  // dependent multiply-adds, so interleaving independent ones keeps the pipeline full (the corner
  // search filters the squares some 40 times per fit). Same arithmetic as highpass_in_place.
  const auto n = columns.size();
  std::vector<double> h(n), previous(n);
  std::vector<double*> col(n);
  for (const CaseRows& rows : layout) {
    if (rows.rows <= 0) continue;
    const double period = data.cases.at(rows.case_index).sample_period_s;
    const auto [p, g] = highpass_coefficients(corner_rad_s, period);
    for (std::size_t i = 0; i < n; ++i) {
      col[i] = x.col(columns[i]).data() + rows.begin;
      h[i] = 0.0;
      previous[i] = col[i][0];
    }
    for (Eigen::Index k = 0; k < rows.rows; ++k) {
      for (std::size_t i = 0; i < n; ++i) {
        const double input = col[i][k];
        h[i] = p * h[i] + g * (input - previous[i]);
        previous[i] = input;
        col[i][k] = h[i];
      }
    }
  }
}

}  // namespace

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

void SquareCornerSearch::filter_block(const Block& block, double corner_rad_s, std::span<HighpassState> state,
                                      Eigen::MatrixXd& out) const {
  const double period = data_.cases.at(s_.cases[block.layout_index].case_index).sample_period_s;
  for (std::size_t i = 0; i < squares_.size(); ++i) {
    auto f = out.col(static_cast<Eigen::Index>(i)).head(block.rows);
    f = s_.phi.col(squares_[i]).segment(block.begin, block.rows);
    highpass_in_place(f, corner_rad_s, period, state[i]);
  }
}

std::vector<SquareCornerSearch::FilteredProducts> SquareCornerSearch::filtered_products(std::span<const double> corners_rad_s) const {
  const auto n = static_cast<Eigen::Index>(squares_.size());
  const Eigen::Index p = s_.phi.cols();
  const auto blocks = static_cast<long>(blocks_.size());
  const std::size_t m = corners_rad_s.size();
  // Each block's products on their own, added in block order: the same bits on any number of
  // threads and corners. A block's filter continues from the state the block before it left, so
  // with more than one thread those states are found first by running the filter alone (cheap
  // next to the products, and the same arithmetic, so the same values), each corner's chain on its
  // own thread. A case's first block starts settled. The corners share each block's pass: its
  // columns are read from memory once for all of them.
  const int threads = parallel::threads_for(blocks);
  const auto count = static_cast<std::size_t>(n);
  const auto state_at = [&](std::size_t b, std::size_t c) { return (b * m + c) * count; };
  std::vector<HighpassState> start(blocks_.size() * m * count);
  if (threads > 1) {
    parallel::for_each_index(static_cast<long>(m), [&](long corner) {
      const auto c = static_cast<std::size_t>(corner);
      Eigen::MatrixXd f(kBlockRows, n);
      std::vector<HighpassState> carried(count);
      for (std::size_t b = 0; b < blocks_.size(); ++b) {
        if (blocks_[b].starts_case) std::fill(carried.begin(), carried.end(), HighpassState{});
        std::copy(carried.begin(), carried.end(), start.begin() + static_cast<std::ptrdiff_t>(state_at(b, c)));
        filter_block(blocks_[b], corners_rad_s[c], carried, f);
      }
    });
  }
  std::vector<FilteredProducts> parts(blocks_.size() * m);
  const auto block_products = [&](long b, std::size_t c, std::span<HighpassState> state, Eigen::MatrixXd& f) {
    const Block& block = blocks_[static_cast<std::size_t>(b)];
    filter_block(block, corners_rad_s[c], state, f);
    FilteredProducts& part = parts[static_cast<std::size_t>(b) * m + c];
    part.cross.resize(n, p);
    for (Eigen::Index j = 0; j < p; ++j) {
      const auto column = s_.phi.col(j).segment(block.begin, block.rows);
      for (Eigen::Index i = 0; i < n; ++i) part.cross(i, j) = f.col(i).head(block.rows).dot(column);
    }
    part.gram.noalias() = f.topRows(block.rows).transpose() * f.topRows(block.rows);
    part.y.noalias() = f.topRows(block.rows).transpose() * s_.y.segment(block.begin, block.rows);
  };
  if (threads > 1) {
#ifdef _OPENMP
#pragma omp parallel num_threads(threads)
#endif
    {
      Eigen::MatrixXd f(kBlockRows, n);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 8)
#endif
      for (long b = 0; b < blocks; ++b) {
        for (std::size_t c = 0; c < m; ++c)
          block_products(b, c, std::span<HighpassState>(start).subspan(state_at(static_cast<std::size_t>(b), c), count), f);
      }
    }
  } else {
    Eigen::MatrixXd f(kBlockRows, n);
    std::vector<HighpassState> carried(m * count);
    for (long b = 0; b < blocks; ++b) {
      if (blocks_[static_cast<std::size_t>(b)].starts_case) std::fill(carried.begin(), carried.end(), HighpassState{});
      for (std::size_t c = 0; c < m; ++c) block_products(b, c, std::span<HighpassState>(carried).subspan(c * count, count), f);
    }
  }
  std::vector<FilteredProducts> sums(m, FilteredProducts{Eigen::MatrixXd::Zero(n, p), Eigen::MatrixXd::Zero(n, n), Eigen::VectorXd::Zero(n)});
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    for (std::size_t c = 0; c < m; ++c) {
      const FilteredProducts& part = parts[b * m + c];
      sums[c].cross += part.cross;
      sums[c].gram += part.gram;
      sums[c].y += part.y;
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
