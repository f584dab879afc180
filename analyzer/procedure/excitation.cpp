#include "analyzer/procedure/excitation.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace inertia::procedure {

AxisExcitation axis_excitation(const Eigen::Matrix4d& gram, bool with_bias) {
  AxisExcitation out;
  const double total = gram(0, 0) + gram(1, 1) + gram(2, 2);
  if (!(total > 0.0)) return out;
  // Gram-Schmidt on inner products: the bias first (when estimated), then IRA, XRA, YRA, each
  // against what is already in and was found determined.
  Eigen::Matrix4d g = gram;
  const auto orthogonalize_against = [&g](int m) {
    const double pivot = g(m, m);
    if (!(pivot > 0.0)) return;
    const Eigen::Vector4d column = g.col(m);
    g -= column * column.transpose() / pivot;
  };
  if (with_bias) orthogonalize_against(3);
  for (int axis = 0; axis < 3; ++axis) {
    out.share[static_cast<std::size_t>(axis)] = std::max(0.0, g(axis, axis)) / total;
    out.determined[static_cast<std::size_t>(axis)] = out.share[static_cast<std::size_t>(axis)] >= kMinExcitationShare;
    if (out.determined[static_cast<std::size_t>(axis)]) orthogonalize_against(axis);
  }
  return out;
}

std::string missing_excitation(int axis, bool gyro) {
  const char* name = axis == 1 ? "XRA" : "YRA";
  const char* angle = axis == 1 ? "about YRA (o)" : "about XRA (p)";
  if (gyro) {
    return std::string("the turn of the input axis ") + angle + " needs a rate about " + name +
           " (a rate-table run with the table axis along " + name + ")";
  }
  return std::string("the turn of the input axis ") + angle + " needs a specific force along " + name +
         " that varies on its own (a table or tumble pose with gravity along " + name +
         ", or vibration along it)";
}

std::vector<std::string> held_angle_notes(const AxisExcitation& excitation, bool gyro, bool with_bias) {
  std::vector<std::string> notes;
  if (!excitation.scale_determined()) {
    notes.push_back(fmt::format("M_C^S held at the nominal case frame: no {} along IRA varies on its own in this mounting "
                                "({:.1e} of its input energy, at least {:.0e} needed){}",
                                gyro ? "rate" : "specific force", excitation.share[0], kMinExcitationShare,
                                with_bias ? "; a constant input is a bias" : ""));
    return notes;
  }
  for (int axis = 1; axis < 3; ++axis) {
    const auto a = static_cast<std::size_t>(axis);
    if (excitation.aligns() && excitation.determined[a]) continue;
    notes.push_back(fmt::format("angle about {} held at the nominal case frame ({:.1e} of the input energy varies on its "
                                "own along {}): {}",
                                axis == 1 ? "o" : "p", excitation.share[a], axis == 1 ? "XRA" : "YRA",
                                missing_excitation(axis, gyro)));
  }
  return notes;
}

bool frame_free(const ident::Term& term) {
  return std::all_of(term.factors().begin(), term.factors().end(), [](const ident::Factor& f) {
    using ident::Variable;
    const bool input = f.variable == Variable::Ai || f.variable == Variable::Wi;
    return (input && f.power == 1 && f.function == ident::FactorFunction::Plain) || f.variable == Variable::T ||
           f.variable == Variable::Y || f.variable == Variable::E;
  });
}

}  // namespace inertia::procedure
