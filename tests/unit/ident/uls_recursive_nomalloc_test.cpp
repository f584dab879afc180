// Built with EIGEN_RUNTIME_NO_MALLOC together with its own copy of the estimator sources (see
// CMakeLists.txt), so Eigen aborts on any heap allocation inside update() while it is forbidden.
#include <gtest/gtest.h>

#include "analyzer/ident/uls_recursive.hpp"
#include "tests/unit/ident/ident_test_data.hpp"

namespace inertia::ident {
namespace {

TEST(UlsRecursiveNoMalloc, UpdateDoesNotAllocate) {
  const auto ex = testing::rational_example(21, 2000, 0.1);
  RecursiveUlsOptions options;
  options.noise_lags = 2;
  options.forgetting = 0.999;
  options.reset_trace = 1e9;
  UlsRecursive rec(5, ex.output_multiplied, options);
  rec.initialize(ex.phi.topRows(300), ex.y.head(300), ex.factors.topRows(300));
  // Row copies made up front: the test, not the estimator, would allocate for them.
  const Eigen::MatrixXd rows = ex.phi.transpose();
  const Eigen::MatrixXd factors = ex.factors.transpose();
  Eigen::internal::set_is_malloc_allowed(false);
  for (Eigen::Index k = 300; k < ex.y.size(); ++k)
    rec.update(rows.col(k), ex.y[k], factors.col(k));
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_TRUE(rec.theta().allFinite());
  EXPECT_EQ(rec.samples(), ex.y.size());
}

// The guard itself is live in this build (NDEBUG off), so the test above can fail.
TEST(UlsRecursiveNoMalloc, GuardCatchesAnAllocation) {
  EXPECT_DEATH(
      {
        Eigen::internal::set_is_malloc_allowed(false);
        Eigen::VectorXd v(1000);
        v.setOnes();
        Eigen::internal::set_is_malloc_allowed(true);
      },
      "heap allocation is forbidden");
}

}  // namespace
}  // namespace inertia::ident
