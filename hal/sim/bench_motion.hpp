#pragma once
// One test case of the test plan as bench motion, sampled at the bench rate: what the rotation
// table or the shaker does to the fixture, the fixture temperature, and the phase labels.
// Frames and conventions (docs/design.md): F_E is the table top / shaker frame; the reference is the
// specific force f = a - g written in F_E (at rest, level: +1 g along z_E, "gravity reaction").
//  - rotation_table: the table top's attitude in the lab (z up) starts at the case's
//    start_attitude (F_E = lab rotated by it) and rotates about each phase's axis (fixed in F_E
//    and in the lab): M_L^E(t) = frame_rotation(axis, theta(t)) M_L^E(phase start). So gravity
//    seen in F_E rotates with the table angle, f_E = M_L^E (0, 0, g0), and w_E = theta'(t) axis.
//    `rate_deg_s`: constant rate from the phase's first sample. `angle_deg`: theta(t) =
//    angle (t/D - sin(2 pi t/D)/(2 pi)), a raised-cosine rate that starts and ends at rest.
//  - shaker: F_E fixed in the lab, horizontal slip table: f_E = (a_x(t), 0, g0), profiles in
//    shaker_profiles.hpp.
//  - thermal, static: f_E = (0, 0, g0).
// Every case starts at t = 0 and from rest; the fixture temperature carries over from case to case
// (one thermal model for the whole plan, run in plan order).
#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "hal/sim/thermal_model.hpp"

namespace inertia::sim {

using Columns3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;

struct PhaseSpan {
  config::PhaseKind kind;
  std::size_t begin = 0;   // first sample
  std::size_t end = 0;     // one past the last sample
};

struct CaseMotion {
  double sample_rate_hz = 0.0;
  Eigen::VectorXd t;                  // s, k / fs
  Columns3 f_e;                       // specific force at the fixture origin, F_E, m/s^2
  Columns3 w_e;                       // angular rate of F_E, rad/s
  Columns3 dw_e;                      // angular acceleration, rad/s^2 (lever arms)
  Eigen::VectorXd shaker_x_m;         // armature displacement along x_E (0 off the shaker)
  Eigen::VectorXd table_angle_rad;    // table angle accumulated over the case's rotations
  Eigen::VectorXd temp_c;             // fixture temperature (truth)
  std::vector<std::string> phase_names;   // distinct labels in order of first appearance
  std::vector<std::uint16_t> phase;       // per sample, index into phase_names
  std::vector<PhaseSpan> spans;           // one per [[case.phase]], in order

  [[nodiscard]] std::size_t size() const { return static_cast<std::size_t>(t.size()); }
};

/// Simulates case `case_index` of the plan. `thermal` is advanced one step per sample.
/// Not real-time (allocates the case's arrays).
CaseMotion simulate_motion(const config::BenchConfig& bench, std::size_t case_index, ThermalModel& thermal);

/// Specific force at `position_m` (F_E, from the origin on the rotation axis) of a rigid fixture:
/// f + dw x r + w x (w x r).
inline Eigen::Vector3d specific_force_at(const Eigen::Vector3d& f, const Eigen::Vector3d& w,
                                         const Eigen::Vector3d& dw, const Eigen::Vector3d& r) {
  return f + dw.cross(r) + w.cross(w.cross(r));
}

}  // namespace inertia::sim
