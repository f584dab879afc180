#include "analyzer/online/live_basis.hpp"

#include <algorithm>


namespace inertia::online {

using Eigen::Index;

Index LiveBasis::base_index(const ident::Term& monomial) {
  const auto it = std::find(base_.begin(), base_.end(), monomial);
  if (it != base_.end()) return static_cast<Index>(it - base_.begin());
  base_.push_back(monomial);
  return static_cast<Index>(base_.size()) - 1;
}

LiveBasis::LiveBasis(const std::vector<ident::Term>& terms, const std::vector<ident::Term>& filtered) : terms_(terms) {
  base_index(ident::Term());   // the constant: sums of the columns for the ULS correction
  for (const ident::Term& t : terms_) {
    TermMap map;
    max_lag_ = std::max(max_lag_, t.max_lag());
    if (!ident::expandable(t)) {
      map.base.push_back(base_index(t));
      has_frozen_ = true;
    } else {
      map.expansion.emplace(t);
      map.square = std::find(filtered.begin(), filtered.end(), t) != filtered.end();
      for (const ident::Term& m : map.expansion->monomials()) {
        const Index b = base_index(m);
        map.base.push_back(b);
        if (map.square) {
          auto it = std::find(filtered_sources_.begin(), filtered_sources_.end(), b);
          if (it == filtered_sources_.end()) {
            filtered_sources_.push_back(b);
            it = std::prev(filtered_sources_.end());
          }
          map.filtered.push_back(static_cast<Index>(it - filtered_sources_.begin()));
        }
      }
    }
    maps_.push_back(std::move(map));
  }
}

Index LiveBasis::find(const ident::Term& term) const {
  const auto it = std::find(terms_.begin(), terms_.end(), term);
  return it == terms_.end() ? -1 : static_cast<Index>(it - terms_.begin());
}

bool LiveBasis::reads(ident::Variable v) const {
  return std::any_of(terms_.begin(), terms_.end(), [v](const ident::Term& t) { return t.uses(v); });
}

void LiveBasis::coefficients(Index term, const Eigen::Matrix3d& m, bool filtered_squares,
                             Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> base_row,
                             Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> filtered_row) const {
  base_row.setZero();
  filtered_row.setZero();
  const TermMap& map = maps_.at(static_cast<std::size_t>(term));
  if (!map.expansion) {
    base_row(map.base.front()) = 1.0;
    return;
  }
  Eigen::VectorXd c(static_cast<Index>(map.base.size()));
  map.expansion->coefficients(m, c);
  const bool filtered = map.square && filtered_squares;
  for (std::size_t j = 0; j < map.base.size(); ++j) {
    if (filtered) filtered_row(map.filtered[j]) += c(static_cast<Index>(j));
    else base_row(map.base[j]) += c(static_cast<Index>(j));
  }
}

void LiveBasis::transform(const std::vector<Index>& terms, const Eigen::Matrix3d& m, bool filtered, Eigen::MatrixXd& t_base,
                          Eigen::MatrixXd& t_filtered) const {
  const auto p = static_cast<Index>(terms.size());
  t_base.resize(p, base_size());
  t_filtered.resize(p, filtered_size());
  for (Index i = 0; i < p; ++i) coefficients(terms[static_cast<std::size_t>(i)], m, filtered, t_base.row(i), t_filtered.row(i));
}

void LiveBasis::evaluate(const ident::SignalSet& signals, Index first_row, Eigen::Ref<Eigen::MatrixXd> out) const {
  ident::fill_regressors(base_, signals, first_row, out);
}

}  // namespace inertia::online
