#include "analyzer/procedure/identifiable_fit.hpp"

#include <algorithm>
#include <optional>

#include "analyzer/ident/term.hpp"

namespace inertia::procedure {

std::vector<Eigen::Index> identifiable_ranking(const StackedRegression& s, const ident::ErrOptions& base,
                                               const std::vector<Eigen::Index>& nuisance) {
  ident::ErrOptions options = base;
  options.forced.clear();
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (ident::is_sensitivity_label(s.labels[j])) options.forced.push_back(static_cast<Eigen::Index>(j));
  }
  for (std::size_t j = 0; j < s.labels.size(); ++j) {
    if (s.labels[j] == "1") options.forced.push_back(static_cast<Eigen::Index>(j));
  }
  options.forced.insert(options.forced.end(), nuisance.begin(), nuisance.end());
  options.reference = ident::ErrReference::AfterForced;
  return ident::err_rank(s.phi, s.y, options).order;
}

ident::UlsResult fit_identifiable(const StackedRegression& s, std::vector<Eigen::Index>& columns,
                                  const ident::UlsOptions& uls, std::vector<std::string>& dropped) {
  for (;;) {
    std::vector<Eigen::Index> sorted = columns;
    std::sort(sorted.begin(), sorted.end());
    try {
      return ident::uls_batch(s.phi, s.y, s.labels, s.rational, uls, sorted);
    } catch (const ident::IdentifiabilityError& e) {
      std::vector<std::string> ranked;
      for (const Eigen::Index j : columns) ranked.push_back(s.labels[static_cast<std::size_t>(j)]);
      const std::optional<std::size_t> leaves =
          ident::column_to_leave(e, ranked, [&](std::size_t j) { return ident::is_sensitivity_label(ranked[j]); });
      if (!leaves) throw;
      const auto victim = columns.begin() + static_cast<std::ptrdiff_t>(*leaves);
      dropped.push_back(s.labels[static_cast<std::size_t>(*victim)]);
      columns.erase(victim);
    }
  }
}

}  // namespace inertia::procedure
