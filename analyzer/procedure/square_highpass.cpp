#include "analyzer/procedure/square_highpass.hpp"

#include <cmath>

namespace inertia::procedure {

bool is_square_term(const ident::Term& term) {
  const auto& f = term.factors();
  return f.size() == 1 && f[0].power == 2 && f[0].function == ident::FactorFunction::Plain &&
         (f[0].variable == ident::Variable::Ai || f[0].variable == ident::Variable::Ap ||
          f[0].variable == ident::Variable::Ao);
}

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s) {
  HighpassState state;
  highpass_in_place(x, corner_rad_s, sample_period_s, state);
}

void highpass_in_place(Eigen::Ref<Eigen::VectorXd> x, double corner_rad_s, double sample_period_s,
                       HighpassState& state) {
  if (x.size() == 0) return;
  const double c = corner_rad_s / std::tan(corner_rad_s * sample_period_s / 2.0);
  const double p = (c - corner_rad_s) / (c + corner_rad_s);
  const double g = c / (c + corner_rad_s);
  if (!state.started) {
    state = {x(0), 0.0, true};
  }
  double h = state.output, previous = state.previous_input;
  for (Eigen::Index k = 0; k < x.size(); ++k) {
    const double input = x(k);
    h = p * h + g * (input - previous);
    previous = input;
    x(k) = h;
  }
  state.previous_input = previous;
  state.output = h;
}

}  // namespace inertia::procedure
