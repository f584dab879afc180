#include "analyzer/procedure/excitation.hpp"

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

}  // namespace inertia::procedure
