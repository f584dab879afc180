#include "analyzer/fusion/reference_fusion.hpp"

#include <array>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "common/frames.hpp"

namespace inertia::fusion {
namespace {

constexpr double kPiValue = 3.14159265358979323846;

/// Fourth-order Butterworth low-pass by the bilinear transform with prewarping: the coefficients
/// of its two second-order sections (transposed direct form II).
template <class Section>
void butterworth4_lowpass(double cutoff_hz, double dt_s, std::array<Section, 2>& sections) {
  const double k = std::tan(kPiValue * cutoff_hz * dt_s);   // prewarped analogue cutoff
  // Pole-pair quality factors of a 4th-order Butterworth: 1 / (2 cos(pi/8)), 1 / (2 cos(3 pi/8)).
  const std::array<double, 2> q = {0.54119610014619698, 1.3065629648763766};
  for (std::size_t i = 0; i < 2; ++i) {
    const double norm = 1.0 / (1.0 + k / q[i] + k * k);
    Section& s = sections[i];
    s.b0 = k * k * norm;
    s.b1 = 2.0 * s.b0;
    s.b2 = s.b0;
    s.a1 = 2.0 * (k * k - 1.0) * norm;
    s.a2 = (1.0 - k / q[i] + k * k) * norm;
  }
}

/// First and second central differences of a whole trace (CentralDifferences over it).
void differences(const Eigen::VectorXd& x, double dt_s, Eigen::VectorXd* first, Eigen::VectorXd* second) {
  const Eigen::Index n = x.size();
  if (first != nullptr) first->resize(n);
  if (second != nullptr) second->resize(n);
  CentralDifferences d(dt_s);
  Eigen::Index k = 0;
  const auto drain = [&] {
    while (d.ready()) {
      const CentralDifferences::Value v = d.pop();
      if (first != nullptr) (*first)(k) = v.first;
      if (second != nullptr) (*second)(k) = v.second;
      ++k;
    }
  };
  for (Eigen::Index i = 0; i < n; ++i) {
    d.push(x(i));
    drain();
  }
  d.finish();
  drain();
}

}  // namespace

double ComplementaryFilter::Section::step(double x) {
  const double y = b0 * x + s1;
  s1 = b1 * x - a1 * y + s2;
  s2 = b2 * x - a2 * y;
  return y;
}

void ComplementaryFilter::Section::settle(double u) {
  // The transposed-direct-form-II state of a constant input u at unit DC gain.
  s2 = u * (b2 - a2);
  s1 = u * (b1 - a1) + s2;
}

ComplementaryFilter::ComplementaryFilter(double dt_s, double crossover_hz) {
  if (!(dt_s > 0.0) || !(crossover_hz > 0.0) || crossover_hz >= 0.5 / dt_s) {
    throw std::invalid_argument("fusion: the crossover must lie between 0 and the Nyquist frequency");
  }
  butterworth4_lowpass(crossover_hz, dt_s, encoder_path_);
  butterworth4_lowpass(crossover_hz, dt_s, accel_path_);
}

double ComplementaryFilter::step(double accel_along_axis, double encoder_accel) {
  if (!started_) {
    // Start at steady state on the first sample so a DC level does not ring.
    for (auto& s : encoder_path_) s.settle(encoder_accel);
    for (auto& s : accel_path_) s.settle(accel_along_axis);
    started_ = true;
  }
  double low_encoder = encoder_accel, low_accel = accel_along_axis;
  for (auto& s : encoder_path_) low_encoder = s.step(low_encoder);
  for (auto& s : accel_path_) low_accel = s.step(low_accel);
  low_encoder_ = low_encoder;
  low_accel_ = low_accel;
  // low(encoder acceleration) + accel - low(accel): the same low-pass on both paths makes the pair
  // exactly complementary, so a consistent noise-free input passes unchanged.
  return low_encoder + accel_along_axis - low_accel;
}

void ComplementaryFilter::coast(double encoder_accel) {
  if (!started_) return;   // nothing to carry: the first reading will settle the paths
  (void)step(encoder_accel + (low_accel_ - low_encoder_), encoder_accel);
}

/// The value beyond `near`, on the line through `far` and `near`: 2 near - far.
CentralDifferences::Value CentralDifferences::beyond(const Value& near, const Value& far) {
  return {2.0 * near.first - far.first, 2.0 * near.second - far.second};
}

CentralDifferences::Value CentralDifferences::three_point(int back) const {
  const std::size_t m = last_.size() - 1 - static_cast<std::size_t>(back);   // the sample's slot
  return {(last_[m + 1] - last_[m - 1]) / (2.0 * dt_), (last_[m + 1] - 2.0 * last_[m] + last_[m - 1]) / (dt_ * dt_)};
}

void CentralDifferences::push(double x) {
  last_ = {last_[1], last_[2], last_[3], last_[4], x};
  const std::int64_t n = count_++;
  if (n == 2) at1_ = three_point(1);
  if (n < 4) return;
  // The sample two behind x: three-point first difference, five-point second.
  Value v = three_point(2);
  v.second = (-last_[4] + 16.0 * last_[3] - 30.0 * last_[2] + 16.0 * last_[1] - last_[0]) / (12.0 * dt_ * dt_);
  if (n == 4) {
    out_.push_back(beyond(at1_, v));   // sample 0
    out_.push_back(at1_);
  }
  out_.push_back(v);
  newest_ = v;
}

void CentralDifferences::finish() {
  const std::int64_t n = count_;
  if (n < 3) {
    for (std::int64_t k = 0; k < n; ++k) out_.push_back({});
  } else if (n == 3) {
    for (int k = 0; k < 3; ++k) out_.push_back(at1_);
  } else {
    // Samples n-2 (three-point) and n-1 (2 d(n-2) - d(n-3)); with n = 4, all four samples.
    const Value before = n == 4 ? at1_ : newest_;
    const Value next_to_end = three_point(1);
    if (n == 4) {
      out_.push_back(beyond(at1_, next_to_end));
      out_.push_back(at1_);
    }
    out_.push_back(next_to_end);
    out_.push_back(beyond(next_to_end, before));
  }
  count_ = 0;
}

CentralDifferences::Value CentralDifferences::pop() {
  const Value v = out_.front();
  out_.pop_front();
  return v;
}

MonitorFusion::MonitorFusion(const MonitorLayout& layout) {
  const auto m = static_cast<Eigen::Index>(layout.axes.size());
  if (m < 3 || static_cast<Eigen::Index>(layout.noise_sd_mps2.size()) != m ||
      (!layout.bias_mps2.empty() && static_cast<Eigen::Index>(layout.bias_mps2.size()) != m)) {
    throw std::invalid_argument("fusion: a layout of " + std::to_string(m) +
                                " monitors (at least 3 needed, one noise figure each)");
  }
  h_.resize(m, 3);
  w_.resize(m);
  bias_ = Eigen::VectorXd::Zero(m);
  for (Eigen::Index j = 0; j < m; ++j) {
    const auto idx = static_cast<std::size_t>(j);
    if (layout.axes[idx].norm() == 0.0 || !(layout.noise_sd_mps2[idx] > 0.0)) {
      throw std::invalid_argument("fusion: monitor " + std::to_string(j) + " has a zero axis or a non-positive noise figure");
    }
    h_.row(j) = layout.axes[idx].normalized().transpose();
    w_(j) = 1.0 / (layout.noise_sd_mps2[idx] * layout.noise_sd_mps2[idx]);
    if (!layout.bias_mps2.empty()) bias_(j) = layout.bias_mps2[idx];
  }
  const Eigen::Matrix3d normal = h_.transpose() * w_.asDiagonal() * h_;
  const Eigen::Vector3d eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(normal).eigenvalues();
  if (eigenvalues(0) < 1e-9 * eigenvalues(2)) {
    throw std::invalid_argument("fusion: the monitor axes do not span three dimensions");
  }
  gain_ = normal.ldlt().solve(h_.transpose() * w_.asDiagonal());   // 3 x m
}

Matrix3Columns fuse_monitors(const Eigen::MatrixXd& readings, const MonitorLayout& layout, double* residual_rms) {
  const MonitorFusion fusion(layout);
  if (readings.cols() != fusion.monitors()) {
    throw std::invalid_argument("fusion: " + std::to_string(readings.cols()) + " monitor columns for a layout of " +
                                std::to_string(fusion.monitors()) + " monitors");
  }
  const Eigen::MatrixXd centred = readings.rowwise() - fusion.bias_.transpose();
  Matrix3Columns a = centred * fusion.gain_.transpose();
  if (residual_rms != nullptr) {
    const Eigen::MatrixXd r = (centred - a * fusion.h_.transpose()) * fusion.w_.cwiseSqrt().asDiagonal();
    const double dof = static_cast<double>(readings.rows()) * static_cast<double>(fusion.monitors() - 3);
    *residual_rms = dof > 0 ? std::sqrt(r.squaredNorm() / dof) : 0.0;
  }
  return a;
}

Eigen::VectorXd complementary_vibration(const Eigen::VectorXd& accel_along_axis, const Eigen::VectorXd& displacement_m,
                                        double dt_s, double crossover_hz) {
  if (accel_along_axis.size() != displacement_m.size()) {
    throw std::invalid_argument("fusion: accelerometer and encoder traces differ in length");
  }
  ComplementaryFilter filter(dt_s, crossover_hz);
  Eigen::VectorXd encoder_accel;
  differences(displacement_m, dt_s, nullptr, &encoder_accel);
  Eigen::VectorXd out(accel_along_axis.size());
  for (Eigen::Index k = 0; k < out.size(); ++k) out(k) = filter.step(accel_along_axis(k), encoder_accel(k));
  return out;
}

Eigen::Vector3d table_specific_force_at(double angle_rad, double rate_rad_s, double accel_rad_s2,
                                        const Eigen::Vector3d& axis_unit, const Eigen::Vector3d& f0_e,
                                        const Eigen::Vector3d& position_m) {
  // A vector fixed in the lab, seen from the table top after it turned by angle about u.
  const Eigen::Vector3d gravity_part = frames::frame_rotation(axis_unit, angle_rad) * f0_e;
  const Eigen::Vector3d w = rate_rad_s * axis_unit;
  const Eigen::Vector3d w_dot = accel_rad_s2 * axis_unit;
  return gravity_part + w_dot.cross(position_m) + w.cross(w.cross(position_m));
}

Matrix3Columns table_specific_force(const Eigen::VectorXd& angle_rad, const Eigen::Vector3d& axis,
                                    const Eigen::Vector3d& f0_e, const Eigen::Vector3d& position_m, double dt_s,
                                    Matrix3Columns* rate_e) {
  if (axis.norm() == 0.0) throw std::invalid_argument("fusion: the table axis is zero");
  const Eigen::Vector3d u = axis.normalized();
  Eigen::VectorXd rate, accel;
  differences(angle_rad, dt_s, &rate, &accel);
  Matrix3Columns f(angle_rad.size(), 3);
  if (rate_e != nullptr) rate_e->resize(angle_rad.size(), 3);
  for (Eigen::Index k = 0; k < angle_rad.size(); ++k) {
    f.row(k) = table_specific_force_at(angle_rad(k), rate(k), accel(k), u, f0_e, position_m).transpose();
    if (rate_e != nullptr) rate_e->row(k) = (rate(k) * u).transpose();
  }
  return f;
}

}  // namespace inertia::fusion
