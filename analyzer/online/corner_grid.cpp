#include "analyzer/online/corner_grid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace inertia::online {

CornerGrid CornerGrid::spanning(double lo, double hi) {
  if (!(lo > 0.0) || !(hi > lo)) throw std::invalid_argument("CornerGrid: needs 0 < lo < hi");
  CornerGrid g;
  const int intervals = std::max(kStencil - 1, static_cast<int>(std::ceil(kNodesPerDecade * std::log10(hi / lo))));
  for (int i = 0; i <= intervals; ++i) {
    const double l = std::log(lo) + (std::log(hi) - std::log(lo)) * i / intervals;
    g.log_nodes_.push_back(l);
    g.nodes_.push_back(std::exp(l));
  }
  g.nodes_.front() = lo;
  g.nodes_.back() = hi;
  return g;
}

CornerGrid CornerGrid::single(double corner_rad_s) {
  CornerGrid g;
  g.nodes_ = {corner_rad_s};
  g.log_nodes_ = {std::log(corner_rad_s)};
  return g;
}

CornerWeights CornerGrid::at(double corner_rad_s) const {
  CornerWeights w;
  if (nodes_.empty()) return w;
  const auto n = static_cast<int>(nodes_.size());
  if (n == 1) {
    w.nodes = {{0, 1.0}};
    return w;
  }
  const double l = std::clamp(std::log(corner_rad_s), log_nodes_.front(), log_nodes_.back());
  // At a node: that node alone (exact).
  for (int k = 0; k < n; ++k) {
    if (std::abs(l - log_nodes_[static_cast<std::size_t>(k)]) <= 1e-12 * std::max(1.0, std::abs(l))) {
      w.nodes = {{k, 1.0}};
      return w;
    }
  }
  const int stencil = std::min(kStencil, n);
  // The interval [k, k + 1] holding l, and the stencil centred on it, kept inside the grid.
  int k = static_cast<int>(std::upper_bound(log_nodes_.begin(), log_nodes_.end(), l) - log_nodes_.begin()) - 1;
  k = std::clamp(k, 0, n - 2);
  const int first = std::clamp(k - (stencil - 2) / 2, 0, n - stencil);
  for (int j = first; j < first + stencil; ++j) {
    double weight = 1.0;
    for (int m = first; m < first + stencil; ++m) {
      if (m == j) continue;
      weight *= (l - log_nodes_[static_cast<std::size_t>(m)]) /
                (log_nodes_[static_cast<std::size_t>(j)] - log_nodes_[static_cast<std::size_t>(m)]);
    }
    w.nodes.emplace_back(j, weight);
  }
  return w;
}

}  // namespace inertia::online
