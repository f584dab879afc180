#include "analyzer/unit/kalibr_intrinsics.hpp"

#include <fmt/format.h>

#include <cmath>

#include "analyzer/compensate/static_response.hpp"
#include "common/units.hpp"

namespace inertia::unit {

namespace {

/// S = L Q with L lower triangular of positive diagonal and Q a rotation; nullopt where S is
/// singular or left-handed (Q would be a reflection).
std::optional<std::pair<Eigen::Matrix3d, Eigen::Matrix3d>> lq(const Eigen::Matrix3d& s) {
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr(s.transpose());   // S' = Q R, so S = R' Q'
  const Eigen::Matrix3d r = qr.matrixQR().triangularView<Eigen::Upper>();
  const Eigen::Matrix3d q = qr.householderQ();
  Eigen::Matrix3d l = r.transpose(), rotation = q.transpose();
  for (int k = 0; k < 3; ++k) {
    if (l(k, k) == 0.0 || !std::isfinite(l(k, k))) return std::nullopt;
    if (l(k, k) < 0.0) {
      l.col(k) *= -1.0;
      rotation.row(k) *= -1.0;
    }
  }
  if (rotation.determinant() < 0.0) return std::nullopt;
  return std::pair{l, rotation};
}

}  // namespace

KalibrNoise kalibr_noise(const model::ModelFile& model) {
  // Kalibr's noise density is continuous-time: sigma_c = sigma_d sqrt(dt), i.e. N (IEEE 952's
  // white-noise coefficient, output unit s^1/2); its random walk is K (output unit s^-1/2); both
  // over the static sensitivity to reach SI.
  const double s = std::abs(compensate::static_sensitivity(
      model, model.sensor == dataset::SensorKind::Accelerometer ? ident::Variable::Ai : ident::Variable::Wi));
  KalibrNoise k;
  const std::optional<double> n = model.noise.values[1], random_walk = model.noise.values[3];
  if (n) {
    k.density = *n / s;
  } else if (model.white_sd && model.sample_period_s) {
    k.density = *model.white_sd * std::sqrt(*model.sample_period_s) / s;
    k.density_from_white = true;
  }
  if (random_walk) k.random_walk = *random_walk / s;
  if (k.density && !std::isfinite(*k.density)) k.density.reset();
  if (k.random_walk && !std::isfinite(*k.random_walk)) k.random_walk.reset();
  return k;
}

std::string kalibr_noise_yaml(const std::string& kind, const KalibrNoise& noise) {
  const bool acc = kind == "accelerometer";
  std::string yaml;
  if (noise.density) {
    yaml += fmt::format("{}_noise_density: {:.6g} # {}/sqrt(Hz), continuous time{}\n", kind, *noise.density, acc ? "m/s^2" : "rad/s",
                        noise.density_from_white ? " (from white_sd: this plan's static stretches gave no N)" : " (N)");
  } else {
    yaml += fmt::format("# {}_noise_density: not determined (the model has neither N nor white_sd with sample_period_s)\n", kind);
  }
  if (noise.random_walk) {
    yaml += fmt::format("{}_random_walk: {:.6g} # {}/sqrt(Hz), continuous time (K)\n", kind, *noise.random_walk, acc ? "m/s^3" : "rad/s^2");
  } else {
    yaml += fmt::format("# {}_random_walk: not determined: the model has no K (the noise analysis of the plan's static "
                        "stretches did not resolve a rate random walk; a longer rest can)\n",
                        kind);
  }
  return yaml;
}

std::optional<double> si_factor(dataset::SensorKind kind, const std::string& output_unit) {
  if (kind == dataset::SensorKind::Accelerometer) {
    if (output_unit == "m/s^2" || output_unit == "m/s2") return 1.0;
    if (output_unit == "g") return kStandardGravity;
    if (output_unit == "mg") return 1e-3 * kStandardGravity;
    return std::nullopt;
  }
  if (output_unit == "rad/s") return 1.0;
  if (output_unit == "deg/s") return kPi / 180.0;
  if (output_unit == "deg/h") return kPi / 180.0 / 3600.0;
  return std::nullopt;
}

KalibrIntrinsics kalibr_intrinsics(const std::optional<TriadFrame>& accelerometers, const std::optional<TriadFrame>& gyroscopes) {
  KalibrIntrinsics k;
  const auto normalized = [&](const TriadFrame& f) -> std::optional<Eigen::Matrix3d> {
    const std::optional<double> factor = si_factor(f.kind, f.output_unit);
    if (!factor) {
      k.note += fmt::format("the {} outputs are in '{}', which is no unit of the sensed quantity: Kalibr's M relates a driver's SI "
                            "measurement to the input, and the driver's conversion is not in the model; ",
                            dataset::to_string(f.kind), f.output_unit);
      return std::nullopt;
    }
    return Eigen::Matrix3d(f.sensitivity * *factor);
  };
  if (accelerometers) {
    if (const std::optional<Eigen::Matrix3d> s = normalized(*accelerometers)) {
      if (const auto m_c = lq(*s)) {
        k.m_accel = m_c->first;
        k.c_imu_unit = m_c->second;
      } else {
        k.note += "the accelerometers' sensitivity matrix is singular or left-handed: no rotation takes the unit's frame to it; ";
      }
    }
  }
  if (gyroscopes) {
    const std::optional<Eigen::Matrix3d> s = normalized(*gyroscopes);
    // Without the accelerometers' frame, Kalibr's IMU frame is the gyroscopes' own.
    const auto m_c = s ? lq(*s * k.c_imu_unit.transpose()) : std::nullopt;
    if (s && !m_c) k.note += "the gyroscopes' sensitivity matrix is singular or left-handed; ";
    if (m_c) {
      k.m_gyro = m_c->first;
      k.c_gyro_i = m_c->second;
      if (!k.m_accel) {
        k.c_imu_unit = k.c_gyro_i;
        k.c_gyro_i = Eigen::Matrix3d::Identity();
      }
      // w_m = ... + factor K_ga a = A C_gyro_i C a, so A = factor K_ga C' C_gyro_i'.
      const double factor = *si_factor(gyroscopes->kind, gyroscopes->output_unit);
      k.a_gyro = Eigen::Matrix3d(factor * gyroscopes->g_sensitivity * k.c_imu_unit.transpose() * k.c_gyro_i.transpose());
    }
  }
  return k;
}

}  // namespace inertia::unit
