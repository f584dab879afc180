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
#include <array>
#include <deque>
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

/// The per-sample fit of fuse_monitors with its gain computed once for a layout (the live fusion).
class MonitorFusion {
 public:
  /// Throws std::invalid_argument as fuse_monitors does for a layout that does not span 3D.
  explicit MonitorFusion(const MonitorLayout& layout);
  /// One sample: the m monitor readings -> specific force in F_E.
  [[nodiscard]] Eigen::Vector3d fuse(const Eigen::Ref<const Eigen::VectorXd>& readings) const {
    return gain_ * (readings - bias_);
  }
  [[nodiscard]] Eigen::Index monitors() const { return gain_.cols(); }

 private:
  friend Matrix3Columns fuse_monitors(const Eigen::MatrixXd&, const MonitorLayout&, double*);
  Eigen::MatrixXd h_;      // m x 3, unit axes
  Eigen::VectorXd w_;      // weights 1 / sd^2
  Eigen::VectorXd bias_;
  Eigen::MatrixXd gain_;   // 3 x m
};

/// Complementary fusion along one axis: low frequencies from the encoder displacement
/// (differentiated twice), high frequencies from the accelerometer estimate, with second-order
/// (critically damped) complementary filters at `crossover_hz`, so the sum of both paths is exact
/// for a noise-free input. `accel_along_axis` and `displacement_m` are sampled at 1/dt_s.
Eigen::VectorXd complementary_vibration(const Eigen::VectorXd& accel_along_axis, const Eigen::VectorXd& displacement_m,
                                        double dt_s, double crossover_hz);

/// The same, one sample at a time (the live fusion): step() returns the fused value of the sample it
/// is given, with the filters started settled on the first sample as the batch form starts them,
/// so a sequence stepped through gives exactly what complementary_vibration gives on it.
class ComplementaryFilter {
 public:
  /// Throws std::invalid_argument when the crossover is not between 0 and the Nyquist frequency.
  ComplementaryFilter(double dt_s, double crossover_hz);
  /// `encoder_accel` is the encoder displacement's second difference at the same sample.
  double step(double accel_along_axis, double encoder_accel);
  /// One sample whose accelerometer reading is lost (the encoder's is there): both paths advance
  /// with the reading predicted as the encoder's acceleration plus the paths' slow difference
  /// (gravity along the axis and the accelerometers' slow error), so the filter goes on in step
  /// with the signal. The sample itself has no output; a consistent input is carried exactly.
  void coast(double encoder_accel);

 private:
  double low_encoder_ = 0.0, low_accel_ = 0.0;   // the paths' last outputs
  struct Section {
    double b0, b1, b2, a1, a2;
    double s1 = 0.0, s2 = 0.0;
    double step(double x);
    void settle(double u);
  };
  std::array<Section, 2> encoder_path_{}, accel_path_{};
  bool started_ = false;
};

/// First and second central differences of a sampled signal, two samples behind it: a sample's
/// differences become final once two more samples are pushed (or the signal ends). The first
/// difference is the three-point one, exact for a constant rate; the second is the five-point
/// stencil (-1, 16, -30, 16, -1) / 12 dt^2, whose gain on a sine is 1 - (w dt)^4 / 90 where the
/// three-point one's is 1 - (w dt)^2 / 12: 0.004 % against 0.5 % at 25 samples a cycle, the
/// shaker's low path at a slow output rate. The samples next to the ends take the three-point
/// second difference, and the end samples are extrapolated linearly from their neighbours
/// (d(0) = 2 d(1) - d(2)), so a smooth trace has no step at its ends for a filter to ring on; with
/// fewer than 3 samples both are zero. A sequence pushed through gives exactly the batch
/// differences of the whole sequence.
class CentralDifferences {
 public:
  struct Value {
    double first = 0.0, second = 0.0;
  };
  explicit CentralDifferences(double dt_s) : dt_(dt_s) {}
  void push(double x);
  /// The signal ended: the remaining samples' differences become final.
  void finish();
  /// Final values not yet taken, oldest first.
  [[nodiscard]] bool ready() const { return !out_.empty(); }
  Value pop();
  [[nodiscard]] std::int64_t pushed() const { return count_; }

 private:
  static Value beyond(const Value& near, const Value& far);
  /// The three-point differences at the sample `back` samples before the newest (1 or 2).
  [[nodiscard]] Value three_point(int back) const;
  double dt_;
  std::int64_t count_ = 0;
  std::array<double, 5> last_{};   // x(count-5 .. count-1)
  Value at1_{};                    // the value at sample 1 (sample 0 is extrapolated from it)
  Value newest_{};                 // the newest value made final (the end's extrapolation)
  std::deque<Value> out_;
};

/// Rotation table at one sample: the specific force for the table turned by `angle_rad` about
/// `axis_unit` (unit, F_E) from the start attitude where it was `f0_e`, turning at `rate_rad_s`
/// with angular acceleration `accel_rad_s2`, at `position_m` (F_E) from the axis.
Eigen::Vector3d table_specific_force_at(double angle_rad, double rate_rad_s, double accel_rad_s2,
                                        const Eigen::Vector3d& axis_unit, const Eigen::Vector3d& f0_e,
                                        const Eigen::Vector3d& position_m);

/// Rotation table: specific force in the table-top frame F_E for a table turning about
/// `axis` (unit, F_E) by angle(t) from the start attitude where the specific force was `f0_e`,
/// for a sensor at `position_m` (F_E) from the axis. Rate and angular acceleration come from the
/// encoder angle by central differences.
Matrix3Columns table_specific_force(const Eigen::VectorXd& angle_rad, const Eigen::Vector3d& axis,
                                    const Eigen::Vector3d& f0_e, const Eigen::Vector3d& position_m, double dt_s,
                                    Matrix3Columns* rate_e = nullptr);

}  // namespace inertia::fusion
