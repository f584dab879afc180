#include "hal/sim/bench_motion.hpp"

#include <cmath>

#include "common/config/phase_label.hpp"
#include "common/frames.hpp"
#include "common/units.hpp"
#include "hal/sim/random_streams.hpp"
#include "hal/sim/shaker_profiles.hpp"

namespace inertia::sim {

namespace {

using config::PhaseKind;

std::uint16_t label_index(CaseMotion& m, const char* label) {
  for (std::size_t i = 0; i < m.phase_names.size(); ++i) {
    if (m.phase_names[i] == label) return static_cast<std::uint16_t>(i);
  }
  m.phase_names.emplace_back(label);
  return static_cast<std::uint16_t>(m.phase_names.size() - 1);
}

// theta, theta', theta'' of a rotation phase at time t from its start.
struct Angle {
  double th, rate, acc;
};
Angle rotation_angle(const config::Phase& p, double t) {
  if (p.rate_rad_s) return {*p.rate_rad_s * t, *p.rate_rad_s, 0.0};
  const double d = p.duration_s, big = *p.angle_rad, k = 2.0 * kPi / d;
  return {big * (t / d - std::sin(k * t) / (2.0 * kPi)), big / d * (1.0 - std::cos(k * t)),
          big / d * k * std::sin(k * t)};
}

}  // namespace

CaseMotion simulate_motion(const config::BenchConfig& bench, std::size_t case_index, ThermalModel& thermal) {
  const config::TestCase& tc = bench.cases.at(case_index);
  const double fs = bench.sample_rate_hz;
  std::size_t total = 0;
  std::vector<std::size_t> counts;
  for (const config::Phase& p : tc.phases) {
    counts.push_back(static_cast<std::size_t>(std::llround(p.duration_s * fs)));
    total += counts.back();
  }
  const auto n = static_cast<Eigen::Index>(total);
  CaseMotion m;
  m.sample_rate_hz = fs;
  m.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) / fs);
  m.f_e.setZero(n, 3);
  m.w_e.setZero(n, 3);
  m.dw_e.setZero(n, 3);
  m.shaker_x_m.setZero(n);
  m.table_angle_rad.setZero(n);
  m.temp_c.resize(n);
  m.phase.resize(total);

  const double g0 = kStandardGravity;
  frames::Dcm attitude = tc.start_attitude.dcm();   // M_L^E
  double table_angle = 0.0;
  std::size_t k0 = 0;
  for (std::size_t pi = 0; pi < tc.phases.size(); ++pi) {
    const config::Phase& p = tc.phases[pi];
    const std::size_t count = counts[pi];
    m.spans.push_back({p.kind, k0, k0 + count});
    const std::uint16_t label = label_index(m, config::phase_label(p.kind));
    if (p.kind == PhaseKind::ThermalStep) thermal.set_setpoint(p.setpoint_c);

    ShakerSegment shaker;
    if (p.kind == PhaseKind::Sine) {
      shaker = sine_segment(p.frequency_hz, p.amplitude_mps2, p.ramp_cycles, count, fs);
    } else if (p.kind == PhaseKind::Random) {
      const std::uint64_t seed = derive_seed(
          bench.seed, {static_cast<std::uint64_t>(Stream::RandomVibration), case_index, pi});
      shaker = random_segment(p.f1_hz, p.f2_hz, p.rms_mps2, p.ramp_s, count, fs, seed);
    } else if (p.kind == PhaseKind::Shock) {
      shaker = shock_segment(p.peak_mps2, p.pulse_s, p.compensation, count, fs);
    }
    const bool on_shaker = shaker.a.size() > 0;
    const frames::Dcm phase_start_attitude = attitude;
    const double phase_start_angle = table_angle;

    for (std::size_t j = 0; j < count; ++j) {
      const std::size_t k = k0 + j;
      const auto r = static_cast<Eigen::Index>(k);
      const double t = static_cast<double>(j) / fs;
      m.phase[k] = label;
      if (tc.kind == config::CaseKind::RotationTable) {
        if (p.kind == PhaseKind::Rotation) {
          const Angle a = rotation_angle(p, t);
          attitude = frames::frame_rotation(p.axis, a.th) * phase_start_attitude;
          table_angle = phase_start_angle + a.th;
          m.w_e.row(r) = a.rate * p.axis.transpose();
          m.dw_e.row(r) = a.acc * p.axis.transpose();
        }
        m.f_e.row(r) = g0 * attitude.col(2).transpose();   // M_L^E (0, 0, g0)
      } else {
        m.f_e(r, 2) = g0;
        if (on_shaker) {
          m.f_e(r, 0) = shaker.a[static_cast<Eigen::Index>(j)];
          m.shaker_x_m[r] = shaker.x[static_cast<Eigen::Index>(j)];
        }
      }
      m.table_angle_rad[r] = table_angle;
      m.temp_c[r] = thermal.temperature_c();
      thermal.step();
    }
    // The next phase starts where this one ended (theta(D), not theta at the last sample).
    if (p.kind == PhaseKind::Rotation) {
      const Angle end = rotation_angle(p, static_cast<double>(count) / fs);
      attitude = frames::frame_rotation(p.axis, end.th) * phase_start_attitude;
      table_angle = phase_start_angle + end.th;
    }
    k0 += count;
  }
  return m;
}

}  // namespace inertia::sim
