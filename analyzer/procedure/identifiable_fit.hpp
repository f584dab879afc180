#pragma once
// What a stacked problem's data can determine, by the rules of ident/normal_equations.hpp on its
// rows: the ranking without the columns the data cannot separate from those before it, and a ULS
// fit that lets a near-dependent column go instead of failing. Every stage of the procedure fits
// through these.
#include <Eigen/Dense>
#include <string>
#include <vector>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// ERR order of the columns of a stacked problem (`sensor`'s sensitivities forced first, the bias
/// after them, then `nuisance`), without the columns the data cannot separate from the ones before
/// them (ident::rank_identifiable).
std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, dataset::SensorKind sensor, const ident::ErrOptions& base,
                                               const std::vector<Eigen::Index>& nuisance = {});

/// ULS on `columns` (ranked order); when the fit names a near-dependence, the named column ranked
/// last (never one of `sensor`'s sensitivities) leaves `columns`, is recorded in `dropped`, and
/// the fit is repeated (ident::fit_identifiable).
ident::UlsResult fit_identifiable(const StackedRegression& s, dataset::SensorKind sensor, std::vector<Eigen::Index>& columns,
                                  const ident::UlsOptions& uls, std::vector<std::string>& dropped);

}  // namespace inertia::procedure
