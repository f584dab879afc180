#include "analyzer/compensate/affine_samples.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "analyzer/compensate/inverse_model.hpp"

namespace inertia::compensate {

namespace {

using Eigen::Index;

// Samples side by side: one AVX register of doubles.
constexpr Index kLanes = 4;
using Lane = Eigen::Array<double, kLanes, 1>;
using LaneMask = Eigen::Array<bool, kLanes, 1>;

/// `count` samples of `samples` from `at` (count < kLanes: the last one repeated into the spare
/// lanes, whose results are not written).
EIGEN_STRONG_INLINE Lane load(const double* samples, Index at, Index count) {
  if (count == kLanes) return Eigen::Map<const Lane>(samples + at);
  Lane v;
  for (Index i = 0; i < kLanes; ++i) v(i) = samples[at + std::min(i, count - 1)];
  return v;
}

EIGEN_STRONG_INLINE void store(const Lane& v, double* samples, Index count) {
  if (count == kLanes) {
    Eigen::Map<Lane> target(samples);
    target = v;
    return;
  }
  for (Index i = 0; i < count; ++i) samples[i] = v(i);
}

/// An equation's per-sample quantities and its covariance as the quadratic form reads it.
struct EquationLanes {
  std::vector<Lane> dg;       // d g / d c per term
  std::vector<Lane> solved;   // each solved row's value
  // The solved rows' entries that are not zero, row by row: (unknown, entry), and where each
  // row's run ends.
  std::vector<std::pair<Index, double>> row_entries;
  std::vector<std::size_t> row_end;
  // C's upper triangle row by row, the diagonal halved: a' C a = 2 sum_i a_i (C_ii a_i / 2 + sum_{j>i} C_ij a_j).
  std::vector<double> triangle;
  Lane b, denominator, quadratic, noise;
};

}  // namespace

template <int D>
void solve_affine_samples(const std::vector<AffineEquation>& equations, const Eigen::Matrix<double, D, D>& inverse, bool invertible,
                          Index first_row, Index n, JointCompensation& out) {
  std::vector<EquationLanes> lanes(equations.size());
  for (std::size_t m = 0; m < equations.size(); ++m) {
    const AffineEquation& e = equations[m];
    EquationLanes& l = lanes[m];
    const Index terms = e.covariance.rows();
    l.dg.assign(static_cast<std::size_t>(terms), Lane::Zero());
    for (const Index t : e.unit_terms) l.dg[static_cast<std::size_t>(t)] = Lane::Ones();
    l.solved.assign(static_cast<std::size_t>(e.rows.rows()), Lane::Zero());
    for (Index r = 0; r < e.rows.rows(); ++r) {
      for (Index d = 0; d < D; ++d)
        if (e.rows(r, d) != 0.0) l.row_entries.emplace_back(d, e.rows(r, d));
      l.row_end.push_back(l.row_entries.size());
    }
    for (Index i = 0; i < terms; ++i) {
      l.triangle.push_back(0.5 * e.covariance(i, i));
      for (Index j = i + 1; j < terms; ++j) l.triangle.push_back(e.covariance(i, j));
    }
  }
  const Eigen::Matrix<double, D, D> inverse_squared = inverse.array().square().matrix();
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

  std::array<Lane, D> x;
  for (Index k = first_row; k < n; k += kLanes) {
    const Index count = std::min(kLanes, n - k), r0 = k - first_row;
    // b per equation: the constant terms' share, minus y, plus each varying term's weighted known
    // part; each varying term's known part is also its derivative (times -y over the denominator).
    for (std::size_t m = 0; m < equations.size(); ++m) {
      const AffineEquation& e = equations[m];
      EquationLanes& l = lanes[m];
      const Lane y = load(e.y, k, count);
      Lane b = e.constant_b - y, denominator = Lane::Ones();
      for (const AffineEquation::VaryingTerm& term : e.varying) {
        Lane v = Lane::Ones();
        for (const AffineEquation::KnownFactor& f : term.factors) {
          const Lane input = load(f.column, k - f.factor.lag, count);
          if (f.factor.function == ident::FactorFunction::Plain && f.factor.power == 1) {
            v *= input;
          } else {
            for (Index i = 0; i < kLanes; ++i) v(i) *= factor_value(f.factor, input(i));
          }
        }
        Lane& dg = l.dg[static_cast<std::size_t>(term.term)];
        if (term.over_y) {
          b += (-y * term.coefficient) * v;
          denominator += term.coefficient * v;
          dg = v * -y;
        } else {
          b += term.coefficient * v;
          dg = v;
        }
      }
      l.b = b;
      l.denominator = denominator;
    }
    // x = -A^-1 b. A zero of the inverse adds a zero (a b that is not finite flags the sample
    // below whatever x it gives).
    for (Index d = 0; d < D; ++d) {
      Lane xd = Lane::Zero();
      for (Index j = 0; j < D; ++j) xd -= inverse(d, j) * lanes[static_cast<std::size_t>(j)].b;
      x[static_cast<std::size_t>(d)] = xd;
    }
    LaneMask inside = LaneMask::Constant(true);
    for (std::size_t m = 0; m < equations.size(); ++m) {
      const AffineEquation& e = equations[m];
      EquationLanes& l = lanes[m];
      // Each solved row's value from its entries that are not zero: a row reads the three axes of
      // its own triad.
      std::size_t entry = 0;
      for (std::size_t r = 0; r < l.solved.size(); ++r) {
        Lane v = Lane::Zero();
        for (; entry < l.row_end[r]; ++entry) v += l.row_entries[entry].second * x[static_cast<std::size_t>(l.row_entries[entry].first)];
        l.solved[r] = v;
      }
      for (const auto& [t, row] : e.row_terms) l.dg[static_cast<std::size_t>(t)] = l.solved[static_cast<std::size_t>(row)];
      Lane quadratic = Lane::Zero();
      const double* c = l.triangle.data();
      const auto terms = static_cast<std::size_t>(l.dg.size());
      for (std::size_t i = 0; i < terms; ++i) {
        Lane c_dg = *c++ * l.dg[i];
        for (std::size_t j = i + 1; j < terms; ++j) c_dg += *c++ * l.dg[j];
        quadratic += c_dg * l.dg[i];
      }
      l.quadratic = (2.0 * quadratic).cwiseMax(0.0);
      l.noise = (e.noise_sd * l.denominator).square();
      // Inside the characterized range: every solved input and every known one at the sample.
      for (const AffineEquation::Bound& bound : e.bounds) {
        const Lane v = bound.solved >= 0 ? l.solved[static_cast<std::size_t>(bound.solved)] : load(bound.column, k, count);
        inside = inside && (v >= bound.lowest) && (v <= bound.highest);
      }
    }
    // Each unknown's variances: the equations' through the inverse's entries squared.
    Lane x_sum = Lane::Zero();
    for (Index d = 0; d < D; ++d) {
      Lane variance_c = Lane::Zero(), variance_n = Lane::Zero();
      for (Index m = 0; m < D; ++m) {
        variance_c += inverse_squared(d, m) * lanes[static_cast<std::size_t>(m)].quadratic;
        variance_n += inverse_squared(d, m) * lanes[static_cast<std::size_t>(m)].noise;
      }
      const Lane& xd = x[static_cast<std::size_t>(d)];
      x_sum += xd;
      store(xd, out.value.col(d).data() + r0, count);
      store(variance_c.sqrt(), out.u_coefficients.col(d).data() + r0, count);
      store(variance_n.sqrt(), out.u_noise.col(d).data() + r0, count);
    }
    // A value not finite in b is one in some x (a column of an inverse has an entry that is not
    // zero, and NaN or infinity times it is not finite), and one in any x is one in their sum.
    for (Index i = 0; i < count; ++i) {
      const Index r = r0 + i;
      if (!invertible || !std::isfinite(x_sum(i))) {
        out.value.row(r).setConstant(kNaN);
        out.u_coefficients.row(r).setConstant(kNaN);
        out.u_noise.row(r).setConstant(kNaN);
        out.flag[static_cast<std::size_t>(r)] = SampleFlag::NotConverged;
        ++out.not_converged;
      } else if (!inside(i)) {
        out.flag[static_cast<std::size_t>(r)] = SampleFlag::OutsideRange;
        ++out.outside_range;
      }
    }
  }
}

template void solve_affine_samples<1>(const std::vector<AffineEquation>&, const Eigen::Matrix<double, 1, 1>&, bool, Index, Index,
                                      JointCompensation&);
template void solve_affine_samples<3>(const std::vector<AffineEquation>&, const Eigen::Matrix<double, 3, 3>&, bool, Index, Index,
                                      JointCompensation&);
template void solve_affine_samples<6>(const std::vector<AffineEquation>&, const Eigen::Matrix<double, 6, 6>&, bool, Index, Index,
                                      JointCompensation&);

}  // namespace inertia::compensate
