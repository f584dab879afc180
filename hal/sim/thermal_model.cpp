#include "hal/sim/thermal_model.hpp"

#include <algorithm>
#include <cmath>

namespace inertia::sim {

ThermalModel::ThermalModel(const config::ThermalController& params, double sample_rate_hz)
    : p_(params), dt_(1.0 / sample_rate_hz), decay_(std::exp(-dt_ / params.tau_s)),
      temp_c_(params.initial_c), setpoint_c_(params.initial_c) {}

void ThermalModel::set_open_loop(double drive) {
  open_loop_ = true;
  drive_ = std::clamp(drive, -1.0, 1.0);
}

double ThermalModel::step() {
  if (!open_loop_) {
    const double e = setpoint_c_ - temp_c_;
    const double unclamped = p_.kp_per_c * e + p_.ki_per_c_s * (integral_ + e * dt_);
    drive_ = std::clamp(unclamped, -1.0, 1.0);
    const bool saturated_with_error = (unclamped > 1.0 && e > 0.0) || (unclamped < -1.0 && e < 0.0);
    if (!saturated_with_error) integral_ += e * dt_;
  }
  // Equilibrium for the held drive, then the exact decay towards it over one period.
  const double equilibrium = p_.ambient_c + p_.tau_s * p_.heat_rate_max_c_per_s * drive_;
  temp_c_ = equilibrium + (temp_c_ - equilibrium) * decay_;
  return temp_c_;
}

}  // namespace inertia::sim
