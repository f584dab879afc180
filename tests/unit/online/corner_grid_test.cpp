// The squares' corner interpolated between the grid's nodes (analyzer/online/corner_grid.hpp):
// the weights reproduce the high pass s/(s + b) at any corner to the accuracy the header states.
#include "analyzer/online/corner_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>

#include "analyzer/procedure/square_highpass.hpp"

namespace inertia::online {
namespace {

/// Frequency response of the bilinear high pass of procedure::highpass_in_place at w rad/s.
std::complex<double> response(double corner, double period, double w) {
  const double c = corner / std::tan(corner * period / 2.0);
  const double p = (c - corner) / (c + corner), g = c / (c + corner);
  const std::complex<double> z_inv = std::polar(1.0, -w * period);
  return g * (1.0 - z_inv) / (1.0 - p * z_inv);
}

TEST(CornerGrid, InterpolatedResponseMatchesTheFilter) {
  const double period = 1e-4;   // 10 kHz: the grid spans 1 .. 1e4 rad/s
  const CornerGrid grid = CornerGrid::spanning(1.0, 1.0e4);
  EXPECT_EQ(grid.nodes().size(), 25u);   // six a decade
  double worst = 0.0, worst_inside = 0.0;
  for (int i = 0; i <= 400; ++i) {
    const double corner = std::exp(std::log(1.0) + std::log(1.0e4) * i / 400.0);
    const CornerWeights w = grid.at(corner);
    double weights = 0.0;
    for (const auto& [node, weight] : w.nodes) weights += weight;
    EXPECT_NEAR(weights, 1.0, 1e-12) << "a constant response is reproduced";
    for (int f = 0; f <= 200; ++f) {
      const double omega = std::numbers::pi / period * f / 200.0;
      std::complex<double> sum = 0.0;
      for (const auto& [node, weight] : w.nodes) sum += weight * response(grid.nodes()[static_cast<std::size_t>(node)], period, omega);
      const double e = std::abs(sum - response(corner, period, omega));
      worst = std::max(worst, e);
      if (corner > grid.nodes()[1] && corner < grid.nodes()[grid.nodes().size() - 2]) worst_inside = std::max(worst_inside, e);
    }
  }
  EXPECT_LT(worst, 2.1e-3);          // the first and last intervals: the stencil leans inward
  EXPECT_LT(worst_inside, 1.2e-3);
  EXPECT_GT(worst, 1e-5) << "between nodes the interpolation is not exact (the test can tell)";
}

TEST(CornerGrid, ANodeIsExactAndTheModelsCornerIsOneNode) {
  const CornerGrid grid = CornerGrid::spanning(1.0, 2827.0);
  const CornerWeights at_node = grid.at(grid.nodes()[5]);
  ASSERT_EQ(at_node.nodes.size(), 1u);
  EXPECT_EQ(at_node.nodes[0].first, 5);
  EXPECT_EQ(at_node.nodes[0].second, 1.0);
  EXPECT_EQ(grid.at(1e9).nodes.size(), 1u) << "clamped to the last node";
  const CornerGrid one = CornerGrid::single(552.8);
  EXPECT_EQ(one.at(100.0).nodes.size(), 1u);
  EXPECT_FALSE(CornerGrid().at(500.0).filtered()) << "no grid: static squares";
}

}  // namespace
}  // namespace inertia::online
