#include "analyzer/compensate/inverse_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "analyzer/compensate/joint_inverse.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/input_error.hpp"

namespace inertia::compensate {

using Eigen::Index;
using ident::FactorFunction;
using ident::Variable;

const char* to_string(SampleFlag flag) {
  switch (flag) {
    case SampleFlag::Ok: return "ok";
    case SampleFlag::OutsideRange: return "outside_range";
    case SampleFlag::NotConverged: return "not_converged";
  }
  return "?";
}

InverseModel::InverseModel(const model::ModelFile& model) {
  sensed_ = model.sensor == dataset::SensorKind::Accelerometer ? Variable::Ai : Variable::Wi;
  noise_sd_ = model.output_sd.value_or(model.white_sd.value_or(0.0));
  square_corner_ = model.square_highpass_rad_s;
  range_ = model.range;
  bool reads_sensed_now = false;
  for (std::size_t j = 0; j < model.terms.size(); ++j) {
    const ident::Term& term = model.terms[j].term;
    if (term.is_noise_term()) continue;
    CompiledTerm t;
    t.coefficient = model.terms[j].coefficient;
    for (const ident::Factor& f : term.factors()) {
      if (f.variable == Variable::Y && f.lag == 0) {
        if (f.power != 1 || f.function != FactorFunction::Plain) {
          throw InputError(fmt::format("term '{}' cannot be compensated: the output enters it unlagged other than as y*p",
                                       term.to_string()));
        }
        t.denominator = true;
        continue;
      }
      if (f.variable == sensed_ && f.lag == 0) reads_sensed_now = true;
      if (f.variable != Variable::Y && f.variable != sensed_) known_.set(static_cast<std::size_t>(f.variable));
      t.factors.push_back(f);
    }
    t.square_filtered = square_corner_.has_value() && procedure::is_square_term(term);
    first_row_ = std::max<Index>(first_row_, term.max_lag());
    terms_.push_back(std::move(t));
    model_index_.push_back(static_cast<Index>(j));
  }
  if (!reads_sensed_now) {
    throw InputError(fmt::format("the model has no term in {} at the current sample: its output does not tell the input",
                                 ident::variable_name(sensed_)));
  }
  const auto n = static_cast<Index>(terms_.size());
  covariance_ = Eigen::MatrixXd::Zero(n, n);
  has_covariance_ = model.covariance.rows() == static_cast<Index>(model.terms.size()) && model.covariance.rows() > 0;
  for (Index a = 0; a < n; ++a) {
    const Index ma = model_index_[static_cast<std::size_t>(a)];
    if (!has_covariance_) {
      covariance_(a, a) = std::pow(model.terms[static_cast<std::size_t>(ma)].std.value_or(0.0), 2);
      continue;
    }
    for (Index b = 0; b < n; ++b) covariance_(a, b) = model.covariance(ma, model_index_[static_cast<std::size_t>(b)]);
  }
}

std::array<double, 3> InverseModel::fallback_starts() const {
  const double lo = range_.count(sensed_) ? range_.at(sensed_).lowest : -1.0;
  const double hi = range_.count(sensed_) ? range_.at(sensed_).highest : 1.0;
  return {0.5 * (lo + hi), hi, lo};
}

double InverseModel::tolerance_scale() const {
  const double span = range_.count(sensed_) ? range_.at(sensed_).highest - range_.at(sensed_).lowest : 0.0;
  return span > 0.0 ? span : 1.0;
}

JointInverse InverseModel::as_joint() const {
  std::vector<Eigen::VectorXd> starts;
  for (const double s : fallback_starts()) starts.push_back(Eigen::VectorXd::Constant(1, s));
  return JointInverse({JointEquation{this, {{sensed_, Eigen::RowVectorXd::Ones(1)}}}}, std::move(starts));
}

CompensatedSignal InverseModel::compensate(const ident::SignalSet& signals, double sample_period_s,
                                           const CompensationOptions& options) const {
  JointCompensation solved = as_joint().compensate({&signals}, sample_period_s, options);
  CompensatedSignal out;
  out.first_row = solved.first_row;
  out.value = solved.value.col(0);
  out.u_coefficients = solved.u_coefficients.col(0);
  out.u_noise = solved.u_noise.col(0);
  out.flag = std::move(solved.flag);
  out.outside_range = solved.outside_range;
  out.not_converged = solved.not_converged;
  out.most_iterations = solved.most_iterations;
  return out;
}

}  // namespace inertia::compensate
