#pragma once
// Static (DC) gains of a dynamic model's input terms. With output lags the coefficients of
// eq. 1 are not the sensor's gains: y[k] = sum_l a_l y[k-l] + sum_l b_l u[k-l] + ... settles on
// a constant input u at y = (sum_l b_l) / (1 - sum_l a_l) u, so a term and its lagged copies
// must be read together, against the output lags. That is the figure to compare with a data
// sheet or a simulation's truth; the raw coefficients of an ARX fit (for example 0.0877 a_i and
// -0.0805 a_i[k-1] beside 0.917 y[k-1]) are not.
#include <string>
#include <vector>

#include "analyzer/ident/uls_batch.hpp"

namespace inertia::ident {

struct StaticGain {
  std::string term;                    ///< the input term at lag 0 ("a_i*a_p")
  std::vector<std::string> lagged;     ///< the model's terms that are shifts of it ("a_i*a_p", "a_i[k-1]*a_p[k-1]")
  double gain = 0.0;                   ///< (sum of their coefficients) / (1 - sum of the y-lag coefficients)
  double std_dev = 0.0;                ///< first-order (delta method) from the fit's covariance
};

/// One entry per input term family of `fit`'s process terms, in the order of first appearance;
/// noise terms and output-multiplied terms are not input terms and are left out. Empty when
/// the model is static (no output lag and no lagged term), where the coefficients are the gains,
/// or when 1 - sum a_l is zero within 1e-9 (an integrator has no static gain).
std::vector<StaticGain> static_gains(const UlsResult& fit);

}  // namespace inertia::ident
