#pragma once
// A model's response to inputs held constant long enough to settle: every lag at its value, the
// output's lags at the settled output, noise terms 0, the squares through eq. 12's high pass at
// 0 (a high pass passes no constant). What exports and the parameter sheet read static
// quantities from (sensitivity, nonlinearity over a range, what a left-out term costs).
#include <array>
#include <functional>

#include "analyzer/ident/term.hpp"
#include "analyzer/model/model_file.hpp"

namespace inertia::compensate {

using InputValues = std::array<double, ident::kVariableCount>;

/// The settled output y of y (1 + sum_b c_b p_b) = sum_a c_a term_a at `values`, with the terms
/// `kept` accepts (all by default) and the coefficients `theta` (in the model's term order; empty:
/// the model's own). A lagged y (power 1) stands for y itself. NaN where a term holds y at a
/// power above 1 or the equation has no finite solution.
double static_output(const model::ModelFile& model, const InputValues& values,
                     const std::function<bool(const ident::Term&)>& kept = {}, const Eigen::VectorXd& theta = {});

/// The static sensitivity to `input`: its plain terms at every lag over 1 - the output lags'
/// coefficients (coefficients from `theta` when given).
double static_sensitivity(const model::ModelFile& model, ident::Variable input, const Eigen::VectorXd& theta = {});

}  // namespace inertia::compensate
