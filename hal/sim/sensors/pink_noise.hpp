#pragma once
// Pink (1/f) noise, O(1) per sample: one white draw through a cascade of first-order pole-zero
// sections. A pole at f_p followed by a zero at f_p*sqrt(r), repeated every ratio r in frequency,
// makes the amplitude fall with slope -1 over half of each ratio and 0 over the other half: an
// average power slope of -1 (-10 dB/decade) with a small ripple (the classic "pinking filter";
// see e.g. Kasdin, Proc. IEEE 83(5), 1995, section on rational approximations). We place
// kSectionsPerDecade poles per decade from pink_min_hz up to Nyquist; below pink_min_hz the
// spectrum is flat, which keeps the variance finite. The gain is set so that the standard
// deviation per sample of the whole component (the flat part below pink_min_hz included, ~5% of
// the variance for 0.01 Hz .. 5 kHz) is exactly the requested one (computed from the stationary
// covariance, not measured), and the state starts stationary (stationary_state.hpp).
// The slope is close to -1 from 10 pink_min_hz up to fs/4 (test
// AccelerometerModel.PinkNoisePsdFallsOneDecadePerDecade); the matched pole-zero mapping flattens
// the top octave below Nyquist, where a 1/f band edge has to bend anyway (figures:
// docs/validation.md, 'Evidence behind choices in the code').
#include <array>
#include <cstdint>

#include "hal/sim/sensors/gaussian_source.hpp"

namespace inertia::sim {

class PinkNoise {
 public:
  /// Two poles per decade keep the ripple of the 1/f approximation near +-0.1 dB (checked by
  /// the PSD test's slope fit) while the cost stays ~2 multiply-adds per section.
  static constexpr int kSectionsPerDecade = 2;
  static constexpr int kMaxSections = 40;   // 20 decades between pink_min_hz and Nyquist

  /// sd: standard deviation per sample (any unit); sd == 0 gives zeros and draws nothing.
  /// Throws std::invalid_argument unless 0 < min_hz < sample_rate_hz / 2 (when sd > 0).
  /// Not real-time (solves for the stationary state).
  PinkNoise(double sd, double min_hz, double sample_rate_hz, std::uint64_t seed, std::uint64_t stream);

  /// Real-time safe.
  double next() noexcept {
    if (sections_ == 0) return 0.0;
    double u = gauss_.next();
    // Section j: H_j(q) = (1 - zero_j q^-1) / (1 - pole_j q^-1), direct form II transposed.
    for (int j = 0; j < sections_; ++j) {
      const double y = u + state_[j];
      state_[j] = pole_[j] * y - zero_[j] * u;
      u = y;
    }
    return gain_ * u;
  }

  [[nodiscard]] int sections() const noexcept { return sections_; }

 private:
  GaussianSource gauss_;
  int sections_ = 0;
  double gain_ = 0.0;
  std::array<double, kMaxSections> pole_{}, zero_{}, state_{};
};

}  // namespace inertia::sim
