#pragma once
// Eq. 12's K_jj(s) a_j^2 terms: the squares of the sensor-frame accelerations pass a first-order
// high pass s / (s + b) before they reach the output. One definition, used where the squares are
// fitted (pipeline), simulated (model_simulation) and stored (model file key
// square_highpass_rad_s): the bilinear transform prewarped at b, started settled (output 0 on the
// first sample),
//   h(k) = p h(k-1) + g (x(k) - x(k-1)),  c = b / tan(b T / 2),  p = (c - b)/(c + b),  g = c/(c + b).
#include <Eigen/Dense>

#include "analyzer/ident/term.hpp"

namespace inertia::procedure {

/// True for a_i^2, a_p^2, a_o^2 (at any lag): the terms the high pass applies to.
bool is_square_term(const ident::Term& term);

/// Filters x in place with s / (s + corner) at the sample period.
void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s);

/// The filter's memory between blocks of one signal (the online estimator filters chunk by chunk).
struct HighpassState {
  double previous_input = 0.0, output = 0.0;
  bool started = false;   // false: the next block starts settled, as highpass_in_place does
};

/// The same filter continued from `state` (updated): blocks filtered one after another give
/// exactly what highpass_in_place gives on their concatenation.
void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s,
                       HighpassState& state);

}  // namespace inertia::procedure
