#include "hal/sim/sensors/accelerometer_model.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "common/frames.hpp"
#include "common/units.hpp"

namespace inertia::sim {
namespace {

// Noise streams of one sensor, drawn from the one config seed (gaussian_source.hpp).
constexpr std::uint64_t kWhiteStream = 1, kPinkStream = 2, kBrownStream = 3;

void require_accelerometer(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument("AccelerometerParams: " + message);
}

// Paper eq. 12: K_jj(s) = K_jj s / (s + b). Bilinear transform prewarped at the corner,
//   s -> c (1 - q^-1) / (1 + q^-1),  c = b / tan(b T_s / 2),
// gives  K(q) = g (1 - q^-1) / (1 - p q^-1),  p = (c - b) / (c + b),  g = K_jj c / (c + b),
// i.e. the recurrence  h(k) = p h(k-1) + g (x(k) - x(k-1))  on x = a_j^2:
// an ARX model of order 1 in (h, x), which is exactly what the identification's lagged terms
// (y[k-1], a_j^2[k-1]) can represent. Properties kept exactly at every sample rate: gain 0 at DC,
// K_jj at Nyquist (the continuous filter's high-frequency gain), -3 dB at b rad/s.
DiscreteFilter<1> high_pass(double k, double b_rad_s, double sample_rate_hz, const char* field) {
  if (k == 0.0) return {};   // term off; its corner is irrelevant
  require_accelerometer(std::isfinite(k), std::string(field) + " gain is not finite");
  require_accelerometer(b_rad_s > 0.0 && b_rad_s < kPi * sample_rate_hz,
          std::string(field) + " = " + std::to_string(b_rad_s) +
              " rad/s must lie in (0, pi * sample_rate_hz) (corner below Nyquist)");
  const double c = b_rad_s / std::tan(b_rad_s / (2.0 * sample_rate_hz));
  const double pole = (c - b_rad_s) / (c + b_rad_s);
  const double g = k * c / (c + b_rad_s);
  return DiscreteFilter<1>({{g, -g}, {1.0, -pole}}, field);
}

double checked_rate(double sample_rate_hz) {
  require_accelerometer(std::isfinite(sample_rate_hz) && sample_rate_hz > 0.0,
          "sample_rate_hz = " + std::to_string(sample_rate_hz) + " must be finite and > 0");
  return sample_rate_hz;
}

double checked_sd(double sd, const char* field) {
  require_accelerometer(std::isfinite(sd) && sd >= 0.0, std::string(field) + " = " + std::to_string(sd) + " must be finite and >= 0");
  return sd;
}

}  // namespace

AccelerometerModel::AccelerometerModel(const AccelerometerParams& p, double sample_rate_hz,
                                       std::uint64_t seed)
    : p_(p),
      sample_rate_hz_(checked_rate(sample_rate_hz)),
      m_cs_(frames::about_third_axis(p.alpha_o_rad) * frames::about_second_axis(p.alpha_p_rad)),
      m_cs_per_g_(m_cs_ / kStandardGravity),
      hp_i_(high_pass(p.k_ii, p.b_ii_rad_s, sample_rate_hz, "b_ii_rad_s")),
      hp_p_(high_pass(p.k_pp, p.b_pp_rad_s, sample_rate_hz, "b_pp_rad_s")),
      hp_o_(high_pass(p.k_oo, p.b_oo_rad_s, sample_rate_hz, "b_oo_rad_s")),
      white_(seed, kWhiteStream),
      pink_(checked_sd(p.pink_sd_g, "pink_sd_g"), p.pink_min_hz, sample_rate_hz, seed, kPinkStream),
      brown_draws_(seed, kBrownStream),
      brown_step_sd_g_(checked_sd(p.brown_sd_g, "brown_sd_g") / std::sqrt(sample_rate_hz)) {
  checked_sd(p.white_sd_g, "white_sd_g");
  require_accelerometer(m_cs_.allFinite(), "alpha_p_rad / alpha_o_rad must be finite");
}

double AccelerometerModel::step(const Eigen::Vector3d& a_case, double temp_delta_c) noexcept {
  const Eigen::Vector3d a = m_cs_per_g_ * a_case;   // sensor frame, g
  const double ai = a.x(), ap = a.y(), ao = a.z();
  const double ii = ai * ai, pp = ap * ap, oo = ao * ao;
  if (first_) {
    hp_i_.settle(ii);
    hp_p_.settle(pp);
    hp_o_.settle(oo);
    first_ = false;
  }
  const double sign_i = static_cast<double>((ai > 0.0) - (ai < 0.0));   // sign(0) = 0
  const double abs_i = std::abs(ai);
  double noise = 0.0;
  if (p_.white_sd_g > 0.0) noise += p_.white_sd_g * white_.next();
  noise += pink_.next();
  if (brown_step_sd_g_ > 0.0) {
    brown_g_ += brown_step_sd_g_ * brown_draws_.next();
    noise += brown_g_;
  }
  const double inside = p_.k_b + p_.bias_tc_g_per_degc * temp_delta_c + ai + p_.k_s * sign_i +
                        p_.k_a * abs_i + p_.k_oq * ai * abs_i + p_.k_ip * ai * ap +
                        p_.k_io * ai * ao + p_.k_po * ap * ao + hp_i_.step(ii) + hp_p_.step(pp) +
                        hp_o_.step(oo) + noise;
  return p_.k_i * (1.0 + p_.scale_tc_per_degc * temp_delta_c) * inside;
}

}  // namespace inertia::sim
