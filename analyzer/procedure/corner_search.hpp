#pragma once
// The rule that chooses the squares' high-pass corner b of eq. 12 (square_highpass.hpp): the
// corner whose fit leaves the least residual sum of squares. The offline search
// (SquareCornerSearch, on rows) and the live solver (online/live_solver, on statistics kept at a
// grid of corners) both choose by it; only how a residual at a corner is computed differs.
//
// The residual is smooth in log b near its minimum but may have several local minima over the
// decades a search spans, so the nodes are tried first and Brent's method (Boost.Math) refines
// between the best node's neighbours, on log b. 14 bits (2^-13 relative to log b, 0.08 % of b at
// b ~ 500 rad/s) are far below the corner's own scatter over seeds. The static squares (no high
// pass) compete when allowed and keep a tie: a filter is only chosen when it fits better.
#include <boost/math/tools/minima.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>

namespace inertia::procedure {

/// Whether the misalignment fixed point's pass `refinement` (0 the first) searches the corner:
/// the corner hardly moves with M_C^S after the first step, so it is searched on the first two
/// passes and held on the later ones. The offline fixed point and the live solver both ask here.
[[nodiscard]] constexpr bool corner_searched_on(int refinement) { return refinement < 2; }

struct CornerChoice {
  std::optional<double> corner_rad_s;   // none: the static squares
  double rss = std::numeric_limits<double>::infinity();
};

/// The corner with the least `rss(corner)` (none: the static squares; return +inf or NaN where
/// there is no fit) over `nodes` (ascending, rad/s), refined between the best node's neighbours,
/// with the static squares competing when `static_allowed`. Without any finite residual: the
/// static squares when allowed, else the first node, with rss +inf.
template <class Rss>
CornerChoice least_residual_corner(std::span<const double> nodes, bool static_allowed, Rss&& rss) {
  constexpr int kBits = 14;
  constexpr std::uintmax_t kMaxIterations = 40;
  CornerChoice best;
  const auto consider = [&best](std::optional<double> corner, double r) {
    if (r < best.rss) best = {corner, r};
  };
  if (static_allowed) consider(std::nullopt, rss(std::optional<double>()));
  std::optional<std::size_t> best_node;
  double best_node_rss = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const double r = rss(std::optional<double>(nodes[k]));
    if (r < best_node_rss) {
      best_node_rss = r;
      best_node = k;
    }
    consider(nodes[k], r);
  }
  if (best_node && nodes.size() >= 2) {
    const double a = std::log(nodes[*best_node == 0 ? 0 : *best_node - 1]);
    const double b = std::log(nodes[std::min(nodes.size() - 1, *best_node + 1)]);
    std::uintmax_t iterations = kMaxIterations;
    const auto [log_b, r] = boost::math::tools::brent_find_minima(
        [&](double x) {
          const double value = rss(std::optional<double>(std::exp(x)));
          return std::isfinite(value) ? value : std::numeric_limits<double>::infinity();
        },
        a, b, kBits, iterations);
    consider(std::exp(log_b), r);
  }
  if (!std::isfinite(best.rss)) best.corner_rad_s = static_allowed || nodes.empty() ? std::nullopt : std::optional<double>(nodes.front());
  return best;
}

}  // namespace inertia::procedure
