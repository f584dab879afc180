#include "analyzer/noise/quadratic_form_law.hpp"

#include <boost/math/distributions/normal.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace inertia::noise {

QuadraticFormLaw QuadraticFormLaw::from(const Eigen::VectorXd& leading, double trace, double trace_of_square) {
  QuadraticFormLaw law;
  law.leading = leading;
  const double rest_mean = trace - leading.sum();
  const double rest_square = trace_of_square - leading.squaredNorm();
  // What rounding leaves of an exhausted spectrum is no rest.
  if (rest_mean > 1e-12 * trace && rest_square > 0.0) {
    law.rest_scale = rest_square / rest_mean;
    law.rest_dof = rest_mean * rest_mean / rest_square;
  }
  return law;
}

double QuadraticFormLaw::mean() const { return leading.sum() + rest_scale * rest_dof; }

double QuadraticFormLaw::variance() const {
  return 2.0 * (leading.squaredNorm() + rest_scale * rest_scale * rest_dof);
}

double QuadraticFormLaw::upper_tail(double q) const {
  if (!(q > 0.0)) return 1.0;
  // Cumulant generating function K(t) = -1/2 sum log(1 - 2 l t) - nu/2 log(1 - 2 c t) and its
  // first two derivatives, for t below 1 / (2 max weight).
  struct Derivatives {
    double k0 = 0.0, k1 = 0.0, k2 = 0.0;
  };
  const auto at = [&](double t) {
    Derivatives d;
    const auto add = [&](double weight, double times) {
      const double s = 1.0 - 2.0 * weight * t;
      d.k0 -= 0.5 * times * std::log(s);
      d.k1 += times * weight / s;
      d.k2 += times * 2.0 * weight * weight / (s * s);
    };
    for (Eigen::Index i = 0; i < leading.size(); ++i) add(leading(i), 1.0);
    if (rest_dof > 0.0) add(rest_scale, rest_dof);
    return d;
  };
  const double largest = std::max(leading.size() > 0 ? leading.maxCoeff() : 0.0, rest_dof > 0.0 ? rest_scale : 0.0);
  if (!(largest > 0.0)) return 0.0;
  // K'(t) rises from 0 (t -> -inf) to +inf (t -> 1 / 2 largest): bisect for K'(t) = q.
  const double top = 0.5 / largest;
  double lo = -top, hi = top;
  while (at(lo).k1 > q) lo *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-15 * top; ++i) {
    const double mid = 0.5 * (lo + hi);
    (at(mid).k1 < q ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  const Derivatives d = at(t);
  const double w2 = 2.0 * (t * q - d.k0);
  const boost::math::normal standard;
  if (std::abs(t) * std::sqrt(d.k2) < 1e-4 || !(w2 > 0.0)) {
    // At the mean the two terms below cancel: the first-order Edgeworth value instead.
    const double k3 = 8.0 * (leading.array().cube().sum() + rest_scale * rest_scale * rest_scale * rest_dof);
    const double k2 = variance();
    return std::clamp(0.5 - k3 / (6.0 * std::sqrt(2.0 * std::numbers::pi) * std::pow(k2, 1.5)), 0.0, 1.0);
  }
  const double w = std::copysign(std::sqrt(w2), t), u = t * std::sqrt(d.k2);
  const double p = boost::math::cdf(boost::math::complement(standard, w)) + boost::math::pdf(standard, w) * (1.0 / u - 1.0 / w);
  return std::clamp(p, 0.0, 1.0);
}

}  // namespace inertia::noise
