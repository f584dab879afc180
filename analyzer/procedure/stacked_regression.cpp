#include "analyzer/procedure/stacked_regression.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace inertia::procedure {

std::vector<Eigen::Index> stretch_starts(std::span<const CaseRows> cases) {
  std::vector<Eigen::Index> out;
  for (std::size_t k = 1; k < cases.size(); ++k) out.push_back(cases[k].begin);
  return out;
}

std::vector<CaseRows> stack_layout(std::span<const ident::Term> terms, std::span<const StackInput> inputs,
                                   Eigen::Index min_first_row) {
  const Eigen::Index first_row = std::max(ident::first_usable_row(terms), min_first_row);
  std::vector<CaseRows> out;
  Eigen::Index row = 0;
  for (const StackInput& in : inputs) {
    if (in.data == nullptr) throw std::invalid_argument("stack_regressions: a case without data");
    const Eigen::Index rows = std::max<Eigen::Index>(0, in.data->size() - first_row);
    if (rows == 0) continue;
    out.push_back(CaseRows{in.case_index, row, rows, first_row});
    row += rows;
  }
  return out;
}

StackedRegression stack_regressions(std::span<const ident::Term> terms, std::span<const StackInput> inputs,
                                    double t_ref, std::string_view dataset_label, Eigen::Index min_first_row) {
  StackedRegression out;
  out.labels = ident::to_strings(std::vector<ident::Term>(terms.begin(), terms.end()));
  out.cases = stack_layout(terms, inputs, min_first_row);
  for (const StackInput& in : inputs) {
    if (!(in.weight > 0.0) || !std::isfinite(in.weight)) {
      throw std::invalid_argument("stack_regressions: case '" + in.data->name + "' has a non-positive weight");
    }
  }
  const Eigen::Index total = out.cases.empty() ? 0 : out.cases.back().begin + out.cases.back().rows;
  const auto columns = static_cast<Eigen::Index>(terms.size());
  out.phi.resize(total, columns);
  out.y.resize(total);
  std::vector<ident::Term> factor_terms;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    if (!terms[j].is_output_multiplied()) continue;
    out.rational.columns.push_back(static_cast<Eigen::Index>(j));
    factor_terms.push_back(terms[j].denominator_factor());
  }
  out.rational.factors.resize(factor_terms.empty() ? 0 : total, static_cast<Eigen::Index>(factor_terms.size()));
  const ident::VariableSet needed = ident::variables_of(terms) | ident::variables_of(factor_terms);
  const Eigen::Index first_row = std::max(ident::first_usable_row(terms), min_first_row);
  Eigen::Index row = 0;
  for (const StackInput& in : inputs) {
    const ident::SignalSet signals = ident::signals_from_case(*in.data, in.m_es, t_ref, dataset_label, needed, in.reading);
    const Eigen::Index rows = std::max<Eigen::Index>(0, in.data->size() - first_row);   // as stack_layout
    if (rows == 0) continue;
    // Fill straight into the stack: no per-case copy of a matrix that can be hundreds of MB.
    ident::fill_regressors(terms, signals, first_row, out.phi.middleRows(row, rows));
    out.y.segment(row, rows) = in.data->y.tail(rows).array() - in.reading.y_offset;
    if (!factor_terms.empty()) ident::fill_regressors(factor_terms, signals, first_row, out.rational.factors.middleRows(row, rows));
    if (in.weight != 1.0) {
      const double w = std::sqrt(in.weight);
      out.phi.middleRows(row, rows) *= w;
      out.y.segment(row, rows) *= w;
    }
    row += rows;
  }
  return out;
}

}  // namespace inertia::procedure
