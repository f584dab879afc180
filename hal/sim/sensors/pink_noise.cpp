#include "hal/sim/sensors/pink_noise.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/units.hpp"
#include "hal/sim/sensors/stationary_state.hpp"

namespace inertia::sim {

PinkNoise::PinkNoise(double sd, double min_hz, double sample_rate_hz, std::uint64_t seed,
                     std::uint64_t stream)
    : gauss_(seed, stream) {
  if (!(sd >= 0.0) || !std::isfinite(sd))
    throw std::invalid_argument("pink noise: sd = " + std::to_string(sd) + " must be finite and >= 0");
  if (sd == 0.0) return;
  const double nyquist_hz = sample_rate_hz / 2.0;
  if (!(min_hz > 0.0 && min_hz < nyquist_hz))
    throw std::invalid_argument("pink noise: pink_min_hz = " + std::to_string(min_hz) +
                                " must lie in (0, Nyquist = " + std::to_string(nyquist_hz) + " Hz)");
  const double ratio = std::pow(10.0, 1.0 / kSectionsPerDecade);
  sections_ = static_cast<int>(std::ceil(std::log10(nyquist_hz / min_hz) * kSectionsPerDecade));
  if (sections_ > kMaxSections)
    throw std::invalid_argument("pink noise: band pink_min_hz .. Nyquist spans more than " +
                                std::to_string(kMaxSections / kSectionsPerDecade) + " decades");
  // Matched pole-zero mapping z = exp(-2 pi f / fs) of each corner; a zero above Nyquist still maps
  // inside (0, 1), so the last section's shelf simply ends at Nyquist.
  for (int j = 0; j < sections_; ++j) {
    const double f_pole = min_hz * std::pow(ratio, j);
    pole_[j] = std::exp(-2.0 * kPi * f_pole / sample_rate_hz);
    zero_[j] = std::exp(-2.0 * kPi * f_pole * std::sqrt(ratio) / sample_rate_hz);
  }
  // State space of the cascade for unit white input w: u_j = w + sum_{m<j} s_m, y = w + sum s_j,
  // s_j(k+1) = (pole_j - zero_j) u_j + pole_j s_j.
  const Eigen::Index n = sections_;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd b(n, 1);
  for (Eigen::Index j = 0; j < n; ++j) {
    const double d = pole_[j] - zero_[j];
    for (Eigen::Index m = 0; m < j; ++m) a(j, m) = d;
    a(j, j) = pole_[j];
    b(j, 0) = d;
  }
  const Eigen::MatrixXd p = stationary_covariance(a, b);
  // Output variance for unit white input: 1' P 1 (states) + 1 (the current draw, independent).
  const double unit_variance = p.sum() + 1.0;
  gain_ = sd / std::sqrt(unit_variance);
  const Eigen::VectorXd s0 = draw_gaussian(p, gauss_);
  for (Eigen::Index j = 0; j < n; ++j) state_[j] = s0(j);
}

}  // namespace inertia::sim
