#include "analyzer/procedure/mounting_rules.hpp"

namespace inertia::procedure {

namespace {

bool is_plain_square_of(const ident::Term& term, ident::Variable v) {
  const auto& f = term.factors();
  return f.size() == 1 && f[0].power == 2 && f[0].function == ident::FactorFunction::Plain && f[0].variable == v;
}

}  // namespace

bool ieee_1293_excluded(const ident::Term& term, const MountingKind& kind, bool bias_supplied, const Ieee1293Rules& rules) {
  if (kind.rotation_table && rules.rotation_table &&
      (is_plain_square_of(term, ident::Variable::Ap) || is_plain_square_of(term, ident::Variable::Ao)))
    return true;
  return kind.shaker_only && rules.shaker && bias_supplied && term.is_bias();
}

bool takes_bias(const MountingKind& kind, const Ieee1293Rules& rules) { return kind.shaker_only && rules.shaker; }

bool hands_on_bias(const MountingKind& kind) { return !kind.shaker_only; }

std::vector<std::size_t> mounting_order(std::span<const MountingKind> kinds) {
  std::vector<std::size_t> order;
  for (std::size_t m = 0; m < kinds.size(); ++m)
    if (hands_on_bias(kinds[m])) order.push_back(m);
  for (std::size_t m = 0; m < kinds.size(); ++m)
    if (!hands_on_bias(kinds[m])) order.push_back(m);
  return order;
}

}  // namespace inertia::procedure
