#pragma once
// Truth model of a fiber-optic gyro: the paper's equation 5 (inputs in SI).
//   Omega(k) S0 [1 + 1e-6 eps_T T(k) + c_f1 w_i(k)] = c_x w_x + c_y w_y + c_z w_z + c_T1 T(k) + c_T2 T(k-1)
//       + B(q)/A(q) n(k) + D(q)/C(q) a_i(k) + F(q)/E(q) a_p(k) + H(q)/G(q) a_o(k) + D_F
// Omega is the sensor output (output unit); [c_x c_y c_z] = c_i * (first row of M_E^S), so cross-axis
// rates come from the sensor misalignment alpha_p, alpha_o and the case mounting.
#include <array>

namespace inertia::sim {

/// A discrete transfer function num(q^-1)/den(q^-1), den[0] = 1.
template <std::size_t Order>
struct DiscreteTransferFunction {
  std::array<double, Order + 1> num{};
  std::array<double, Order + 1> den{};
};

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

}  // namespace inertia::sim
