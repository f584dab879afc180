#include "analyzer/ident/frame_expansion.hpp"

#include <map>
#include <optional>
#include <stdexcept>

namespace inertia::ident {
namespace {

/// Row of M and the first other-frame variable of a sensor-frame variable (a_i -> row 0, a_x).
std::optional<std::pair<int, Variable>> sensor_axis(Variable v) {
  switch (v) {
    case Variable::Ai: return std::pair{0, Variable::Ax};
    case Variable::Ap: return std::pair{1, Variable::Ax};
    case Variable::Ao: return std::pair{2, Variable::Ax};
    case Variable::Wi: return std::pair{0, Variable::Wx};
    case Variable::Wp: return std::pair{1, Variable::Wx};
    case Variable::Wo: return std::pair{2, Variable::Wx};
    default: return std::nullopt;
  }
}

Variable offset(Variable first, int c) { return static_cast<Variable>(static_cast<int>(first) + c); }

}  // namespace

bool expandable(const Term& term) {
  for (const Factor& f : term.factors())
    if (sensor_axis(f.variable) && f.function != FactorFunction::Plain) return false;
  return true;
}

FrameExpansion::FrameExpansion(const Term& term) {
  if (!expandable(term)) {
    throw std::invalid_argument("term '" + term.to_string() +
                                "' holds abs() or sign() of a sensor-frame variable: not a polynomial in another frame");
  }
  // Every power unit of a sensor-frame factor picks one coordinate c of the other frame (and the
  // entry M(row, c)); the frame-free factors ride along. 3^units choices, one product each.
  std::vector<Factor> fixed;
  struct Unit {
    int row;
    Variable first;
    int lag;
  };
  std::vector<Unit> units;
  for (const Factor& f : term.factors()) {
    if (const auto axis = sensor_axis(f.variable)) {
      for (int k = 0; k < f.power; ++k) units.push_back({axis->first, axis->second, f.lag});
    } else {
      fixed.push_back(f);
    }
  }
  std::map<Term, std::size_t> index;
  std::vector<std::pair<Term, std::vector<int>>> raw;
  std::vector<int> choice(units.size(), 0);
  for (;;) {
    std::vector<Factor> factors = fixed;
    std::vector<int> entries;
    for (std::size_t u = 0; u < units.size(); ++u) {
      factors.push_back(Factor{offset(units[u].first, choice[u]), units[u].lag, FactorFunction::Plain, 1});
      entries.push_back(units[u].row * 3 + choice[u]);
    }
    Term monomial = Term::from_factors(std::move(factors));
    index.try_emplace(monomial, 0);
    raw.emplace_back(std::move(monomial), std::move(entries));
    std::size_t u = 0;
    while (u < choice.size() && ++choice[u] == 3) choice[u++] = 0;
    if (u == choice.size()) break;
  }
  for (auto& [monomial, position] : index) {
    position = monomials_.size();
    monomials_.push_back(monomial);
  }
  for (auto& [monomial, entries] : raw) products_.push_back({index.at(monomial), std::move(entries)});
}

void FrameExpansion::coefficients(const Eigen::Matrix3d& m, Eigen::Ref<Eigen::VectorXd> out) const {
  out.setZero();
  for (const Product& p : products_) {
    double c = 1.0;
    for (int e : p.entries) c *= m(e / 3, e % 3);
    out(static_cast<Eigen::Index>(p.monomial)) += c;
  }
}

std::vector<FrameMonomial> expand_in_frame(const Term& term, const Eigen::Matrix3d& m) {
  const FrameExpansion expansion(term);
  Eigen::VectorXd c(static_cast<Eigen::Index>(expansion.monomials().size()));
  expansion.coefficients(m, c);
  std::vector<FrameMonomial> out;
  for (std::size_t j = 0; j < expansion.monomials().size(); ++j)
    out.push_back({expansion.monomials()[j], c(static_cast<Eigen::Index>(j))});
  return out;
}

}  // namespace inertia::ident
