#pragma once
// The accelerometer truth (equation 12) written as the design's model-file terms, so the bench can
// put the truth beside what characterize identifies (truth.toml).
#include <string>
#include <utility>
#include <vector>

#include "hal/sim/sensors/accelerometer_model.hpp"

namespace inertia::sim {

/// Terms of y = sum coefficient * term, in canonical names (docs/design.md "Model terms") with inputs in
/// SI (a_* in m/s^2 in the sensor frame, T in degC): "1", "a_i", "a_i*a_p", "a_i*a_o", "a_p*a_o",
/// "sign(a_i)", "abs(a_i)", "a_i*abs(a_i)", "a_i^2", "a_p^2", "a_o^2", "T", then, when
/// scale_tc_per_degc != 0, each of those times T ("a_i*T", "a_i*a_p*T", ..., "T^2"), in that order.
/// Zero coefficients are left out. Equation 12 works in g, so a term of degree d in acceleration
/// carries 1/g0^d (g0 = kStandardGravity): "a_i" = K_i/g0, "abs(a_i)" = K_i K_a/g0,
/// "a_i*a_p" = K_i K_ip/g0^2, "a_i*abs(a_i)" = K_i K_oq/g0^2, "sign(a_i)" = K_i K_s, "1" = K_i K_b.
/// The high-pass terms K_jj(s) a_j^2 are dynamic; they are reported with their high-frequency
/// gain, "a_j^2" = K_i K_jj/g0^2 (their DC gain is zero: under static input they vanish).
/// The noise is not a term.
std::vector<std::pair<std::string, double>> accelerometer_model_terms(const AccelerometerParams& p);

}  // namespace inertia::sim
