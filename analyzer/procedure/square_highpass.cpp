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
}

double SquareCornerSearch::rss(std::optional<double> corner_rad_s) const {
  Eigen::MatrixXd g = gram_;
  Eigen::VectorXd v = xty_;
  if (corner_rad_s) {
    const auto n = static_cast<Eigen::Index>(squares_.size());
    Eigen::MatrixXd f(s_.phi.rows(), n);
    std::vector<Eigen::Index> all(squares_.size());
    for (Eigen::Index i = 0; i < n; ++i) {
      f.col(i) = s_.phi.col(squares_[static_cast<std::size_t>(i)]);
      all[static_cast<std::size_t>(i)] = i;
    }
    highpass_columns(f, all, s_.cases, data_, *corner_rad_s);
    const Eigen::MatrixXd cross = ident::cross_product(f, s_.phi);   // n x p, square columns still unfiltered on the right
    const Eigen::MatrixXd ff = ident::gram(f);
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index a = squares_[static_cast<std::size_t>(i)];
      g.row(a) = cross.row(i);
      g.col(a) = cross.row(i).transpose();
      v(a) = f.col(i).dot(s_.y);
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = 0; j < n; ++j) g(squares_[static_cast<std::size_t>(i)], squares_[static_cast<std::size_t>(j)]) = ff(i, j);
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
  // The nodes' residuals (and the static squares') do not depend on one another: side by side
  // first, on --jobs threads, each into its slot; the refinement between them is sequential.
  std::vector<double> at_node(nodes.size() + 1);
  parallel::for_each_index(static_cast<long>(at_node.size()), [&](long i) {
    const auto k = static_cast<std::size_t>(i);
    at_node[k] = k == nodes.size() ? rss(std::nullopt) : rss(nodes[k]);
  });
  return least_residual_corner(nodes, true, [&](std::optional<double> corner) {
           if (!corner) return at_node.back();
           const auto node = std::find(nodes.begin(), nodes.end(), *corner);
           return node != nodes.end() ? at_node[static_cast<std::size_t>(node - nodes.begin())] : rss(corner);
         }).corner_rad_s;
}

}  // namespace inertia::procedure
