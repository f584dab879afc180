#pragma once
// Compensation: an identified model read backwards, from a sensor's raw output to the physical
// input it sensed. The model says y (1 + sum_b c_b p_b) = sum_a c_a term_a (model_file.hpp); with
// every other input known (the other axes, temperature, the lagged outputs), each sample's sensed
// input x (a_i for an accelerometer, w_i for a gyro) is the root of
//
//   g(x) = sum_a c_a term_a(x) - y(k) (1 + sum_b c_b p_b(x)) = 0,
//
// found by Newton's method from the previous sample's estimate. The model's dynamics are kept:
// lagged outputs y[k-j] are the measured ones, lagged sensed inputs x[k-j] the estimates already
// made (before the first estimate, the current x: the sensor starts settled, as eq. 12's high pass
// does), and the squares of eq. 12 pass the model's high pass with x(k)^2 as the newest input.
// Noise terms e[k-j] are zero: they describe the output's noise, not the sensor.
//
// Each estimate carries two standard uncertainties, by the delta method at the root:
//   from the coefficients   u_c^2 = J C J',  J_j = -(dg/dc_j) / g'(x),  C the model's covariance;
//   from the output's noise u_n   = s |1 + sum_b c_b p_b(x)| / |g'(x)|,
// s the model's [noise] output_sd (every colour of the noise), else its white_sd.
// Errors of the known inputs, and of earlier estimates fed back through lagged terms, are not
// propagated: the command states so.
#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/model/model_file.hpp"

namespace inertia::compensate {
class JointInverse;
}

namespace inertia::compensate {

namespace detail {
inline double integer_power(double v, int power) {
  double r = 1.0;
  for (int i = 0; i < power; ++i) r *= v;
  return r;
}
inline double sign_of(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }
}  // namespace detail

/// f(v)^power of one factor at the value v of its variable (lag aside). Inline: the compensation
/// calls it per factor and sample.
inline double factor_value(const ident::Factor& f, double v) {
  switch (f.function) {
    case ident::FactorFunction::Plain: return detail::integer_power(v, f.power);
    case ident::FactorFunction::Abs: return detail::integer_power(std::abs(v), f.power);
    case ident::FactorFunction::Sign: return detail::integer_power(detail::sign_of(v), f.power);
  }
  return 0.0;
}
/// d/dv of factor_value (a sign's jump is not a slope: 0).
inline double factor_slope(const ident::Factor& f, double v) {
  switch (f.function) {
    case ident::FactorFunction::Plain: return f.power * detail::integer_power(v, f.power - 1);
    case ident::FactorFunction::Abs: return f.power * detail::integer_power(std::abs(v), f.power - 1) * detail::sign_of(v);
    case ident::FactorFunction::Sign: return 0.0;
  }
  return 0.0;
}

/// factor_value, with factor_slope in `slope`: one power for both.
inline double factor_value_and_slope(const ident::Factor& f, double v, double& slope) {
  switch (f.function) {
    case ident::FactorFunction::Plain: {
      const double below = detail::integer_power(v, f.power - 1);
      slope = f.power * below;
      return below * v;
    }
    case ident::FactorFunction::Abs: {
      const double a = std::abs(v), below = detail::integer_power(a, f.power - 1);
      slope = f.power * below * detail::sign_of(v);
      return below * a;
    }
    case ident::FactorFunction::Sign: slope = 0.0; return detail::integer_power(detail::sign_of(v), f.power);
  }
  slope = 0.0;
  return 0.0;
}

/// Newton's stopping rule on its largest steps (in x's units): the last `step`, the one before
/// (`previous`, 0 before the second step) and `bound`, the tolerance times (|x| + the scale).
/// Converged when the last step is within the bound, or when the next one, predicted by Newton's
/// quadratic convergence from the last two (step^3 / previous^2), is: once the last step is within
/// `regime` (the bound's square root times the scale's, so that its square is the bound's order)
/// and smaller than the one before. The second saves the evaluation that would only confirm it.
inline bool newton_converged(double step, double previous, double bound, double regime) {
  return step <= bound || (step <= regime && step < previous && step * step * step <= bound * previous * previous);
}

enum class SampleFlag : std::uint8_t {
  Ok = 0,
  OutsideRange = 1,   // an input (known or solved) lies outside the model's [range] plus the margin
  NotConverged = 2,   // Newton found no root within the iterations: the value is NaN
};
const char* to_string(SampleFlag flag);

struct CompensationOptions {
  int max_iterations = 30;
  /// A sample is outside the characterized range when an input lies beyond [lowest, highest]
  /// widened on each side by this fraction of the span.
  double range_margin = 0.01;
};

struct CompensatedSignal {
  Eigen::Index first_row = 0;       // sample index of element 0 (the model's largest lag)
  Eigen::VectorXd value;            // the sensed input, SI (m/s^2 or rad/s); NaN where not converged
  Eigen::VectorXd u_coefficients;   // standard uncertainty from the coefficients' covariance
  Eigen::VectorXd u_noise;          // standard uncertainty from the output's white noise
  std::vector<SampleFlag> flag;
  Eigen::Index outside_range = 0, not_converged = 0;
  int most_iterations = 0;          // the most Newton steps any sample took, over all its starts
};

class InverseModel {
 public:
  /// Throws InputError for a model without a term in the sensed input at the current sample (the
  /// output does not depend on it), or with the output y unlagged other than as y*p.
  explicit InverseModel(const model::ModelFile& model);

