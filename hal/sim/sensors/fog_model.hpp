#pragma once
// Truth model of a fiber-optic gyro: the paper's equation 5 (inputs in SI).
//   Omega(k) S0 [1 + 1e-6 eps_T T(k) + c_f1 w_i(k)] = c_x w_x + c_y w_y + c_z w_z + c_T1 T(k) + c_T2 T(k-1)
//       + B(q)/A(q) n(k) + D(q)/C(q) a_i(k) + F(q)/E(q) a_p(k) + H(q)/G(q) a_o(k) + D_F
// Omega is the sensor output (output unit). The rates and accelerations enter in the case frame
// F_C; [c_x c_y c_z] = c_i * (first row of M_C^S), so c_x w_x + c_y w_y + c_z w_z = c_i w_i and
// cross-axis rates come from the sensor misalignment alpha_p, alpha_o (the case mounting, M_E^C,
// is applied by the bench before the model).
#include <Eigen/Dense>
#include <array>
#include <cstdint>

#include "hal/sim/sensors/discrete_filter.hpp"
#include "hal/sim/sensors/gaussian_source.hpp"

namespace inertia::sim {

struct FogParams {
  double s0 = 1.0;                     // S0, rad/s per output unit
  double eps_t_ppm_per_degc = 0.0;     // epsilon_T, ppm/degC
  double c_f1 = 0.0;                   // rate nonlinearity, 1/(rad/s)
  double c_i = 1.0;                    // input-axis sensitivity (dimensionless)
  double alpha_p_rad = 0.0;            // sensor misalignment about PA
  double alpha_o_rad = 0.0;            // sensor misalignment about OA
  double c_t1 = 0.0;                   // rad/s per degC, on T(k)
  double c_t2 = 0.0;                   // rad/s per degC, on T(k-1)
  double drift_rad_s = 0.0;            // D_F
  double noise_sd_rad_s = 1e-5;        // sd of the white driving noise n'(k)
  DiscreteTransferFunction<3> noise{{1.0, 0.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}};   // B(q)/A(q)
  DiscreteTransferFunction<2> g_sens_i{{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};          // D(q)/C(q), rad/s per m/s^2
  DiscreteTransferFunction<2> g_sens_p{{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};          // F(q)/E(q)
  DiscreteTransferFunction<2> g_sens_o{{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};          // H(q)/G(q)
};

class FogModel {
 public:
  /// Throws std::invalid_argument naming the field for a transfer function with den[0] != 1 or an
  /// unstable denominator, s0 == 0, a negative noise sd or a non-positive sample rate.
  /// The coloured noise B/A starts from its stationary distribution. Not real-time.
  FogModel(const FogParams& p, double sample_rate_hz, std::uint64_t seed);

  /// One sample. w_case: rate in F_C, rad/s; a_case: specific force in F_C, m/s^2;
  /// temp_delta_c = temp - t_ref, degC. Returns Omega in the output unit. Call once per sample in
  /// time order; the first call takes T(k-1) = T(k) and settles the g-sensitivity filters at
  /// that acceleration (static before the record). Real-time safe.
  double step(const Eigen::Vector3d& w_case, const Eigen::Vector3d& a_case, double temp_delta_c) noexcept;

  /// M_C^S = R_OA(alpha_o) R_PA(alpha_p) (frame rotations, common/frames.hpp).
  [[nodiscard]] Eigen::Matrix3d m_cs() const { return m_cs_; }
  [[nodiscard]] const FogParams& params() const noexcept { return p_; }

 private:
  FogParams p_;
  Eigen::Matrix3d m_cs_;
  DiscreteFilter<3> noise_;
  DiscreteFilter<2> g_i_, g_p_, g_o_;
  GaussianSource draws_;
  double temp_prev_c_ = 0.0;
  bool first_ = true;
};

}  // namespace inertia::sim
