#pragma once
// Truth model of a pendulous accelerometer: the paper's equation 12, section 3.1.
//   y = K_i (K_b + a_i + K_s sign(a_i) + K_a |a_i| + K_oq a_i|a_i| + K_ip a_i a_p + K_io a_i a_o
//            + K_po a_p a_o + K_ii(s) a_i^2 + K_pp(s) a_p^2 + K_oo(s) a_o^2 + e_N + e_B + e_K)
// with a_S = R_OA(alpha_o) R_PA(alpha_p) a_C, accelerations in g (as the paper's table 1), and
// K_jj(s) = K_jj s / (s + b_jj) first-order high-pass filters.
// Our extension (not in the paper, zero by default): temperature coefficients of bias and scale,
//   y = K_i (1 + scale_tc T) (K_b + bias_tc T + a_i + ... + e_K),   T = temp - t_ref.
// Discretisation (details in the .cpp): each K_jj(s) by the bilinear transform prewarped at b_jj,
//   h(k) = p h(k-1) + g (a_j^2(k) - a_j^2(k-1)),  p = (c - b)/(c + b),  g = K_jj c/(c + b),
//   c = b / tan(b / (2 fs)),
// an order-1 ARX recurrence, so lagged terms (y[k-1], a_j^2[k-1]) represent it exactly.
// Noise: e_N white; e_B pink (pink_noise.hpp), stationary from the first sample; e_K a random
// walk starting at 0 at the first sample, each step of sd brown_sd_g / sqrt(fs). Each component
// has its own random stream derived from the seed. sign(0) = 0.
#include <Eigen/Dense>
#include <cstdint>

#include "hal/sim/sensors/discrete_filter.hpp"
#include "hal/sim/sensors/gaussian_source.hpp"
#include "hal/sim/sensors/pink_noise.hpp"

namespace inertia::sim {

struct AccelerometerParams {
  double k_i = 0.86;              // scale factor, output unit per g
  double k_b = 4e-3;              // bias, g
  double k_s = 0.0;               // sign(a_i) coefficient (asymmetry), g
  double k_a = 0.0;               // |a_i| coefficient (rectification), dimensionless
  double k_oq = 0.0;              // a_i |a_i| coefficient (odd quadratic), 1/g
  double k_ip = 1e-3;             // a_i a_p cross-coupling, 1/g
  double k_io = 1e-3;             // a_i a_o cross-coupling, 1/g
  double k_po = 1e-3;             // a_p a_o cross-coupling, 1/g
  double k_ii = 60e-6;            // high-pass gain of a_i^2, 1/g
  double k_pp = 60e-6;            // high-pass gain of a_p^2, 1/g
  double k_oo = 60e-6;            // high-pass gain of a_o^2, 1/g
  double b_ii_rad_s = 500.0;      // high-pass corner of K_ii(s), rad/s (table 1 "bK")
  double b_pp_rad_s = 500.0;
  double b_oo_rad_s = 500.0;
  double alpha_p_rad = 1.4e-3;    // sensor misalignment about PA
  double alpha_o_rad = 1.4e-3;    // sensor misalignment about OA
  double white_sd_g = 1e-4;       // N: standard deviation per sample of the white component, g
  double pink_sd_g = 1.5e-3;      // B: standard deviation per sample of the pink (1/f) component, g
  double brown_sd_g = 0.0;        // K: standard deviation of the brown (1/f^2) component after 1 s, g
  double pink_min_hz = 0.01;      // lower edge of the 1/f band (the band's upper edge is Nyquist)
  double bias_tc_g_per_degc = 0.0;   // optional: bias temperature coefficient, g/degC (on T = temp - t_ref)
  double scale_tc_per_degc = 0.0;    // optional: relative scale-factor temperature coefficient, 1/degC
};

class AccelerometerModel {
 public:
  /// Throws std::invalid_argument naming the field when a parameter is out of range
  /// (sample rate <= 0, a high-pass corner outside (0, pi * sample_rate_hz) while its gain is
  /// non-zero, a negative noise level, pink_min_hz outside (0, Nyquist)). Not real-time.
  AccelerometerModel(const AccelerometerParams& p, double sample_rate_hz, std::uint64_t seed);

  /// One sample. a_case: specific force in the case frame F_C, m/s^2; temp_delta_c = temp - t_ref
  /// (degC). Returns y in the output unit. Call once per sample, in time order; the first call
  /// also settles the high-pass filters at that input (the sensor sat under it before the record
  /// began). Real-time safe: no allocation, no lock.
  double step(const Eigen::Vector3d& a_case, double temp_delta_c) noexcept;

  /// M_C^S = R_OA(alpha_o) R_PA(alpha_p) (frame rotations, common/frames.hpp).
  [[nodiscard]] Eigen::Matrix3d m_cs() const { return m_cs_; }
  [[nodiscard]] const AccelerometerParams& params() const noexcept { return p_; }
  [[nodiscard]] double sample_rate_hz() const noexcept { return sample_rate_hz_; }

 private:
  AccelerometerParams p_;
  double sample_rate_hz_;
  Eigen::Matrix3d m_cs_;
  Eigen::Matrix3d m_cs_per_g_;      // M_C^S / g0: m/s^2 in the case frame -> g in the sensor frame
  DiscreteFilter<1> hp_i_, hp_p_, hp_o_;
  GaussianSource white_;
  PinkNoise pink_;
  GaussianSource brown_draws_;
  double brown_step_sd_g_;          // brown_sd_g / sqrt(sample_rate_hz): sd of one random-walk step
  double brown_g_ = 0.0;            // e_K, the random walk, starts at 0 with the record
  bool first_ = true;
};

}  // namespace inertia::sim
