#pragma once
// Ground truth by sensor fusion (the paper's section 2.3): the fixture's specific force in F_E
// from the references that surround the sensors under test.
//  - Skewed single-axis monitoring accelerometers: at each sample a weighted least-squares fit of
//    the 3D specific force to the projections m_j = n_j . a + b_j + noise (section 2.3: no two
//    monitors share an orientation, so N has full column rank and one reading is redundant).
//  - The linear encoder on the shaker armature: displacement is exact at low frequency where an
//    accelerometer's bias and 1/f noise dominate, and useless at high frequency where its
//    quantization, differentiated twice, explodes; a complementary filter hands over between the
//    two along the vibration axis at `crossover_hz`.
//  - The rotation-table encoder: gravity turned by the table angle, plus the centripetal and
//    tangential terms of the sensor's offset from the axis.
// All inputs and outputs SI (m/s^2, m, rad, rad/s, s).
#include <Eigen/Dense>
#include <vector>

namespace inertia::fusion {

using Matrix3Columns = Eigen::Matrix<double, Eigen::Dynamic, 3>;

struct MonitorLayout {
  std::vector<Eigen::Vector3d> axes;   // nominal sensitive axes in F_E (normalized internally)
  std::vector<double> noise_sd_mps2;   // per monitor; weights are 1 / sd^2
  std::vector<double> bias_mps2;       // known (calibrated) biases, subtracted; empty = zero
};

/// Per-sample weighted least squares over the monitors. `readings` is N x m (m >= 3 monitors).
/// Throws std::invalid_argument when the layout does not span 3D or sizes disagree.
/// `residual_rms` receives the RMS of the weighted post-fit residuals (a consistency check of the
/// layout: it should be near 1 when the noise figures are right and the axes are where stated).
Matrix3Columns fuse_monitors(const Eigen::MatrixXd& readings, const MonitorLayout& layout,
                             double* residual_rms = nullptr);

/// Complementary fusion along one axis: low frequencies from the encoder displacement
/// (differentiated twice), high frequencies from the accelerometer estimate, with second-order
/// (critically damped) complementary filters at `crossover_hz`, so the sum of both paths is exact
/// for a noise-free input. `accel_along_axis` and `displacement_m` are sampled at 1/dt_s.
Eigen::VectorXd complementary_vibration(const Eigen::VectorXd& accel_along_axis, const Eigen::VectorXd& displacement_m,
                                        double dt_s, double crossover_hz);

/// Rotation table: specific force in the table-top frame F_E for a table turning about
/// `axis` (unit, F_E) by angle(t) from the start attitude where the specific force was `f0_e`,
/// for a sensor at `position_m` (F_E) from the axis. Rate and angular acceleration come from the
/// encoder angle by central differences.
Matrix3Columns table_specific_force(const Eigen::VectorXd& angle_rad, const Eigen::Vector3d& axis,
                                    const Eigen::Vector3d& f0_e, const Eigen::Vector3d& position_m, double dt_s,
                                    Matrix3Columns* rate_e = nullptr);

}  // namespace inertia::fusion
