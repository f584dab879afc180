// The corner rule (analyzer/procedure/corner_search.hpp) on residual functions of known minimum.
#include "analyzer/procedure/corner_search.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace inertia::procedure {
namespace {

std::vector<double> log_grid(double lo, double hi, int n) {
  std::vector<double> out;
  for (int i = 0; i < n; ++i) out.push_back(std::exp(std::log(lo) + (std::log(hi) - std::log(lo)) * i / (n - 1)));
  return out;
}

TEST(CornerSearch, FindsTheMinimumBetweenTheNodes) {
  const double truth = 37.0;
  int calls = 0;
  const auto rss = [&](std::optional<double> b) {
    ++calls;
    if (!b) return 10.0;
    const double d = std::log(*b / truth);
    return 1.0 + d * d;
  };
  const std::vector<double> nodes = log_grid(1.0, 1e4, 13);
  const CornerChoice choice = least_residual_corner(nodes, true, rss);
  ASSERT_TRUE(choice.corner_rad_s);
  // Brent's method to 14 bits: log b to 2^-13 of itself (twice that allowed).
  EXPECT_NEAR(std::log(*choice.corner_rad_s), std::log(truth), 2.0 * std::ldexp(1.0, -13) * std::log(truth));
  EXPECT_NEAR(choice.rss, 1.0, 1e-6);
  EXPECT_LT(calls, 1 + 13 + 45);
}

TEST(CornerSearch, TheStaticSquaresKeepATieAndWinWhenTheyFitBetter) {
  const std::vector<double> nodes = log_grid(1.0, 100.0, 5);
  const auto flat = [](std::optional<double>) { return 2.0; };
  EXPECT_FALSE(least_residual_corner(nodes, true, flat).corner_rad_s);
  const auto static_better = [](std::optional<double> b) { return b ? 3.0 + 1.0 / *b : 1.0; };
  EXPECT_FALSE(least_residual_corner(nodes, true, static_better).corner_rad_s);
  // Not allowed: the best corner whatever the static squares would give.
  const CornerChoice forced = least_residual_corner(nodes, false, static_better);
  ASSERT_TRUE(forced.corner_rad_s);
  EXPECT_NEAR(*forced.corner_rad_s, 100.0, 1e-2);
}

TEST(CornerSearch, WithoutAnyFitTheStaticSquaresOrTheFirstNodeAreNamedWithAnInfiniteResidual) {
  const std::vector<double> nodes = log_grid(1.0, 100.0, 5);
  const auto none = [](std::optional<double>) { return std::numeric_limits<double>::quiet_NaN(); };
  const CornerChoice a = least_residual_corner(nodes, true, none);
  EXPECT_FALSE(a.corner_rad_s);
  EXPECT_TRUE(std::isinf(a.rss));
  const CornerChoice b = least_residual_corner(nodes, false, none);
  ASSERT_TRUE(b.corner_rad_s);
  EXPECT_EQ(*b.corner_rad_s, 1.0);
  // A single node is used as it is (no bracket to refine in).
  const std::vector<double> one{42.0};
  const CornerChoice c = least_residual_corner(one, false, [](std::optional<double> b) { return b ? *b : 0.0; });
  EXPECT_EQ(*c.corner_rad_s, 42.0);
}

}  // namespace
}  // namespace inertia::procedure
