#pragma once
// Free-run simulation of an identified model on measured reference inputs: the model's output
// when only the inputs are known (verification, Fig. 7; the discrepancy workflow). Lagged outputs
// y[k-j] are fed back from the simulation itself, noise terms e[k-j] are zero (they describe the
// noise, not the sensor), and output-multiplied terms divide: y = a / (1 + sum theta_b p_b).
#include <Eigen/Dense>
#include <optional>
#include <span>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/term.hpp"

namespace inertia::procedure {

/// Simulates sum theta_j term_j over `signals` (which need every input the terms read; y only for
/// the first `first_row` samples, which seed the output lags). Returns the output for samples
/// first_row .. N-1. Throws InputError for a term the simulation cannot feed back (y inside a
/// nonlinear function or product with another lagged y) or a missing input.
/// `square_highpass_rad_s`: the squares a_j^2 pass eq. 12's high pass with this corner
/// (square_highpass.hpp) at `sample_period_s`; nullopt: they are static.
Eigen::VectorXd simulate_model(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                               const ident::SignalSet& signals, Eigen::Index first_row,
                               std::optional<double> square_highpass_rad_s = std::nullopt, double sample_period_s = 0.0);

}  // namespace inertia::procedure
