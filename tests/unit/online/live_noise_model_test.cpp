// The live noise model's choice of rows (online/live_noise_model.hpp, noise_pieces): a window
// fitted before the plan determines the model leaves a level per phase and a misfit in a phase
// whose input changes; the AR noise model is fitted on what is noise, not on them.
#include "analyzer/online/live_noise_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "analyzer/procedure/prewhitening.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;
using Eigen::VectorXd;

/// Two poses of AR(1) noise (phi 0.8, innovation sd 1) on levels the early model did not explain
/// (+40 and -25), and between them a move whose misfit follows the input (a ramp of 30 plus the
/// noise): the window of an online run over a table's first two poses.
struct Window {
  VectorXd residuals;
  std::vector<procedure::CaseRows> pieces;
};

Window two_poses_and_a_move(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const std::array<Index, 3> rows{5000, 2000, 3000};
  Window w;
  w.residuals.resize(rows[0] + rows[1] + rows[2]);
  double noise = 0.0;
  Index at = 0;
  for (std::size_t p = 0; p < rows.size(); ++p) {
    w.pieces.push_back({p, at, rows[p], 0});
    for (Index k = 0; k < rows[p]; ++k, ++at) {
      noise = 0.8 * noise + normal(rng);
      const double misfit = p == 0 ? 40.0 : p == 2 ? -25.0 : 30.0 * static_cast<double>(k) / static_cast<double>(rows[p]);
      w.residuals(at) = misfit + noise;
    }
  }
  return w;
}

TEST(LiveNoiseModel, TheNoiseIsFittedWithinThePhasesAtTheNoiseFloor) {
  Window w = two_poses_and_a_move(5);
  // Every piece as it comes: the levels and the move read as a near unit root.
  const procedure::ArWhitener raw = procedure::ArWhitener::fit(w.residuals, w.pieces, 20);
  ASSERT_GE(raw.order(), 1);
  const std::vector<procedure::CaseRows> kept = noise_pieces(w.residuals, w.pieces);
  ASSERT_EQ(kept.size(), 2U) << "the two poses; the move's misfit is far above the noise";
  EXPECT_EQ(kept[0].begin, 0);
  EXPECT_EQ(kept[1].begin, 7000);
  for (const procedure::CaseRows& piece : kept) EXPECT_NEAR(w.residuals.segment(piece.begin, piece.rows).mean(), 0.0, 1e-9);
  const procedure::ArWhitener noise = procedure::ArWhitener::fit(w.residuals, kept, 20);
  ASSERT_GE(noise.order(), 1);
  std::cout << "[ figures ] AR(1) phi 0.8: every piece as it comes " << raw.coefficients()(0) << " (order " << raw.order()
            << "), the poses about their levels " << noise.coefficients()(0) << " (order " << noise.order() << ")\n";
  // 8000 rows of AR(1): the estimate's sd is sqrt((1 - phi^2) / n) = 0.0067; 4 sd.
  EXPECT_NEAR(noise.coefficients()(0), 0.8, 4.0 * std::sqrt((1.0 - 0.64) / 8000.0));
  EXPECT_GT(std::abs(raw.coefficients()(0) - 0.8), 0.1) << "the raw pieces must be what the rule mends";
}

TEST(LiveNoiseModel, AWindowWithinOnePhaseIsAllNoise) {
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal;
  VectorXd residuals(2000);
  for (Index k = 0; k < residuals.size(); ++k) residuals(k) = 3.0 + normal(rng);
  const std::vector<procedure::CaseRows> kept = noise_pieces(residuals, {{0, 0, 2000, 0}});
  ASSERT_EQ(kept.size(), 1U);
  EXPECT_EQ(kept[0].rows, 2000);
  EXPECT_NEAR(residuals.mean(), 0.0, 1e-12);
  // Pieces shorter than the floor's minimum set no floor; with none long enough, all are kept.
  VectorXd shorter = VectorXd::Ones(60);
  EXPECT_EQ(noise_pieces(shorter, {{0, 0, 30, 0}, {1, 30, 30, 0}}).size(), 2U);
}

}  // namespace
}  // namespace inertia::online
