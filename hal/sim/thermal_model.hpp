#pragma once
// Temperature-controlled mounting fixture (paper section 2.3: Peltier module between fixture and
// slip table, controller on the fixture temperature). First-order plant
//   dT/dt = (T_amb - T) / tau + heat_rate_max * u,   u in [-1, 1] (Peltier drive)
// under a PI controller u = clamp(kp e + ki integral(e)), e = setpoint - T. The plant is stepped
// exactly for a drive held over one sample (zero-order hold), so the open-loop response is the
// analytic exponential at any sample rate. Anti-windup: the integral stops while the drive
// saturates in the direction of the error.
#include "common/config/bench_config.hpp"

namespace inertia::sim {

class ThermalModel {
 public:
  ThermalModel(const config::ThermalController& params, double sample_rate_hz);

  void set_setpoint(double setpoint_c) { setpoint_c_ = setpoint_c; }
  /// Open loop: hold `drive` (clamped to [-1, 1]) instead of the controller's output.
  void set_open_loop(double drive);
  /// Advances one sample period; returns the fixture temperature at the new sample. Real-time safe.
  double step();

  [[nodiscard]] double temperature_c() const { return temp_c_; }
  [[nodiscard]] double setpoint_c() const { return setpoint_c_; }
  [[nodiscard]] double drive() const { return drive_; }

 private:
  config::ThermalController p_;
  double dt_;
  double decay_;          // exp(-dt / tau)
  double temp_c_;
  double setpoint_c_;
  double integral_ = 0.0;
  double drive_ = 0.0;
  bool open_loop_ = false;
};

}  // namespace inertia::sim
