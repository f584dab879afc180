#include "analyzer/model/coefficient_uncertainty.hpp"

#include <algorithm>
#include <cmath>

namespace inertia::model {

Eigen::VectorXd coefficient_vector(const ModelFile& model) {
  Eigen::VectorXd theta(static_cast<Eigen::Index>(model.terms.size()));
  for (std::size_t j = 0; j < model.terms.size(); ++j) theta(static_cast<Eigen::Index>(j)) = model.terms[j].coefficient;
  return theta;
}

Eigen::MatrixXd coefficient_covariance(const ModelFile& model) {
  const auto n = static_cast<Eigen::Index>(model.terms.size());
  if (model.covariance.rows() == n && n > 0) return model.covariance;
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index j = 0; j < n; ++j) c(j, j) = std::pow(model.terms[static_cast<std::size_t>(j)].std.value_or(0.0), 2);
  return c;
}

Eigen::MatrixXd delta_method_covariance(const CoefficientFunction& f, const Eigen::VectorXd& x, const Eigen::MatrixXd& covariance) {
  const Eigen::VectorXd at = f(x);
  Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(at.size(), x.size());
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    const double sd = std::sqrt(std::max(covariance(j, j), 0.0));
    if (sd == 0.0) continue;
    const double h = 1e-3 * sd;
    Eigen::VectorXd up = x, down = x;
    up(j) += h;
    down(j) -= h;
    jacobian.col(j) = (f(up) - f(down)) / (2.0 * h);
  }
  return jacobian * covariance * jacobian.transpose();
}

Eigen::MatrixXd propagated_covariance(const ModelFile& model, const CoefficientFunction& f) {
  return delta_method_covariance(f, coefficient_vector(model), coefficient_covariance(model));
}

}  // namespace inertia::model
