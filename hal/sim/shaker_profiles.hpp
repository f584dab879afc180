#pragma once
// Slip-table shaker motion along x_E for one phase: acceleration, velocity and displacement that
// are exact derivatives of one another, so the linear encoder (displacement) and the references
// (acceleration) describe the same motion and the displacement never drifts.
//  - sine: x = -(A/w^2) win(t) sin(w t) with smooth (C2) ramps of `ramp_cycles` cycles at both
//    ends; a follows analytically, so on the plateau a = A sin(w t) exactly (t from phase start),
//    and x = v = 0 at both ends. ramp_cycles = 0 switches the sine on and off abruptly (velocity
//    steps at the ends: the encoder sees a kink).
//  - random: a flat acceleration PSD between f1 and f2 synthesized in the frequency domain with
//    equal amplitudes and uniform random phases on the FFT bins of the band (FFT length: the next
//    power of two >= the phase), displacement and velocity from the same spectrum divided by
//    (i w)^2 and i w; then a smooth (C2) taper of ramp_s at both ends applied to the
//    displacement, a = (win s)''. The plateau's PSD level is grms^2/(f2 - f1).
//  - shock: a half-sine of `peak` over `pulse_s` centred in the phase, between two half-sines of
//    opposite sign, `compensation` times longer and carrying half the main pulse's area each
//    (the pre- and post-pulses of a shaker shock). The profile is symmetric about the centre with
//    zero net area, so velocity and displacement return to zero.
// Not real-time: allocates the phase's arrays. Deterministic: the only draws are the random
// phases, from `seed`.
#include <Eigen/Dense>
#include <cstddef>
#include <cstdint>

namespace inertia::sim {

struct ShakerSegment {
  Eigen::VectorXd a;   // m/s^2 along x_E
  Eigen::VectorXd v;   // m/s
  Eigen::VectorXd x;   // m
};

ShakerSegment sine_segment(double frequency_hz, double amplitude_mps2, double ramp_cycles,
                           std::size_t samples, double sample_rate_hz);
ShakerSegment random_segment(double f1_hz, double f2_hz, double rms_mps2, double ramp_s,
                             std::size_t samples, double sample_rate_hz, std::uint64_t seed);
ShakerSegment shock_segment(double peak_mps2, double pulse_s, double compensation,
                            std::size_t samples, double sample_rate_hz);

/// Window rising over `ramp` (s) at the start of [0, length] and falling over `ramp` at its end:
/// w(u) = u - sin(2 pi u)/(2 pi), u = time into the ramp / ramp, so w, w', w'' are continuous.
/// Value and first two derivatives at t. Exposed for tests.
struct WindowValue {
  double w, dw, ddw;
};
WindowValue ramp_window(double t, double length, double ramp);

}  // namespace inertia::sim
