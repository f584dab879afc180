#include "analyzer/procedure/batch_regression.hpp"

#include <algorithm>

#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/mountings.hpp"
#include "analyzer/procedure/whitened_problem.hpp"

namespace inertia::procedure {

void set_case_frames(const dataset::Dataset& data, const std::vector<MountingResult>& mountings,
                     const std::vector<Eigen::Vector3d>& turns, std::vector<CaseOutcome>& cases) {
  for (std::size_t m = 0; m < mountings.size(); ++m) {
    for (std::size_t index : mountings[m].cases) {
      cases[index].case_index = index;
      cases[index].m_es = turned(mountings[m].m_cs, turns[m]) * data.cases[index].m_ec;   // M_E^S = M_C^S M_E^C
    }
  }
}

std::vector<StackInput> batch_inputs(const dataset::Dataset& data, const PipelineOptions& options,
                                     const std::vector<CaseOutcome>& cases) {
  std::vector<StackInput> inputs;
  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    inputs.push_back({i, &data.cases[i], cases[i].m_es, case_weight(options, data.cases[i]), {}});
  }
  return inputs;
}

Eigen::MatrixXd BatchRegression::placement_columns(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                                                   const std::vector<MountingResult>& mountings,
                                                   const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner,
                                                   std::span<const StatedPlacement> placements) const {
  std::vector<CaseOutcome> cases(data_.cases.size());
  set_case_frames(data_, mountings, turns, cases);
  return procedure::placement_columns(terms, theta, batch_inputs(data_, options_, cases), placements, data_, label_, first_row_,
                                      corner, whitener_);
}

StackedRegression BatchRegression::unwhitened(std::span<const ident::Term> terms, const std::vector<MountingResult>& mountings,
                                              const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner,
                                              std::span<const std::size_t> only) const {
  std::vector<CaseOutcome> cases(data_.cases.size());
  set_case_frames(data_, mountings, turns, cases);
  std::vector<StackInput> inputs = batch_inputs(data_, options_, cases);
  if (!only.empty())
    std::erase_if(inputs, [&](const StackInput& in) { return std::find(only.begin(), only.end(), in.case_index) == only.end(); });
  StackedRegression s = stack_regressions(terms, inputs, data_.t_ref, label_, first_row_);
  apply_square_model(s, data_, corner);
  return s;
}

StackedRegression BatchRegression::operator()(std::span<const ident::Term> terms, const std::vector<MountingResult>& mountings,
                                              const std::vector<Eigen::Vector3d>& turns, std::optional<double> corner) const {
  StackedRegression s = unwhitened(terms, mountings, turns, corner);
  whitener_.apply(s);
  return s;
}

}  // namespace inertia::procedure
