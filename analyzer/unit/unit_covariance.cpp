#include "analyzer/unit/unit_covariance.hpp"

#include <cmath>
#include <limits>
#include <utility>

#include "analyzer/model/coefficient_uncertainty.hpp"
#include "analyzer/unit/kalibr_intrinsics.hpp"

namespace inertia::unit {

namespace {

using Eigen::Index;

/// A 3 x 3 matrix's elements row by row.
Eigen::VectorXd elements(const Eigen::Matrix3d& m) {
  Eigen::VectorXd v(9);
  for (Index r = 0; r < 3; ++r)
    for (Index c = 0; c < 3; ++c) v(3 * r + c) = m(r, c);
  return v;
}

Eigen::Matrix3d matrix_of(const Eigen::VectorXd& v, Index at) {
  Eigen::Matrix3d m;
  for (Index r = 0; r < 3; ++r)
    for (Index c = 0; c < 3; ++c) m(r, c) = v(at + 3 * r + c);
  return m;
}

/// The rotation vector d of `turned` = exp([d]x) `from`.
Eigen::VectorXd rotation_between(const Eigen::Matrix3d& turned, const Eigen::Matrix3d& from) {
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(turned * from.transpose()));
  Eigen::VectorXd d(3);
  for (Index k = 0; k < 3; ++k) d(k) = aa.angle() * aa.axis()(k);
  return d;
}

/// K (diagonal) and R of a sensitivity matrix S = K R.
std::pair<Eigen::Matrix3d, Eigen::Matrix3d> scale_and_axes(const Eigen::Matrix3d& s) {
  Eigen::Matrix3d k = Eigen::Matrix3d::Zero(), r;
  for (Index row = 0; row < 3; ++row) {
    k(row, row) = s.row(row).norm();
    r.row(row) = s.row(row) / k(row, row);
  }
  return {k, r};
}

}  // namespace

Eigen::MatrixXd UnitParameter::sd() const {
  const Eigen::VectorXd d = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  if (value.cols() == 1 || rotation) return d;
  return matrix_of(d, 0);
}

