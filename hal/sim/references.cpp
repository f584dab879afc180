#include "hal/sim/references.hpp"

#include <vector>

namespace inertia::sim {

SingleAxisAccelerometer::SingleAxisAccelerometer(const config::MonitorAccelerometer& params, std::uint64_t seed)
    : axis_true_(params.misalignment.dcm().transpose() * params.axis.normalized()),
      gain_(1.0 + params.scale_error), bias_(params.bias_mps2), noise_sd_(params.noise_sd_mps2), rng_(seed) {}

CaseReferences simulate_references(const config::BenchConfig& bench, std::size_t case_index,
                                   const CaseMotion& motion) {
  const auto n = static_cast<Eigen::Index>(motion.size());
  const auto nm = static_cast<Eigen::Index>(bench.monitors.size());
  CaseReferences r;
  r.monitors.resize(n, nm);
  std::vector<SingleAxisAccelerometer> monitors;
  for (Eigen::Index j = 0; j < nm; ++j) {
    monitors.emplace_back(bench.monitors[static_cast<std::size_t>(j)],
                          derive_seed(bench.seed, {static_cast<std::uint64_t>(Stream::Monitor), case_index,
                                                   static_cast<std::uint64_t>(j)}));
  }
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Vector3d f = motion.f_e.row(k).transpose();
    for (Eigen::Index j = 0; j < nm; ++j) r.monitors(k, j) = monitors[static_cast<std::size_t>(j)].measure(f);
  }
  if (bench.control_accelerometer) {
    SingleAxisAccelerometer acc(*bench.control_accelerometer,
                                derive_seed(bench.seed, {static_cast<std::uint64_t>(Stream::Control), case_index}));
    r.control.resize(n);
    for (Eigen::Index k = 0; k < n; ++k) r.control[k] = acc.measure(motion.f_e.row(k).transpose());
  }
  if (bench.linear_encoder.present) {
    r.linear_counts.resize(motion.size());
    for (Eigen::Index k = 0; k < n; ++k) {
      r.linear_counts[static_cast<std::size_t>(k)] = encoder_counts(motion.shaker_x_m[k], bench.linear_encoder.resolution);
    }
  }
  if (bench.table_encoder.present) {
    r.table_counts.resize(motion.size());
    for (Eigen::Index k = 0; k < n; ++k) {
      r.table_counts[static_cast<std::size_t>(k)] =
          encoder_counts(motion.table_angle_rad[k], bench.table_encoder.resolution);
    }
  }
  RandomSource temp_rng(derive_seed(bench.seed, {static_cast<std::uint64_t>(Stream::Thermal), case_index}));
  r.temp_measured_c.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    r.temp_measured_c[k] = motion.temp_c[k] + bench.thermal.sensor_noise_sd_c * temp_rng.normal();
  }
  return r;
}

}  // namespace inertia::sim
