// Products over rows (analyzer/ident/row_products.hpp): A'B and A'A against a sum over the rows in
// extended precision, and the same bits whatever the number of threads.
#include "analyzer/ident/row_products.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "common/parallel.hpp"

namespace inertia::ident {
namespace {

Eigen::MatrixXd gaussian(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Eigen::MatrixXd x(rows, cols);
  for (Eigen::Index j = 0; j < cols; ++j)
    for (Eigen::Index i = 0; i < rows; ++i) x(i, j) = g(rng) + 0.5 * static_cast<double>(j);   // columns with means, as a bias
  return x;
}

/// sum_t a(t, i) b(t, j) in long double, term by term.
Eigen::MatrixXd exact_cross(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::MatrixXd out(a.cols(), b.cols());
  for (Eigen::Index i = 0; i < a.cols(); ++i)
    for (Eigen::Index j = 0; j < b.cols(); ++j) {
      long double sum = 0.0L;
      for (Eigen::Index t = 0; t < a.rows(); ++t) sum += static_cast<long double>(a(t, i)) * b(t, j);
      out(i, j) = static_cast<double>(sum);
    }
  return out;
}

class RowProducts : public ::testing::Test {
 protected:
  void TearDown() override { parallel::set_jobs(1); }
};

TEST_F(RowProducts, CrossProductAndGramAreTheSumsOverRowsAcrossBlockEdges) {
  // Row counts below, at and across the block size, and many blocks.
  for (const Eigen::Index rows : {Eigen::Index{1}, Eigen::Index{100}, kProductBlockRows, kProductBlockRows + 1, 5 * kProductBlockRows + 17}) {
    // A narrow B (a column at a time) and a wide one (one product of the blocks).
    const Eigen::MatrixXd a = gaussian(rows, 7, 1), b = gaussian(rows, 3, 2), wide = gaussian(rows, 6, 5);
    const Eigen::MatrixXd expected_cross = exact_cross(a, b), expected_gram = exact_cross(a, a);
    // Rounding of a sum of n products of O(1) terms: a few n eps of the sum of their magnitudes.
    const double tolerance = 8.0 * std::numeric_limits<double>::epsilon() * static_cast<double>(rows) * (1.0 + 3.5 * 3.5);
    EXPECT_LT((cross_product(a, b) - expected_cross).cwiseAbs().maxCoeff(), tolerance) << rows << " rows";
    EXPECT_LT((cross_product(a, wide) - exact_cross(a, wide)).cwiseAbs().maxCoeff(), tolerance) << rows << " rows, wide B";
    const Eigen::MatrixXd g = gram(a);
    EXPECT_LT((g - expected_gram).cwiseAbs().maxCoeff(), tolerance) << rows << " rows";
    EXPECT_EQ(g, g.transpose()) << "both triangles, the same numbers";
    const Eigen::VectorXd y = b.col(0);
    EXPECT_LT((cross_product(a, y) - expected_cross.col(0)).cwiseAbs().maxCoeff(), tolerance) << "a vector B";
  }
}

TEST_F(RowProducts, TheAnswerIsTheSameBitsOnOneAndSeveralThreads) {
  const Eigen::MatrixXd a = gaussian(7 * kProductBlockRows + 5, 9, 3), b = gaussian(a.rows(), 4, 4);
  parallel::set_jobs(1);
  const Eigen::MatrixXd cross1 = cross_product(a, b), gram1 = gram(a);
  for (const int jobs : {2, 3, 8}) {
    parallel::set_jobs(jobs);
    EXPECT_EQ(cross_product(a, b), cross1) << jobs << " jobs";
    EXPECT_EQ(gram(a), gram1) << jobs << " jobs";
  }
}

TEST_F(RowProducts, ANarrowFactorsColumnsAreEachTheirOwnProduct) {
  // A'[e1 e2] column by column is A'e1 and A'e2 to the bit, as the ELS passes' noise columns and
  // the output's products are formed alike.
  const Eigen::MatrixXd a = gaussian(3 * kProductBlockRows + 11, 12, 6), b = gaussian(a.rows(), 2, 7);
  const Eigen::MatrixXd both = cross_product(a, b);
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    const Eigen::VectorXd column = b.col(j);
    EXPECT_EQ(Eigen::MatrixXd(both.col(j)), cross_product(a, column)) << "column " << j;
  }
}

TEST_F(RowProducts, FactorsOfDifferentRowsAreRefused) {
  EXPECT_THROW((void)cross_product(Eigen::MatrixXd::Ones(4, 2), Eigen::MatrixXd::Ones(5, 2)), std::invalid_argument);
}

}  // namespace
}  // namespace inertia::ident
