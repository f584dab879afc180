#include "hal/sim/sensors/accelerometer_model_terms.hpp"

#include "common/units.hpp"

namespace inertia::sim {

std::vector<std::pair<std::string, double>> accelerometer_model_terms(const AccelerometerParams& p) {
  constexpr double g0 = kStandardGravity;
  constexpr double g0_sq = kStandardGravity * kStandardGravity;
  // Terms of the bracket of equation 12, times K_i, converted from g to m/s^2.
  const std::vector<std::pair<std::string, double>> bracket = {
      {"1", p.k_i * p.k_b},
      {"a_i", p.k_i / g0},
      {"a_i*a_p", p.k_i * p.k_ip / g0_sq},
      {"a_i*a_o", p.k_i * p.k_io / g0_sq},
      {"a_p*a_o", p.k_i * p.k_po / g0_sq},
      {"sign(a_i)", p.k_i * p.k_s},
      {"abs(a_i)", p.k_i * p.k_a / g0},
      {"a_i*abs(a_i)", p.k_i * p.k_oq / g0_sq},
      {"a_i^2", p.k_i * p.k_ii / g0_sq},
      {"a_p^2", p.k_i * p.k_pp / g0_sq},
      {"a_o^2", p.k_i * p.k_oo / g0_sq},
      {"T", p.k_i * p.bias_tc_g_per_degc},
  };
  std::vector<std::pair<std::string, double>> terms;
  terms.reserve(2 * bracket.size());
  // The scale-factor temperature coefficient multiplies the whole bracket: (1 + s T) * sum c_t t.
  // Its product with the bias lands on "T"; every other product is a new term "t*T".
  const double s = p.scale_tc_per_degc;
  for (const auto& [name, c] : bracket) {
    const double value = name == "T" ? c + s * p.k_i * p.k_b : c;
    if (value != 0.0) terms.emplace_back(name, value);
  }
  if (s != 0.0) {
    for (const auto& [name, c] : bracket) {
      if (name == "1") continue;   // already folded into "T"
      const std::string product = name == "T" ? std::string("T^2") : name + "*T";
      if (s * c != 0.0) terms.emplace_back(product, s * c);
    }
  }
  return terms;
}

}  // namespace inertia::sim
