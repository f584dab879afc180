#pragma once
// The squares' high-pass corner b (eq. 12: K_jj s / (s + b) a_j^2) as a continuous parameter of
// statistics kept at a few fixed corners.
//
// The live estimator cannot filter its past samples again when the corner estimate moves, so it
// keeps the squares' monomials filtered at the nodes of a log grid and forms the column at any b
// in between by 4-point Lagrange interpolation in log b:
//     hp_b(x) ~ sum_j w_j(log b) hp_{b_j}(x)
// (the filter's response is a smooth function of log b). With six nodes per decade the
// interpolated response differs from the filter's by at most 1.2e-3 of its full scale at any
// frequency, 2.1e-3 in the grid's first and last intervals, where the stencil leans inward (test
// CornerGrid.InterpolatedResponseMatchesTheFilter); at a node it is exact. A model file's corner
// is a grid of one node.
#include <Eigen/Dense>

#include <utility>
#include <vector>

namespace inertia::online {

/// Which nodes' filtered columns make up one corner, and with what weights (empty: static squares).
struct CornerWeights {
  std::vector<std::pair<int, double>> nodes;
  [[nodiscard]] bool filtered() const { return !nodes.empty(); }
};

class CornerGrid {
 public:
  static constexpr int kStencil = 4;           // Lagrange nodes per interpolated corner
  static constexpr double kNodesPerDecade = 6.0;

  CornerGrid() = default;
  /// Nodes log-spaced from `lo` to `hi` rad/s at kNodesPerDecade (both ends included).
  static CornerGrid spanning(double lo, double hi);
  /// One node: a given corner.
  static CornerGrid single(double corner_rad_s);

  [[nodiscard]] const std::vector<double>& nodes() const { return nodes_; }
  [[nodiscard]] bool empty() const { return nodes_.empty(); }
  [[nodiscard]] double lo() const { return nodes_.front(); }
  [[nodiscard]] double hi() const { return nodes_.back(); }
  /// The weights of the corner b (clamped into [lo, hi]).
  [[nodiscard]] CornerWeights at(double corner_rad_s) const;

 private:
  std::vector<double> nodes_;
  std::vector<double> log_nodes_;
};

}  // namespace inertia::online
