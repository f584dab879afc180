#include "hal/sim/sensors/discrete_filter.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace inertia::sim {
namespace {

std::string list(std::span<const double> v) {
  std::ostringstream s;
  s.precision(17);
  s << '[';
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
  s << ']';
  return s.str();
}

}  // namespace

void validate_transfer_function(std::span<const double> num, std::span<const double> den,
                                std::string_view name) {
  const std::string what(name);
  for (double c : num)
    if (!std::isfinite(c)) throw std::invalid_argument(what + ": num = " + list(num) + " has a non-finite coefficient");
  for (double c : den)
    if (!std::isfinite(c)) throw std::invalid_argument(what + ": den = " + list(den) + " has a non-finite coefficient");
  if (den.empty() || den[0] != 1.0)
    throw std::invalid_argument(what + ": den = " + list(den) + " must start with 1 (den[0] == 1)");
  // Schur-Cohn (Levinson step-down): den is stable iff every reflection coefficient k_m = a_m of
  // the successively reduced polynomials has |k_m| < 1. Exact for a root on the unit circle.
  std::vector<double> a(den.begin(), den.end()), reduced(den.size());
  for (std::size_t m = a.size() - 1; m >= 1; --m) {
    const double k = a[m];
    if (!(std::abs(k) < 1.0))
      throw std::invalid_argument(what + ": den = " + list(den) +
                                  " has a root on or outside the unit circle (unstable filter)");
    for (std::size_t i = 1; i < m; ++i) reduced[i] = (a[i] - k * a[m - i]) / (1.0 - k * k);
    for (std::size_t i = 1; i < m; ++i) a[i] = reduced[i];
  }
}

}  // namespace inertia::sim
