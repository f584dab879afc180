#include "analyzer/procedure/placement.hpp"

#include <algorithm>
#include <string>

#include "analyzer/procedure/whitened_problem.hpp"

namespace inertia::procedure {

Eigen::Matrix3d placement_covariance(const Eigen::Vector3d& theta, std::span<const CasePlacement> cases, bool with_bias) {
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  const Eigen::Index n = with_bias ? 4 : 3;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(n, n);
  bool any = false;
  for (const CasePlacement& c : cases) {
    gram += c.gram.topLeftCorner(n, n);
    any = any || c.sd_rad > 0.0;
  }
  if (!any) return covariance;
  // An axis the mounting does not excite leaves G singular: the pseudo-inverse answers for the rest
  // (the held angle gets the mounting tolerance instead).
  const Eigen::MatrixXd g_inverse = gram.completeOrthogonalDecomposition().pseudoInverse();
  Eigen::Matrix3d cross;
  cross << 0.0, -theta(2), theta(1), theta(2), 0.0, -theta(0), -theta(1), theta(0), 0.0;
  for (const CasePlacement& c : cases) {
    if (!(c.sd_rad > 0.0)) continue;
    const Eigen::MatrixXd h = c.gram.topLeftCorner(n, 3);   // sum of r a'
    const Eigen::Matrix3d j = (g_inverse * h * cross).topRows(3);
    covariance += c.sd_rad * c.sd_rad * j * j.transpose();
  }
  return covariance;
}

std::vector<StatedPlacement> stated_placements(const dataset::Dataset& data) {
  std::vector<StatedPlacement> out;
  std::vector<const std::string*> plan_cases;   // one per entry of out
  for (std::size_t i = 0; i < data.cases.size(); ++i) {
    const dataset::CaseData& c = data.cases[i];
    if (!(c.placement_sd_rad > 0.0)) continue;
    const auto at = std::find_if(plan_cases.begin(), plan_cases.end(), [&](const std::string* p) { return *p == c.plan_case(); });
    if (at == plan_cases.end()) {
      plan_cases.push_back(&c.plan_case());
      out.push_back({{i}, c.placement_sd_rad});
    } else {
      out[static_cast<std::size_t>(at - plan_cases.begin())].pieces.push_back(i);
    }
  }
  return out;
}

Eigen::MatrixXd placement_columns(std::span<const ident::Term> terms, const Eigen::VectorXd& theta,
                                  std::span<const StackInput> inputs, std::span<const StatedPlacement> placements,
                                  const dataset::Dataset& data, std::string_view label, Eigen::Index first_row,
                                  std::optional<double> square_corner, const ArWhitener& whitener) {
  const std::vector<CaseRows> layout = stack_layout(terms, inputs, first_row);
  const Eigen::Index rows = layout.empty() ? 0 : layout.back().begin + layout.back().rows;
  // Each placement's pieces among the inputs, with their rows.
  std::vector<std::vector<std::pair<const StackInput*, const CaseRows*>>> present;
  std::vector<double> sd;
  for (const StatedPlacement& placement : placements) {
    std::vector<std::pair<const StackInput*, const CaseRows*>> pieces;
    for (const std::size_t piece : placement.pieces) {
      const auto input = std::find_if(inputs.begin(), inputs.end(), [&](const StackInput& in) { return in.case_index == piece; });
      const auto at = std::find_if(layout.begin(), layout.end(), [&](const CaseRows& r) { return r.case_index == piece; });
      if (input != inputs.end() && at != layout.end()) pieces.emplace_back(&*input, &*at);
    }
    if (pieces.empty()) continue;
    present.push_back(std::move(pieces));
    sd.push_back(placement.sd_rad);
  }
  Eigen::MatrixXd columns = Eigen::MatrixXd::Zero(rows, 3 * static_cast<Eigen::Index>(present.size()));
  for (std::size_t k = 0; k < present.size(); ++k) {
    for (const auto& [input, at] : present[k]) {
      const Eigen::Matrix3d& m_ec = input->data->m_ec;
      for (int axis = 0; axis < 3; ++axis) {
        // The case frame turned about its own axis: M_E^S = M_C^S R M_E^C.
        const auto prediction = [&](double angle) {
          StackInput turned = *input;
          turned.m_es = input->m_es * m_ec.transpose() * Eigen::AngleAxisd(angle, Eigen::Vector3d::Unit(axis)).toRotationMatrix() * m_ec;
          StackedRegression s = stack_regressions(terms, std::span<const StackInput>(&turned, 1), data.t_ref, label, first_row);
          apply_square_model(s, data, square_corner);
          return Eigen::VectorXd(s.phi * theta);
        };
        columns.block(at->begin, 3 * static_cast<Eigen::Index>(k) + axis, at->rows, 1) = 0.5 * (prediction(sd[k]) - prediction(-sd[k]));
      }
    }
  }
  whitener.apply_to_columns(columns, layout);
  return columns;
}

}  // namespace inertia::procedure
