#include "hal/sim/sensors/fog_model.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "common/frames.hpp"
#include "hal/sim/sensors/stationary_state.hpp"

namespace inertia::sim {
namespace {

constexpr std::uint64_t kNoiseStream = 11;   // distinct from the accelerometer's streams

void require_fog(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("FogParams: " + message);
}

}  // namespace

FogModel::FogModel(const FogParams& p, double sample_rate_hz, std::uint64_t seed)
    : p_(p),
      m_cs_(frames::about_third_axis(p.alpha_o_rad) * frames::about_second_axis(p.alpha_p_rad)),
      noise_(p.noise, "FogParams.noise (B/A)"),
      g_i_(p.g_sens_i, "FogParams.g_sens_i (D/C)"),
      g_p_(p.g_sens_p, "FogParams.g_sens_p (F/E)"),
      g_o_(p.g_sens_o, "FogParams.g_sens_o (H/G)"),
      draws_(seed, kNoiseStream) {
  // The sample rate does not enter equation 5 (its filters are already discrete), but a caller
  // passing a nonsense rate has mixed up its arguments.
  require_fog(std::isfinite(sample_rate_hz) && sample_rate_hz > 0.0,
          "sample_rate_hz = " + std::to_string(sample_rate_hz) + " must be finite and > 0");
  require_fog(std::isfinite(p.s0) && p.s0 != 0.0, "s0 = " + std::to_string(p.s0) + " must be finite and non-zero");
  require_fog(std::isfinite(p.noise_sd_rad_s) && p.noise_sd_rad_s >= 0.0,
          "noise_sd_rad_s = " + std::to_string(p.noise_sd_rad_s) + " must be finite and >= 0");
  for (double v : {p.eps_t_ppm_per_degc, p.c_f1, p.c_i, p.alpha_p_rad, p.alpha_o_rad, p.c_t1, p.c_t2, p.drift_rad_s})
    require_fog(std::isfinite(v), "a coefficient is not finite");
  if (p.noise_sd_rad_s > 0.0) {
    DiscreteFilter<3>::StateMatrix a;
    DiscreteFilter<3>::StateVector b;
    noise_.state_space(a, b);
    const Eigen::MatrixXd cov = stationary_covariance(a, b * p.noise_sd_rad_s);
    noise_.set_state(draw_gaussian(cov, draws_));
  }
}

double FogModel::step(const Eigen::Vector3d& w_case, const Eigen::Vector3d& a_case,
                      double temp_delta_c) noexcept {
  // Only the input axis of the rate matters: c_x w_x + c_y w_y + c_z w_z = c_i (M_C^S w_C)_i.
  const double w_i = m_cs_.row(0).dot(w_case);
  const Eigen::Vector3d a = m_cs_ * a_case;
  if (first_) {
    g_i_.settle(a.x());
    g_p_.settle(a.y());
    g_o_.settle(a.z());
    temp_prev_c_ = temp_delta_c;
    first_ = false;
  }
  const double n = p_.noise_sd_rad_s > 0.0 ? p_.noise_sd_rad_s * draws_.next() : 0.0;
  const double rhs = p_.c_i * w_i + p_.c_t1 * temp_delta_c + p_.c_t2 * temp_prev_c_ + noise_.step(n) +
                     g_i_.step(a.x()) + g_p_.step(a.y()) + g_o_.step(a.z()) + p_.drift_rad_s;
  temp_prev_c_ = temp_delta_c;
  return rhs / (p_.s0 * (1.0 + 1e-6 * p_.eps_t_ppm_per_degc * temp_delta_c + p_.c_f1 * w_i));
}

}  // namespace inertia::sim
