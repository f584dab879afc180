#include "analyzer/fusion/reference_fusion.hpp"

#include <array>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "common/frames.hpp"

namespace inertia::fusion {
namespace {

/// Second-order section in transposed direct form II, for the Butterworth low-pass.
struct Biquad {
  double b0, b1, b2, a1, a2;
  double s1 = 0.0, s2 = 0.0;
  double step(double x) {
    const double y = b0 * x + s1;
    s1 = b1 * x - a1 * y + s2;
    s2 = b2 * x - a2 * y;
    return y;
  }
};

/// Fourth-order Butterworth low-pass by the bilinear transform with prewarping, as two biquads.
std::array<Biquad, 2> butterworth4_lowpass(double cutoff_hz, double dt_s) {
  const double k = std::tan(3.14159265358979323846 * cutoff_hz * dt_s);   // prewarped analogue cutoff
  std::array<Biquad, 2> sections{};
  // Pole-pair quality factors of a 4th-order Butterworth: 1 / (2 cos(pi/8)), 1 / (2 cos(3 pi/8)).
  const std::array<double, 2> q = {0.54119610014619698, 1.3065629648763766};
  for (std::size_t i = 0; i < 2; ++i) {
    const double norm = 1.0 / (1.0 + k / q[i] + k * k);
    Biquad& s = sections[i];
    s.b0 = k * k * norm;
    s.b1 = 2.0 * s.b0;
    s.b2 = s.b0;
    s.a1 = 2.0 * (k * k - 1.0) * norm;
    s.a2 = (1.0 - k / q[i] + k * k) * norm;
  }
  return sections;
}

Eigen::VectorXd lowpass(const Eigen::VectorXd& x, double cutoff_hz, double dt_s) {
  auto sections = butterworth4_lowpass(cutoff_hz, dt_s);
  // Start at steady state for the first sample so a DC level does not ring.
  Eigen::VectorXd y(x.size());
  if (x.size() == 0) return y;
  for (auto& s : sections) {
    // For a constant input u the TDF-II steady state is s1 = u (1 - b0) ... solved for unit DC gain.
    const double u = x(0);
    s.s2 = u * (s.b2 - s.a2);
    s.s1 = u * (s.b1 - s.a1) + s.s2;
  }
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    double v = x(k);
    for (auto& s : sections) v = s.step(v);
    y(k) = v;
  }
  return y;
}

void extrapolate_ends(Eigen::VectorXd& d) {
  const Eigen::Index n = d.size();
  if (n < 4) {
    d(0) = d(1);
    d(n - 1) = d(n - 2);
    return;
  }
  d(0) = 2.0 * d(1) - d(2);
  d(n - 1) = 2.0 * d(n - 2) - d(n - 3);
}

/// Second derivative by central differences; the end samples are extrapolated linearly so that a
/// smooth trace has no step at the ends for the filters to ring on.
Eigen::VectorXd second_derivative(const Eigen::VectorXd& x, double dt_s) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd d = Eigen::VectorXd::Zero(n);
  if (n < 3) return d;
  d.segment(1, n - 2) = (x.tail(n - 2) - 2.0 * x.segment(1, n - 2) + x.head(n - 2)) / (dt_s * dt_s);
  extrapolate_ends(d);
  return d;
}

Eigen::VectorXd first_derivative(const Eigen::VectorXd& x, double dt_s) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd d = Eigen::VectorXd::Zero(n);
  if (n < 3) return d;
  d.segment(1, n - 2) = (x.tail(n - 2) - x.head(n - 2)) / (2.0 * dt_s);
  extrapolate_ends(d);
  return d;
}

}  // namespace

