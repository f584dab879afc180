#pragma once
// The bench's reference instruments (paper section 2.3): single-axis monitoring accelerometers in
// a skewed layout, the shaker's control accelerometer on the vibration axis, the linear encoder
// on the armature, the table encoder, and the thermal controller's temperature sensor.
// The dataset's a_x..a_z columns are the true specific force; these channels are what a fusion
// of real references would start from (written to OUT/references/<case>.csv).
#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <vector>

#include "common/config/bench_config.hpp"
#include "hal/sim/bench_motion.hpp"
#include "hal/sim/random_streams.hpp"

namespace inertia::sim {

/// Single-axis accelerometer: m = (1 + scale_error) n_true . f_E + bias + noise (m/s^2), where
/// n_true is the nominal axis turned (actively) by the misalignment: n_true = R^T n with
/// R = misalignment.dcm(). Mounted at the fixture origin (no lever arm).
class SingleAxisAccelerometer {
 public:
  SingleAxisAccelerometer(const config::MonitorAccelerometer& params, std::uint64_t seed);
  /// Real-time safe. Call once per sample in time order.
  double measure(const Eigen::Vector3d& f_e) noexcept {
    return gain_ * axis_true_.dot(f_e) + bias_ + noise_sd_ * rng_.normal();
  }
  [[nodiscard]] const Eigen::Vector3d& true_axis() const { return axis_true_; }

 private:
  Eigen::Vector3d axis_true_;
  double gain_, bias_, noise_sd_;
  RandomSource rng_;
};

/// Encoder counts of a position: floor(value / resolution), as a counter of edges crossed from 0
/// (the position read back, counts * resolution, lies within one resolution below the truth).
inline std::int64_t encoder_counts(double value, double resolution) {
  return static_cast<std::int64_t>(std::floor(value / resolution));
}

struct CaseReferences {
  Eigen::MatrixXd monitors;                 // samples x monitors, m/s^2
  Eigen::VectorXd control;                  // m/s^2; empty without a control accelerometer
  std::vector<std::int64_t> linear_counts;  // empty without a linear encoder
  std::vector<std::int64_t> table_counts;   // empty without a table encoder
  Eigen::VectorXd temp_measured_c;          // fixture temperature sensor
};

CaseReferences simulate_references(const config::BenchConfig& bench, std::size_t case_index,
                                   const CaseMotion& motion);

}  // namespace inertia::sim
