#pragma once
// Eq. 12's high pass s / (s + b) written out as the recursion procedure/square_highpass.hpp
// documents (bilinear, prewarped at b; settled start: h = 0 and x(-1) = x(0)): the reference the
// filter's implementations, offline and live, are held against.
#include <Eigen/Dense>
#include <cmath>

namespace inertia::testing {

inline Eigen::VectorXd reference_highpass(const Eigen::VectorXd& x, double b, double period) {
  const double c = b / std::tan(b * period / 2.0);
  const double p = (c - b) / (c + b), g = c / (c + b);
  Eigen::VectorXd h(x.size());
  double previous_h = 0.0, previous_x = x.size() > 0 ? x(0) : 0.0;
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    previous_h = p * previous_h + g * (x(k) - previous_x);
    previous_x = x(k);
    h(k) = previous_h;
  }
  return h;
}

}  // namespace inertia::testing
