#pragma once
// What a stacked problem's data can determine: the ERR ranking without the columns the data
// cannot separate from those before it, and a ULS fit that lets a near-dependent column go
// instead of failing. Every stage of the procedure fits through these.
#include <Eigen/Dense>
#include <string>
#include <vector>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/stacked_regression.hpp"

namespace inertia::procedure {

/// ERR order of the columns of a stacked problem (sensitivities forced first, the bias after
/// them, then `nuisance`), without the columns the data cannot separate from the ones before them.
std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, const ident::ErrOptions& base,
                                               const std::vector<Eigen::Index>& nuisance = {});

/// ULS on `columns`; when the fit names a near-dependence, the named column ranked last (never a
/// sensitivity) leaves `columns`, is recorded in `dropped`, and the fit is repeated.
ident::UlsResult fit_identifiable(const StackedRegression& s, std::vector<Eigen::Index>& columns,
                                  const ident::UlsOptions& uls, std::vector<std::string>& dropped);

}  // namespace inertia::procedure