Matrix3Columns fuse_monitors(const Eigen::MatrixXd& readings, const MonitorLayout& layout, double* residual_rms) {
  const auto m = static_cast<Eigen::Index>(layout.axes.size());
  if (m < 3 || readings.cols() != m || static_cast<Eigen::Index>(layout.noise_sd_mps2.size()) != m ||
      (!layout.bias_mps2.empty() && static_cast<Eigen::Index>(layout.bias_mps2.size()) != m)) {
    throw std::invalid_argument("fusion: " + std::to_string(readings.cols()) + " monitor columns for a layout of " +
                                std::to_string(m) + " monitors (at least 3 needed, one noise figure each)");
  }
  Eigen::MatrixXd h(m, 3);
  Eigen::VectorXd w(m);
  Eigen::RowVectorXd bias = Eigen::RowVectorXd::Zero(m);
  for (Eigen::Index j = 0; j < m; ++j) {
    const auto idx = static_cast<std::size_t>(j);
    if (layout.axes[idx].norm() == 0.0 || !(layout.noise_sd_mps2[idx] > 0.0)) {
      throw std::invalid_argument("fusion: monitor " + std::to_string(j) + " has a zero axis or a non-positive noise figure");
    }
    h.row(j) = layout.axes[idx].normalized().transpose();
    w(j) = 1.0 / (layout.noise_sd_mps2[idx] * layout.noise_sd_mps2[idx]);
    if (!layout.bias_mps2.empty()) bias(j) = layout.bias_mps2[idx];
  }
  const Eigen::Matrix3d normal = h.transpose() * w.asDiagonal() * h;
  const Eigen::Vector3d eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(normal).eigenvalues();
  if (eigenvalues(0) < 1e-9 * eigenvalues(2)) {
    throw std::invalid_argument("fusion: the monitor axes do not span three dimensions");
  }
  const Eigen::MatrixXd gain = normal.ldlt().solve(h.transpose() * w.asDiagonal());   // 3 x m
  const Eigen::MatrixXd centred = readings.rowwise() - bias;
  Matrix3Columns a = centred * gain.transpose();
  if (residual_rms != nullptr) {
    const Eigen::MatrixXd r = (centred - a * h.transpose()) * w.cwiseSqrt().asDiagonal();
    const double dof = static_cast<double>(readings.rows()) * static_cast<double>(m - 3);
    *residual_rms = dof > 0 ? std::sqrt(r.squaredNorm() / dof) : 0.0;
  }
  return a;
}

Eigen::VectorXd complementary_vibration(const Eigen::VectorXd& accel_along_axis, const Eigen::VectorXd& displacement_m,
                                        double dt_s, double crossover_hz) {
  if (accel_along_axis.size() != displacement_m.size()) {
    throw std::invalid_argument("fusion: accelerometer and encoder traces differ in length");
  }
  if (!(dt_s > 0.0) || !(crossover_hz > 0.0) || crossover_hz >= 0.5 / dt_s) {
    throw std::invalid_argument("fusion: the crossover must lie between 0 and the Nyquist frequency");
  }
  // low(encoder acceleration) + accel - low(accel): the same low-pass on both paths makes the pair
  // exactly complementary, so a consistent noise-free input passes unchanged.
  const Eigen::VectorXd encoder_accel = second_derivative(displacement_m, dt_s);
  return lowpass(encoder_accel, crossover_hz, dt_s) + accel_along_axis - lowpass(accel_along_axis, crossover_hz, dt_s);
}

Matrix3Columns table_specific_force(const Eigen::VectorXd& angle_rad, const Eigen::Vector3d& axis,
                                    const Eigen::Vector3d& f0_e, const Eigen::Vector3d& position_m, double dt_s,
                                    Matrix3Columns* rate_e) {
  if (axis.norm() == 0.0) throw std::invalid_argument("fusion: the table axis is zero");
  const Eigen::Vector3d u = axis.normalized();
  const Eigen::VectorXd rate = first_derivative(angle_rad, dt_s);
  const Eigen::VectorXd accel = second_derivative(angle_rad, dt_s);
  Matrix3Columns f(angle_rad.size(), 3);
  if (rate_e != nullptr) rate_e->resize(angle_rad.size(), 3);
  for (Eigen::Index k = 0; k < angle_rad.size(); ++k) {
    // A vector fixed in the lab, seen from the table top after it turned by angle about u.
    const Eigen::Vector3d gravity_part = frames::frame_rotation(u, angle_rad(k)) * f0_e;
    const Eigen::Vector3d w = rate(k) * u;
    const Eigen::Vector3d w_dot = accel(k) * u;
    f.row(k) = (gravity_part + w_dot.cross(position_m) + w.cross(w.cross(position_m))).transpose();
    if (rate_e != nullptr) rate_e->row(k) = w.transpose();
  }
  return f;
}

}  // namespace inertia::fusion
