#include "analyzer/unit/triad_frame.hpp"

#include <fmt/format.h>

#include <cmath>

#include "analyzer/compensate/static_response.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/model/coefficient_uncertainty.hpp"
#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"

namespace inertia::unit {

namespace {

using ident::Variable;

Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v(2), v(1), v(2), 0.0, -v(0), -v(1), v(0), 0.0;
  return m;
}

TriadAxis triad_axis(const model::ModelFile& m) {
  const bool gyro = m.sensor == dataset::SensorKind::Gyroscope;
  const std::array<Variable, 3> inputs = gyro ? std::array{Variable::Wi, Variable::Wp, Variable::Wo}
                                              : std::array{Variable::Ai, Variable::Ap, Variable::Ao};
  // Case coordinates to unit coordinates: a_C = T a_U, so a vector of dy/da_C turns by T'.
  const Eigen::Matrix3d to_unit = config::unit_axis_frame(m.unit_axis).transpose();
  const Eigen::Matrix3d m_cs = m.m_cs;
  const auto gradient = [&](const std::array<Variable, 3>& of, const Eigen::VectorXd& theta) {
    Eigen::Vector3d g;
    for (int k = 0; k < 3; ++k) g(k) = compensate::static_sensitivity(m, of[static_cast<std::size_t>(k)], theta);
    return g;
  };
  const std::array<Variable, 3> specific_force{Variable::Ai, Variable::Ap, Variable::Ao};
  // s_k and the g-sensitivity (gyroscopes; zero for an accelerometer) in unit coordinates.
  const auto unit_vectors = [&](const Eigen::VectorXd& theta) -> Eigen::VectorXd {
    const Eigen::Matrix3d turn = to_unit * m_cs.transpose();
    const Eigen::Vector3d s = turn * gradient(inputs, theta);
    const Eigen::Vector3d g = gyro ? Eigen::Vector3d(turn * gradient(specific_force, theta)) : Eigen::Vector3d::Zero();
    Eigen::VectorXd v(6);
    v << s, g;
    return v;
  };
  TriadAxis a;
  a.sensor = m.name;
  const Eigen::VectorXd theta = model::coefficient_vector(m);
  const Eigen::VectorXd vectors = unit_vectors(theta);
  a.sensitivity = vectors.head(3);
  a.g_sensitivity = vectors.tail(3);
  a.joint_covariance = model::propagated_covariance(m, unit_vectors);
  if (m.misalignment) {
    // M_C^S turned by small angles d about the case axes: M' = (I - [d]x) M, so a vector v_C = M' v_S
    // moves by -M' [v_S]x d, s and g alike. Only p and o: a turn about i does not move the input axis.
    const Eigen::Vector3d variance(0.0, std::pow(m.misalignment->sd_p, 2), std::pow(m.misalignment->sd_o, 2));
    Eigen::Matrix<double, 6, 3> jacobian;
    jacobian.topRows(3) = -to_unit * m_cs.transpose() * cross_matrix(gradient(inputs, theta));
    jacobian.bottomRows(3) = gyro ? Eigen::Matrix3d(-to_unit * m_cs.transpose() * cross_matrix(gradient(specific_force, theta)))
                                  : Eigen::Matrix3d::Zero();
    const Eigen::Matrix<double, 6, 6> angles = jacobian * variance.asDiagonal() * jacobian.transpose();
    a.angles_covariance = angles.topLeftCorner(3, 3);
    a.joint_covariance += angles;
    a.angles_dof = m.misalignment->dof;
    a.angles_estimated = m.misalignment->sd_p > 0.0 && m.misalignment->sd_o > 0.0;
  }
  a.covariance = a.joint_covariance.topLeftCorner(3, 3);
  const auto bias = [&](const Eigen::VectorXd& t) -> Eigen::VectorXd {
    return Eigen::VectorXd::Constant(1, compensate::static_output(m, compensate::InputValues{}, {}, t));
  };
  a.bias = bias(theta)(0);
  a.bias_sd = std::sqrt(std::max(0.0, model::propagated_covariance(m, bias)(0, 0)));
  return a;
}

}  // namespace

