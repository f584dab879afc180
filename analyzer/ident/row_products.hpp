#pragma once
// Products over a regression's rows, A'B and A'A, on --jobs threads (common/parallel.hpp) with an
// answer that does not depend on their number.
//
// The rows are cut into blocks of kProductBlockRows, a count fixed here and not by the threads;
// each block's product is formed on its own (the threads take blocks in turn) and the blocks'
// products are added in block order. So one machine gives the same bits with 1 or 8 jobs, while
// a product of many rows uses every core (Eigen's own products stay single-threaded:
// EIGEN_DONT_PARALLELIZE, cmake/InertiaDependencies.cmake).
#include <Eigen/Dense>

namespace inertia::ident {

inline constexpr Eigen::Index kProductBlockRows = Eigen::Index{1} << 15;

/// A'B (a.cols() x b.cols()); a and b have the same rows. B may be a vector (a column). A narrow B
/// (a few columns: the output, ELS's noise columns) is taken a column at a time, A' times a
/// vector: a matrix product would copy (pack) all of A's rows for a few columns of output.
[[nodiscard]] Eigen::MatrixXd cross_product(const Eigen::Ref<const Eigen::MatrixXd>& a, const Eigen::Ref<const Eigen::MatrixXd>& b);
/// A'A, both triangles (a SYRK per block: half a GEMM's flops).
[[nodiscard]] Eigen::MatrixXd gram(const Eigen::Ref<const Eigen::MatrixXd>& a);

}  // namespace inertia::ident
