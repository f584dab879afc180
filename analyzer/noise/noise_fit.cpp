#include "analyzer/noise/noise_fit.hpp"

#include <Eigen/Dense>

#include <boost/math/distributions/normal.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace inertia::noise {
namespace {

constexpr double kFlicker = 2.0 * std::numbers::ln2 / std::numbers::pi;

/// Correlation of overlapping Allan variance estimates `octaves` apart, for the noise that
/// dominates them: adjacent octaves share half their samples, and the redder the noise the more
/// the long windows of one octave see what the other saw. The figures for 1, 2 and 3 octaves are
/// empirical, from simulated records of each noise type (docs/validation.md, 'Evidence behind
/// choices in the code'); farther octaves: the third's figure falling by 0.7 an octave. White PM
/// and ramps take the nearest type.
double octave_correlation(int alpha, int octaves) {
  if (octaves == 0) return 1.0;
  static constexpr double kWhite[3] = {0.50, 0.15, 0.03}, kFlicker[3] = {0.70, 0.33, 0.13}, kWalk[3] = {0.88, 0.65, 0.48};
  const double* t = alpha >= 0 ? kWhite : alpha == -1 ? kFlicker : kWalk;
  if (octaves <= 3) return t[octaves - 1];
  return t[2] * std::pow(0.7, octaves - 3);
}

struct SubsetFit {
  bool ok = false;
  Eigen::VectorXd z;
  Eigen::MatrixXd covariance;
  double rss = 0.0;
};

/// Weighted least squares of v on the columns `s` of a (weights w); the covariance of the
/// estimate the sandwich (A'WA)^-1 A'W C W A (A'WA)^-1 with C the estimates' full covariance.
SubsetFit fit_subset(const Eigen::MatrixXd& a, const Eigen::VectorXd& v, const Eigen::VectorXd& w,
                     const Eigen::MatrixXd& c, const std::vector<int>& s) {
  SubsetFit out;
  const Eigen::Index m = a.rows();
  Eigen::MatrixXd as(m, static_cast<Eigen::Index>(s.size()));
  for (std::size_t k = 0; k < s.size(); ++k) as.col(static_cast<Eigen::Index>(k)) = a.col(s[k]);
  // Columns scaled to unit weighted norm: their magnitudes span tens of decades.
  const Eigen::MatrixXd wa = w.cwiseSqrt().asDiagonal() * as;
  const Eigen::VectorXd scale = wa.colwise().norm().transpose();
  if ((scale.array() <= 0.0).any()) return out;
  const Eigen::MatrixXd was = wa * scale.cwiseInverse().asDiagonal();
  const Eigen::VectorXd wv = w.cwiseSqrt().cwiseProduct(v);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(was, Eigen::ComputeThinU | Eigen::ComputeThinV);
  if (svd.singularValues().minCoeff() < 1e-10 * svd.singularValues().maxCoeff()) return out;
  out.z = svd.solve(wv).cwiseQuotient(scale);
  out.rss = (wv - wa * out.z).squaredNorm();
  const Eigen::MatrixXd bread = (as.transpose() * w.asDiagonal() * as).inverse();
  const Eigen::MatrixXd wav = w.asDiagonal() * as;
  out.covariance = bread * (wav.transpose() * c * wav) * bread;
  out.ok = true;
  return out;
}

Eigen::Matrix<double, 1, kNoiseTerms> basis_row(double tau) {
  Eigen::Matrix<double, 1, kNoiseTerms> a;
  a << 3.0 / (tau * tau), 1.0 / tau, kFlicker, tau / 3.0, tau * tau / 2.0;
  return a;
}

}  // namespace

const char* noise_term_name(NoiseTerm t) {
  static constexpr const char* kNames[kNoiseTerms] = {"Q", "N", "B", "K", "R"};
  return kNames[static_cast<int>(t)];
}

const char* noise_term_meaning(NoiseTerm t) {
  static constexpr const char* kMeanings[kNoiseTerms] = {"quantization", "white noise (angle / velocity random walk)",
                                                         "bias instability (flicker)", "rate random walk",
                                                         "rate ramp"};
  return kMeanings[static_cast<int>(t)];
}

int noise_term_alpha(NoiseTerm t) {
  static constexpr int kAlpha[kNoiseTerms] = {2, 0, -1, -2, -3};
  return kAlpha[static_cast<int>(t)];
}

double model_avar(const std::array<double, kNoiseTerms>& c, double tau) {
  const auto a = basis_row(tau);
  double s = 0.0;
  for (int j = 0; j < kNoiseTerms; ++j) s += a(j) * c[static_cast<std::size_t>(j)] * c[static_cast<std::size_t>(j)];
  return s;
}

