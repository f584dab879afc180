// The derivative of a fit's prediction with respect to one mounting's turn (prediction_derivative)
// built from that mounting's cases alone: the other cases' rows do not move, so it must equal,
// bit for bit, the derivative built from the whole batch stack.
#include "analyzer/procedure/batch_regression.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/post_selection_inference.hpp"
#include "common/frames.hpp"
#include "tests/support/synthetic_cases.hpp"

namespace inertia::procedure {
namespace {

/// Three shaker cases: two of mounting "a", one of mounting "b", each turned differently in F_E.
dataset::Dataset two_mountings() {
  std::vector<testing::SyntheticCase> cases;
  for (int c = 0; c < 3; ++c)
    cases.push_back({c < 2 ? "a" : "b", 2000 + 700 * c, frames::frame_rotation(Eigen::Vector3d(1.0, -0.5 * c, 2.0).normalized(), 0.2 * c)});
  return testing::synthetic_shaker_cases(cases, 11);
}

TEST(BatchRegression, ATurnsDerivativeFromItsMountingsCasesIsTheWholeStacksBits) {
  const dataset::Dataset data = two_mountings();
  PipelineOptions options;
  std::vector<MountingResult> mountings(2);
  mountings[0].mounting = "a";
  mountings[0].cases = {0, 1};
  mountings[0].m_cs = frames::frame_rotation(Eigen::Vector3d(0.0, 1.0, 0.0), 0.01);
  mountings[1].mounting = "b";
  mountings[1].cases = {2};
  mountings[1].m_cs = frames::frame_rotation(Eigen::Vector3d(0.0, 0.0, 1.0), -0.02);
  const std::vector<ident::Term> terms = ident::parse_terms({"1", "a_i", "a_p", "a_o", "a_i^2", "a_i*a_p", "a_o*T"});
  const double corner = 40.0;
  const BatchRegression rows_at(data, options, "test", 1, ArWhitener::of(Eigen::Vector2d(0.6, -0.2)));
  const std::vector<Eigen::Vector3d> nominal(2, Eigen::Vector3d::Zero());
  const StackedRegression stack = rows_at(terms, mountings, nominal, corner);
  ident::UlsResult fit;
  fit.labels = stack.labels;
  fit.process_terms = static_cast<Eigen::Index>(terms.size());
  fit.theta = Eigen::VectorXd::LinSpaced(fit.process_terms, 0.5, -0.3);

  for (std::size_t k = 0; k < mountings.size(); ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      const auto derivative = [&](std::span<const std::size_t> only) {
        return prediction_derivative(fit, 1e-4, rows_at.whitener(), stack.cases, [&](std::span<const ident::Term> t, double moved) {
          std::vector<Eigen::Vector3d> turns = nominal;
          turns[k](axis) = moved;
          return rows_at.unwhitened(t, mountings, turns, corner, only);
        });
      };
      const Eigen::VectorXd whole = derivative({});
      const Eigen::VectorXd own = derivative(mountings[k].cases);
      ASSERT_EQ(own.size(), stack.y.size());
      ASSERT_EQ(whole.size(), stack.y.size());
      for (Eigen::Index r = 0; r < own.size(); ++r) ASSERT_EQ(own(r), whole(r)) << "mounting " << k << ", axis " << axis << ", row " << r;
      // The turn moves its own cases' rows and no other's.
      for (const CaseRows& rows : stack.cases) {
        const bool moves = std::find(mountings[k].cases.begin(), mountings[k].cases.end(), rows.case_index) != mountings[k].cases.end();
        const double size = own.segment(rows.begin, rows.rows).norm();
        if (moves) EXPECT_GT(size, 0.0) << "case " << rows.case_index;
        else EXPECT_EQ(size, 0.0) << "case " << rows.case_index;
      }
    }
  }
  // A layout the rebuilt rows do not fit is refused, not written past.
  std::vector<CaseRows> shorter = stack.cases;
  shorter.back().rows -= 1;
  EXPECT_THROW(prediction_derivative(fit, 1e-4, rows_at.whitener(), shorter,
                                     [&](std::span<const ident::Term> t, double moved) {
                                       std::vector<Eigen::Vector3d> turns = nominal;
                                       turns[1](0) = moved;
                                       return rows_at.unwhitened(t, mountings, turns, corner, mountings[1].cases);
                                     }),
               std::logic_error);
}

}  // namespace
}  // namespace inertia::procedure
