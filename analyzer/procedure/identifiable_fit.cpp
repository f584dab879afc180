#include "analyzer/procedure/identifiable_fit.hpp"

#include "analyzer/ident/normal_equations.hpp"

namespace inertia::procedure {

std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, dataset::SensorKind sensor, const ident::ErrOptions& base,
                                               const std::vector<Eigen::Index>& nuisance) {
  const ident::NormalEquations equations = ident::NormalEquations::from_rows(s.phi, s.y, s.labels);
  return ident::rank_identifiable(equations, sensor, base, nuisance).order;
}

ident::UlsResult fit_identifiable(const StackedRegression& s, dataset::SensorKind sensor, std::vector<Eigen::Index>& columns,
                                  const ident::UlsOptions& uls, std::vector<std::string>& dropped) {
  std::vector<Eigen::Index> left;
  ident::UlsResult fit = ident::fit_identifiable(columns, s.labels, sensor, left, [&](std::span<const Eigen::Index> ascending) {
    return ident::uls_batch(s.phi, s.y, s.labels, s.rational, uls, ascending);
  });
  for (const Eigen::Index j : left) dropped.push_back(s.labels[static_cast<std::size_t>(j)]);
  return fit;
}

}  // namespace inertia::procedure
