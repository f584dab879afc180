#pragma once
// Completing a symmetric matrix of which only the lower triangle was computed (Eigen's
// selfadjointView<Lower>().rankUpdate(), a SYRK): the Gram matrices of err.cpp and uls_batch.cpp.
#include <Eigen/Dense>

namespace inertia::ident {

/// Copies the lower triangle onto the upper one, element by element so no aliasing question arises.
inline void mirror_lower(Eigen::MatrixXd& m) {
  for (Eigen::Index j = 1; j < m.cols(); ++j)
    for (Eigen::Index i = 0; i < j; ++i) m(i, j) = m(j, i);
}

}  // namespace inertia::ident
