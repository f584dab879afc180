#pragma once
// Kalibr's scale-misalignment IMU model ("scale-misalignment" in its camchain-imucam results) of a
// unit's triads:
//   accelerometers  a_m = M_a C a + b_a
//   gyroscopes      w_m = M_g C_gyro_i C w + A C_gyro_i C a + b_g
// with a, w the specific force and rate in the unit's frame, M_a and M_g lower triangular, C the
// rotation from the unit's frame to Kalibr's IMU frame (the one M_a's triangle fixes: its x along
// the x accelerometer, its y in the plane of x and y), C_gyro_i the gyroscopes' rotation from
// there. a_m and w_m are what a driver publishes: each output in SI, its value times its unit's
// (g: 9.80665 m/s^2). So S = K R (triad_frame.hpp) times that factor is M C, an LQ decomposition
// with M's diagonal positive; A is K_ga times the gyroscopes' factor, turned to Kalibr's gyroscope
// frame.
#include <Eigen/Dense>

#include <optional>
#include <string>

#include "analyzer/unit/triad_frame.hpp"

namespace inertia::unit {

struct KalibrIntrinsics {
  std::optional<Eigen::Matrix3d> m_accel;          // M_a (with the accelerometer triad)
  Eigen::Matrix3d c_imu_unit = Eigen::Matrix3d::Identity();   // C: unit frame to Kalibr's IMU frame
  std::optional<Eigen::Matrix3d> m_gyro, a_gyro;   // M_g, A ((rad/s) per m/s^2)
  Eigen::Matrix3d c_gyro_i = Eigen::Matrix3d::Identity();
  std::string note;                                 // what could not be expressed, and why
};

/// Kalibr's noise parameters of one output, continuous time, in SI over its static sensitivity:
/// the noise density N (else white_sd sqrt(sample period), `density_from_white`) and the random
/// walk K; nullopt where the model does not determine them.
struct KalibrNoise {
  std::optional<double> density, random_walk;
  bool density_from_white = false;
};
KalibrNoise kalibr_noise(const model::ModelFile& model);
/// Kalibr's imu.yaml lines of `kind` ("accelerometer" or "gyroscope"): each value with its unit
/// and source, or a comment that says why it is not determined.
std::string kalibr_noise_yaml(const std::string& kind, const KalibrNoise& noise);

/// The SI value of one `output_unit` of a triad of `kind` (g: 9.80665, deg/s: pi/180), or nullopt
/// for a unit that is not one of the sensed quantity (V, counts): a driver's conversion from it is
/// not in the model.
std::optional<double> si_factor(dataset::SensorKind kind, const std::string& output_unit);

/// Kalibr's intrinsics of the triads given (either may be absent). A triad whose outputs have no
/// SI factor, or whose sensitivity matrix is left-handed or singular, is left out, and `note` says
/// why.
KalibrIntrinsics kalibr_intrinsics(const std::optional<TriadFrame>& accelerometers, const std::optional<TriadFrame>& gyroscopes);

}  // namespace inertia::unit