double model_psd(const std::array<double, kNoiseTerms>& c, double f_hz, double tau0_s) {
  const double w = 2.0 * std::numbers::pi * f_hz;
  const auto v = [&](NoiseTerm t) { return c[static_cast<std::size_t>(t)] * c[static_cast<std::size_t>(t)]; };
  const double quantization = 4.0 * std::pow(std::sin(std::numbers::pi * f_hz * tau0_s), 2) / tau0_s;
  return 2.0 * (v(NoiseTerm::Q) * quantization + v(NoiseTerm::N) + v(NoiseTerm::B) / w + v(NoiseTerm::K) / (w * w) +
                v(NoiseTerm::R) / (w * w * w));
}

double NoiseFit::avar(double tau) const {
  std::array<double, kNoiseTerms> c{};
  for (int j = 0; j < kNoiseTerms; ++j) c[static_cast<std::size_t>(j)] = terms[static_cast<std::size_t>(j)].value;
  return model_avar(c, tau);
}

NoiseFit fit_noise(const std::vector<AllanPoint>& points, const NoiseFitOptions& options) {
  NoiseFit out;
  out.fitted = options.terms;
  const auto n = static_cast<Eigen::Index>(points.size());
  Eigen::MatrixXd a(n, kNoiseTerms);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    a.row(i) = basis_row(points[static_cast<std::size_t>(i)].tau);
    v(i) = points[static_cast<std::size_t>(i)].avar;
  }
  // Start: each point weighted by its own estimate and white-noise edf.
  Eigen::VectorXd edf(n), expected = v;
  std::vector<int> alpha(static_cast<std::size_t>(n), 0);
  const auto dominant_alpha = [&alpha](Eigen::Index i) { return alpha[static_cast<std::size_t>(i)]; };
  for (Eigen::Index i = 0; i < n; ++i) edf(i) = point_edf(points[static_cast<std::size_t>(i)], 0);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(kNoiseTerms);
  std::vector<int> subset;
  Eigen::MatrixXd covariance;
  double chi2 = 0.0;
  std::vector<Eigen::Index> used;
  Eigen::MatrixXd au, cov;
  Eigen::VectorXd vu, w;
  for (int iteration = 0; iteration < 6; ++iteration) {
    used.clear();
    for (Eigen::Index i = 0; i < n; ++i)
      if (edf(i) >= options.min_edf && expected(i) > 0.0) used.push_back(i);
    int enabled = 0;
    for (bool t : options.terms) enabled += t ? 1 : 0;
    if (static_cast<int>(used.size()) < std::min(enabled, 2) + 1)
      throw std::invalid_argument("noise fit: " + std::to_string(used.size()) + " octave(s) with enough degrees of freedom");
    const auto m = static_cast<Eigen::Index>(used.size());
    au.resize(m, kNoiseTerms);
    vu.resize(m);
    // The estimates' covariance: variance 2 sigma^4 / edf, correlation between octaves.
    cov.resize(m, m);
    for (Eigen::Index r = 0; r < m; ++r) {
      const Eigen::Index i = used[static_cast<std::size_t>(r)];
      au.row(r) = a.row(i);
      vu(r) = v(i);
    }
    for (Eigen::Index r = 0; r < m; ++r) {
      const Eigen::Index i = used[static_cast<std::size_t>(r)];
      for (Eigen::Index c = 0; c < m; ++c) {
        const Eigen::Index j = used[static_cast<std::size_t>(c)];
        const int octaves = static_cast<int>(std::lround(std::abs(std::log2(points[static_cast<std::size_t>(j)].tau /
                                                                             points[static_cast<std::size_t>(i)].tau))));
        const double rho = std::sqrt(octave_correlation(dominant_alpha(i), octaves) * octave_correlation(dominant_alpha(j), octaves));
        cov(r, c) = rho * std::sqrt(2.0 / edf(i)) * std::sqrt(2.0 / edf(j)) * expected(i) * expected(j);
      }
    }
    {
      // Octaves dominated by different noise types mix two correlation tables, which need not
      // be positive definite together: the nearest one that is (eigenvalues clipped).
      const Eigen::VectorXd d = cov.diagonal().cwiseSqrt();
      Eigen::MatrixXd corr = d.cwiseInverse().asDiagonal() * cov * d.cwiseInverse().asDiagonal();
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(corr);
      const Eigen::VectorXd lambda = eig.eigenvalues().cwiseMax(1e-3);
      corr = eig.eigenvectors() * lambda.asDiagonal() * eig.eigenvectors().transpose();
      const Eigen::VectorXd dc = corr.diagonal().cwiseSqrt();
      corr = dc.cwiseInverse().asDiagonal() * corr * dc.cwiseInverse().asDiagonal();
      cov = d.asDiagonal() * corr * d.asDiagonal();
    }
    // Weights: each octave's own variance (generalized least squares with the full covariance
    // leans on the strongly correlated long octaves and bends the random-walk term); the
    // correlation enters the estimate's covariance (sandwich) below.
    w = cov.diagonal().cwiseInverse();
    // The best non-negative subset (32 at most: exhaustive is exact and cheap).
    double best = std::numeric_limits<double>::infinity();
    Eigen::VectorXd best_z;
    std::vector<int> best_subset;
    Eigen::MatrixXd best_cov;
    for (int mask = 1; mask < (1 << kNoiseTerms); ++mask) {
      std::vector<int> s;
      bool allowed = true;
      for (int j = 0; j < kNoiseTerms; ++j) {
        if ((mask >> j) & 1) {
          if (!options.terms[static_cast<std::size_t>(j)]) allowed = false;
          s.push_back(j);
        }
      }
      if (!allowed || static_cast<Eigen::Index>(s.size()) >= m) continue;
      const SubsetFit f = fit_subset(au, vu, w, cov, s);
      if (!f.ok || (f.z.array() <= 0.0).any()) continue;
      if (f.rss < best) {
        best = f.rss;
        best_z = f.z;
        best_subset = s;
        best_cov = f.covariance;
      }
    }
    if (best_subset.empty()) throw std::invalid_argument("noise fit: no non-negative combination of the terms fits");
    z.setZero();
    for (std::size_t c = 0; c < best_subset.size(); ++c) z(best_subset[c]) = best_z(static_cast<Eigen::Index>(c));
    subset = best_subset;
    covariance = best_cov;
    chi2 = best;
    // Weights from the model, edf from the noise that dominates each octave.
    expected = a * z;
    for (Eigen::Index i = 0; i < n; ++i) {
      int dominant = 1;
      double largest = -1.0;
      for (int j = 0; j < kNoiseTerms; ++j) {
        const double part = a(i, j) * z(j);
        if (part > largest) {
          largest = part;
          dominant = j;
        }
      }
      alpha[static_cast<std::size_t>(i)] = noise_term_alpha(static_cast<NoiseTerm>(dominant));
      edf(i) = point_edf(points[static_cast<std::size_t>(i)], alpha[static_cast<std::size_t>(i)]);
    }
  }
  out.dof = static_cast<int>(used.size()) - static_cast<int>(subset.size());
  out.chi_square = chi2;
  // The intervals come from the estimates' modelled covariance; a fit much worse than it (a
  // noise the five terms do not hold) is in chi_square for the report to say so.
  const boost::math::normal normal;
  const double zq = boost::math::quantile(normal, 0.5 + 0.5 * options.level);
  out.tau_min = points[static_cast<std::size_t>(used.front())].tau;
  out.tau_max = points[static_cast<std::size_t>(used.back())].tau;
  for (int j = 0; j < kNoiseTerms; ++j) {
    NoiseCoefficient& c = out.terms[static_cast<std::size_t>(j)];
    const auto at = std::find(subset.begin(), subset.end(), j);
    if (at != subset.end()) {
      const auto k = static_cast<Eigen::Index>(at - subset.begin());
      const double sd = std::sqrt(covariance(k, k));
      const double value = z(j);
      c.value = std::sqrt(value);
      c.lower = std::sqrt(std::max(0.0, value - zq * sd));
      c.upper = std::sqrt(value + zq * sd);
      c.determined = value - zq * sd > 0.0;
    } else if (options.terms[static_cast<std::size_t>(j)]) {
      // Not in the best non-negative fit: its upper bound from the fit that adds it unconstrained.
      std::vector<int> with = subset;
      with.push_back(j);
      const SubsetFit f = fit_subset(au, vu, w, cov, with);
      if (f.ok) {
        const auto k = static_cast<Eigen::Index>(with.size() - 1);
        c.upper = std::sqrt(std::max(0.0, f.z(k) + zq * std::sqrt(f.covariance(k, k))));
      }
    }
    // The taus where this term carries at least half of the model.
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (a(i, j) * z(j) >= 0.5 * expected(i) && expected(i) > 0.0) {
        lo = std::min(lo, points[static_cast<std::size_t>(i)].tau);
        hi = std::max(hi, points[static_cast<std::size_t>(i)].tau);
      }
    }
    if (hi > 0.0) {
      c.tau_min = lo;
      c.tau_max = hi;
    }
  }
  out.model.assign(expected.data(), expected.data() + expected.size());
  out.edf.assign(edf.data(), edf.data() + edf.size());
  return out;
}

}  // namespace inertia::noise