  /// a_i for an accelerometer, w_i for a gyroscope.
  [[nodiscard]] ident::Variable sensed() const { return sensed_; }
  /// The inputs besides y the terms read (never the sensed one, which is solved for).
  [[nodiscard]] const ident::VariableSet& known_inputs() const { return known_; }
  [[nodiscard]] Eigen::Index first_row() const { return first_row_; }
  /// False: the model file has no [covariance], and u_coefficients uses its [std] alone.
  [[nodiscard]] bool has_covariance() const { return has_covariance_; }

  /// Compensates one record. `signals` holds y and every known input (a sensed-input column in it
  /// is ignored). Throws InputError for a missing input, or std::invalid_argument for a model
  /// with a square high pass and no positive sample period.
  [[nodiscard]] CompensatedSignal compensate(const ident::SignalSet& signals, double sample_period_s,
                                             const CompensationOptions& options = {}) const;

  /// This model as a joint inverse of one equation, the sensed input its one unknown: what
  /// compensate solves, and what the C export writes.
  [[nodiscard]] JointInverse as_joint() const;

  /// A model term as the inversion reads it (noise terms are left out).
  struct CompiledTerm {
    std::vector<ident::Factor> factors;   // without the unlagged y of a denominator term
    double coefficient = 0.0;
    bool denominator = false;             // y*p: factors hold p
    bool square_filtered = false;         // a square through eq. 12's high pass
  };
  [[nodiscard]] const std::vector<CompiledTerm>& terms() const { return terms_; }
  /// The coefficients' covariance over terms() (the [std] squared without [covariance]).
  [[nodiscard]] const Eigen::MatrixXd& covariance() const { return covariance_; }
  /// The output's noise sd u_noise scales: output_sd, else white_sd, else 0.
  [[nodiscard]] double noise_sd() const { return noise_sd_; }
  [[nodiscard]] const std::optional<double>& square_corner() const { return square_corner_; }
  [[nodiscard]] const std::map<ident::Variable, model::ModelFile::Span>& range() const { return range_; }
  /// Newton's starting points after the previous estimate: the middle and the ends of the sensed
  /// input's characterized range (0 and +-1 without one).
  [[nodiscard]] std::array<double, 3> fallback_starts() const;
  /// Newton stops when a step is at most this times (|x| + the range's span, or 1), or when the
  /// next step its quadratic convergence predicts is (newton_converged).
  static constexpr double kStepTolerance = 1e-13;
  [[nodiscard]] double tolerance_scale() const;

 private:
  ident::Variable sensed_ = ident::Variable::Ai;
  ident::VariableSet known_;
  std::vector<CompiledTerm> terms_;          // noise terms left out
  std::vector<Eigen::Index> model_index_;    // terms_[i] is the model's term model_index_[i]
  Eigen::MatrixXd covariance_;               // over terms_
  bool has_covariance_ = false;
  Eigen::Index first_row_ = 0;
  double noise_sd_ = 0.0;   // the output's noise: output_sd, else white_sd
  std::optional<double> square_corner_;
  std::map<ident::Variable, model::ModelFile::Span> range_;
};

}  // namespace inertia::compensate