TriadFrame triad_frame(const std::vector<model::ModelFile>& members) {
  if (members.size() != 3) throw InputError(fmt::format("a triad is three models, one along each unit axis: {} given", members.size()));
  TriadFrame f;
  const model::ModelFile& first = members.front();
  f.unit = first.unit;
  f.serial = first.serial;
  f.kind = first.sensor;
  f.output_unit = first.output_unit;
  std::array<bool, 3> seen{};
  for (const model::ModelFile& m : members) {
    const std::string name = m.name.empty() ? std::string("(unnamed)") : m.name;
    if (m.unit.empty() || m.unit_axis < 0)
      throw InputError(fmt::format("model of '{}' states no unit and unit_axis: it was not characterized as a unit's member "
                                   "(the bench file's [[unit]])",
                                   name));
    if (m.unit != f.unit) throw InputError(fmt::format("model of '{}' is of unit '{}', not '{}'", name, m.unit, f.unit));
    if (m.sensor != f.kind) throw InputError(fmt::format("model of '{}' is of another kind than the others", name));
    if (m.serial != f.serial) throw InputError(fmt::format("model of '{}' states serial '{}', the others '{}'", name, m.serial, f.serial));
    if (seen[static_cast<std::size_t>(m.unit_axis)])
      throw InputError(fmt::format("two models along unit axis {}", static_cast<char>('x' + m.unit_axis)));
    seen[static_cast<std::size_t>(m.unit_axis)] = true;
    f.axes[static_cast<std::size_t>(m.unit_axis)] = triad_axis(m);
  }
  for (int k = 0; k < 3; ++k) {
    const TriadAxis& a = f.axes[static_cast<std::size_t>(k)];
    f.sensitivity.row(k) = a.sensitivity.transpose();
    const double norm = a.sensitivity.norm();
    const Eigen::Vector3d n = a.sensitivity / norm;
    f.scale(k) = norm;
    f.scale_sd(k) = std::sqrt(std::max(0.0, n.dot(a.covariance * n)));   // d|s| = n . ds
    f.misalignment.row(k) = n.transpose();
    f.bias(k) = a.bias;
    f.g_sensitivity.row(k) = a.g_sensitivity.transpose();
    f.bias_sd(k) = a.bias_sd;
  }
  for (int pair = 0; pair < 3; ++pair) {
    const TriadAxis& a = f.axes[static_cast<std::size_t>(pair)];
    const TriadAxis& b = f.axes[static_cast<std::size_t>((pair + 1) % 3)];
    const double na = a.sensitivity.norm(), nb = b.sensitivity.norm();
    const double c = a.sensitivity.dot(b.sensitivity) / (na * nb);
    // d c / d s_a = s_b / (|s_a| |s_b|) - c s_a / |s_a|^2, and the same with a and b swapped.
    const Eigen::Vector3d ga = b.sensitivity / (na * nb) - c * a.sensitivity / (na * na);
    const Eigen::Vector3d gb = a.sensitivity / (na * nb) - c * b.sensitivity / (nb * nb);
    const double variance = ga.dot(a.covariance * ga) + gb.dot(b.covariance * gb);
    const auto p = static_cast<std::size_t>(pair);
    f.non_orthogonality[p] = std::asin(c);
    f.non_orthogonality_sd[p] = std::sqrt(std::max(0.0, variance) / (1.0 - c * c));
    // Welch-Satterthwaite: V^2 / sum v_i^2 / dof_i over the parts with finite dof.
    const double va = ga.dot(a.angles_covariance * ga), vb = gb.dot(b.angles_covariance * gb);
    double denominator = 0.0;
    if (std::isfinite(a.angles_dof)) denominator += va * va / a.angles_dof;
    if (std::isfinite(b.angles_dof)) denominator += vb * vb / b.angles_dof;
    f.non_orthogonality_dof[p] = denominator > 0.0 ? variance * variance / denominator : std::numeric_limits<double>::infinity();
    f.non_orthogonality_half_width[p] = ident::student_t_interval_factor(0.95, f.non_orthogonality_dof[p]) * f.non_orthogonality_sd[p];
  }
  return f;
}

}  // namespace inertia::unit
