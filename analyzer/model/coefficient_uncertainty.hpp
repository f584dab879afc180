#pragma once
// What a model file's coefficients know about their own uncertainty, and how it carries to any
// quantity computed from them (a sheet's parameter, a unit's scale factor): the delta method,
// C_f = J C J', with J by central differences.
#include <Eigen/Dense>

#include <functional>

#include "analyzer/model/model_file.hpp"

namespace inertia::model {

/// The coefficients of [terms], in the file's order.
Eigen::VectorXd coefficient_vector(const ModelFile& model);

/// Their covariance: [covariance] where the file has it, else each term's sd alone (no correlations).
Eigen::MatrixXd coefficient_covariance(const ModelFile& model);

using CoefficientFunction = std::function<Eigen::VectorXd(const Eigen::VectorXd& theta)>;

/// The covariance of f(x) for an x of covariance C by the delta method: J C J', J by central
/// differences with steps of 1e-3 of each element's sd (an element without sd does not vary).
Eigen::MatrixXd delta_method_covariance(const CoefficientFunction& f, const Eigen::VectorXd& x, const Eigen::MatrixXd& covariance);

/// The covariance of f(theta) over the model's coefficients (delta_method_covariance).
Eigen::MatrixXd propagated_covariance(const ModelFile& model, const CoefficientFunction& f);

}  // namespace inertia::model