std::vector<UnitParameter> unit_parameters(const Triads& triads) {
  const std::optional<TriadFrame>& acc = triads.accelerometer;
  const std::optional<TriadFrame>& gyro = triads.gyroscope;
  // x: the accelerometers' S row by row, then the gyroscopes' S and K_ga; its covariance from each
  // member's joint covariance of (s_k, g_k).
  const Index acc_at = 0, gyro_at = acc ? 9 : 0, g_at = gyro_at + 9;
  const Index n = (acc ? 9 : 0) + (gyro ? 18 : 0);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd x_covariance = Eigen::MatrixXd::Zero(n, n);
  if (acc) {
    x.segment(acc_at, 9) = elements(acc->sensitivity);
    for (Index k = 0; k < 3; ++k) x_covariance.block(acc_at + 3 * k, acc_at + 3 * k, 3, 3) = acc->axes[static_cast<std::size_t>(k)].covariance;
  }
  if (gyro) {
    x.segment(gyro_at, 9) = elements(gyro->sensitivity);
    x.segment(g_at, 9) = elements(gyro->g_sensitivity);
    for (Index k = 0; k < 3; ++k) {
      const Eigen::Matrix<double, 6, 6>& j = gyro->axes[static_cast<std::size_t>(k)].joint_covariance;
      const Index s = gyro_at + 3 * k, g = g_at + 3 * k;
      x_covariance.block(s, s, 3, 3) = j.topLeftCorner(3, 3);
      x_covariance.block(g, g, 3, 3) = j.bottomRightCorner(3, 3);
      x_covariance.block(s, g, 3, 3) = j.topRightCorner(3, 3);
      x_covariance.block(g, s, 3, 3) = j.bottomLeftCorner(3, 3);
    }
  }
  const KalibrIntrinsics kalibr = kalibr_intrinsics(acc, gyro);

  // Every parameter that depends on x, as one vector: its entries' names and sizes in order.
  std::vector<UnitParameter> out;
  const auto triads_at = [&](const Eigen::VectorXd& at) {
    std::optional<TriadFrame> a = acc, g = gyro;
    if (a) a->sensitivity = matrix_of(at, acc_at);
    if (g) {
      g->sensitivity = matrix_of(at, gyro_at);
      g->g_sensitivity = matrix_of(at, g_at);
    }
    return std::pair{a, g};
  };
  const auto parameters = [&](const Eigen::VectorXd& at) -> Eigen::VectorXd {
    const auto [a, g] = triads_at(at);
    std::vector<Eigen::VectorXd> parts;
    if (a) {
      const auto [k, r] = scale_and_axes(a->sensitivity);
      parts.push_back(elements(k));
      parts.push_back(elements(r));
    }
    if (g) {
      const auto [k, r] = scale_and_axes(g->sensitivity);
      parts.push_back(elements(k));
      parts.push_back(elements(r));
      parts.push_back(elements(g->g_sensitivity));
    }
    // A step that leaves Kalibr's form (a sign flip of the decomposition) reads as not a number.
    const KalibrIntrinsics turned = kalibr_intrinsics(a, g);
    const Eigen::VectorXd lost = Eigen::VectorXd::Constant(9, std::numeric_limits<double>::quiet_NaN());
    if (kalibr.m_accel) {
      parts.push_back(turned.m_accel ? elements(*turned.m_accel) : lost);
      parts.push_back(turned.m_accel ? rotation_between(turned.c_imu_unit, kalibr.c_imu_unit) : Eigen::VectorXd(lost.head(3)));
    }
    if (kalibr.m_gyro) {
      if (!kalibr.m_accel)
        parts.push_back(turned.m_gyro ? rotation_between(turned.c_imu_unit, kalibr.c_imu_unit) : Eigen::VectorXd(lost.head(3)));
      parts.push_back(turned.m_gyro ? elements(*turned.m_gyro) : lost);
      parts.push_back(turned.m_gyro ? elements(*turned.a_gyro) : lost);
      parts.push_back(turned.m_gyro ? rotation_between(turned.c_gyro_i, kalibr.c_gyro_i) : Eigen::VectorXd(lost.head(3)));
    }
    Index size = 0;
    for (const Eigen::VectorXd& p : parts) size += p.size();
    Eigen::VectorXd v(size);
    Index at_v = 0;
    for (const Eigen::VectorXd& p : parts) {
      v.segment(at_v, p.size()) = p;
      at_v += p.size();
    }
    return v;
  };
  const Eigen::MatrixXd covariance = model::delta_method_covariance(parameters, x, x_covariance);

  Index at = 0;
  const auto take = [&](std::string name, Eigen::MatrixXd value, bool rotation = false) {
    const Index size = rotation ? 3 : value.size();
    out.push_back({std::move(name), std::move(value), covariance.block(at, at, size, size), rotation});
    at += size;
  };
  const auto bias = [&](std::string name, const TriadFrame& f) {
    out.push_back({std::move(name), f.bias, f.bias_sd.array().square().matrix().asDiagonal().toDenseMatrix(), false});
  };
  if (acc) {
    const auto [k, r] = scale_and_axes(acc->sensitivity);
    take("K_a", k);
    take("R_a", r);
  }
  if (gyro) {
    const auto [k, r] = scale_and_axes(gyro->sensitivity);
    take("K_g", k);
    take("R_g", r);
    take("K_ga", gyro->g_sensitivity);
  }
  if (kalibr.m_accel) {
    take("M_a", *kalibr.m_accel);
    take("C", kalibr.c_imu_unit, true);
  }
  if (kalibr.m_gyro) {
    if (!kalibr.m_accel) take("C", kalibr.c_imu_unit, true);
    take("M_g", *kalibr.m_gyro);
    take("A", *kalibr.a_gyro);
    take("C_gyro_i", kalibr.c_gyro_i, true);
  }
  if (acc) bias("b_a", *acc);
  if (gyro) bias("b_g", *gyro);
  return out;
}

}  // namespace inertia::unit
