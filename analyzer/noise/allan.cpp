#include "analyzer/noise/allan.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <boost/math/distributions/chi_squared.hpp>

namespace inertia::noise {

/// One octave level: its samples (raw, or 2^j-averages), the window sums of its octaves, and the
/// pair it is building for the next level.
struct AllanAccumulator::Level {
  int first_octave = 0, last_octave = 0;   // octaves k (m' = 2^k of this level's samples)
  std::vector<double> ring;                // newest 4 * 2^last_octave samples (2m + 1 are read)
  std::size_t mask = 0;
  std::int64_t resum_period = 0;           // 2^last_octave
  std::int64_t count = 0;                  // samples received
  std::vector<double> newer, older;        // per octave: sum of the newest m', of the m' before
  std::vector<double> sum_sq;              // per octave: sum of (newer - older)^2
  std::vector<std::int64_t> terms;
  // Modified variance: per octave the newest m' second differences and their sum.
  std::vector<std::vector<double>> d_ring;
  std::vector<double> d_sum, mod_sum_sq;
  std::vector<std::int64_t> d_count, mod_terms;
  double pending = 0.0;                    // first of a pair for the next level
  bool has_pending = false;
  bool modified = false;

  Level(int first, int last, bool with_modified) : first_octave(first), last_octave(last), modified(with_modified) {
    const std::size_t size = std::size_t{4} << last;
    ring.assign(size, 0.0);
    mask = size - 1;
    resum_period = std::int64_t{1} << last;
    const auto n = static_cast<std::size_t>(last - first + 1);
    newer.assign(n, 0.0);
    older.assign(n, 0.0);
    sum_sq.assign(n, 0.0);
    terms.assign(n, 0);
    if (modified) {
      d_ring.resize(n);
      for (std::size_t o = 0; o < n; ++o) d_ring[o].assign(std::size_t{1} << (first + static_cast<int>(o)), 0.0);
      d_sum.assign(n, 0.0);
      mod_sum_sq.assign(n, 0.0);
      d_count.assign(n, 0);
      mod_terms.assign(n, 0);
    }
  }

  [[nodiscard]] double at(std::int64_t age) const {   // age 0 = newest
    return ring[static_cast<std::size_t>(count - 1 - age) & mask];
  }

  void push(double v) {
    ring[static_cast<std::size_t>(count) & mask] = v;
    ++count;
    // Powers of two throughout: masks, not divisions (an integer division per octave was most of
    // the per-sample cost).
    const bool resum = (count & (resum_period - 1)) == 0;
    for (int k = first_octave; k <= last_octave; ++k) {
      const auto o = static_cast<std::size_t>(k - first_octave);
      const std::int64_t m = std::int64_t{1} << k;
      if (resum) {
        // Exact sums from the ring: whatever rounding the running updates gathered is gone.
        double a = 0.0, b = 0.0;
        for (std::int64_t i = 0; i < std::min(m, count); ++i) a += at(i);
        for (std::int64_t i = m; i < std::min(2 * m, count); ++i) b += at(i);
        newer[o] = a;
        older[o] = b;
      } else {
        newer[o] += v;
        if (count > m) {
          const double leaving = at(m);
          newer[o] -= leaving;
          older[o] += leaving;
        }
        if (count > 2 * m) older[o] -= at(2 * m);
      }
      if (count < 2 * m) continue;
      const double d = newer[o] - older[o];
      sum_sq[o] += d * d;
      ++terms[o];
      if (!modified) continue;
      // Modified variance: the sum of the newest m second differences.
      std::vector<double>& dr = d_ring[o];
      const auto slot = static_cast<std::size_t>(d_count[o] & (m - 1));
      if (d_count[o] >= m) d_sum[o] -= dr[slot];
      dr[slot] = d;
      d_sum[o] += d;
      ++d_count[o];
      if ((d_count[o] & (m - 1)) == 0) {
        // Re-sum exactly once per window turn.
        double s = 0.0;
        for (double x : dr) s += x;
        d_sum[o] = s;
      }
      if (d_count[o] >= m) {
        mod_sum_sq[o] += d_sum[o] * d_sum[o];
        ++mod_terms[o];
      }
    }
  }
};

AllanAccumulator::AllanAccumulator(double tau0_s, int exact_octaves) : tau0_(tau0_s), exact_octaves_(exact_octaves) {
  if (!(tau0_s > 0.0) || !std::isfinite(tau0_s)) throw std::invalid_argument("AllanAccumulator: tau0 must be > 0");
  if (exact_octaves < 1 || exact_octaves > 20) throw std::invalid_argument("AllanAccumulator: exact_octaves in 1..20");
  levels_.emplace_back(0, exact_octaves, true);
}

AllanAccumulator::~AllanAccumulator() = default;
AllanAccumulator::AllanAccumulator(AllanAccumulator&&) noexcept = default;
AllanAccumulator& AllanAccumulator::operator=(AllanAccumulator&&) noexcept = default;

void AllanAccumulator::push(double y) {
  double v = y;
  for (std::size_t j = 0;; ++j) {
    Level& level = levels_[j];
    level.push(v);
    if (!level.has_pending) {
      level.pending = v;
      level.has_pending = true;
      return;
    }
    // A pair complete: its average is the next level's sample.
    v = 0.5 * (level.pending + v);
    level.has_pending = false;
    if (j + 1 == levels_.size()) levels_.emplace_back(exact_octaves_, exact_octaves_, false);
  }
}

void AllanAccumulator::push(const Eigen::Ref<const Eigen::VectorXd>& y) {
  for (Eigen::Index k = 0; k < y.size(); ++k) push(y(k));
}

std::int64_t AllanAccumulator::samples() const { return levels_.front().count; }

std::size_t AllanAccumulator::memory_bytes() const {
  std::size_t bytes = 0;
  for (const Level& l : levels_) {
    bytes += l.ring.size() * sizeof(double);
    for (const auto& r : l.d_ring) bytes += r.size() * sizeof(double);
  }
  return bytes;
}

std::vector<AllanPoint> AllanAccumulator::points() const {
  std::vector<AllanPoint> out;
  for (std::size_t j = 0; j < levels_.size(); ++j) {
    const Level& level = levels_[j];
    const std::int64_t stride = std::int64_t{1} << j;
    for (int k = level.first_octave; k <= level.last_octave; ++k) {
      const auto o = static_cast<std::size_t>(k - level.first_octave);
      if (level.terms[o] == 0) continue;
      const std::int64_t m_level = std::int64_t{1} << k;
      AllanPoint p;
      p.m = m_level * stride;
      p.tau = static_cast<double>(p.m) * tau0_;
      const auto mm = static_cast<double>(m_level);
      p.avar = level.sum_sq[o] / (2.0 * mm * mm * static_cast<double>(level.terms[o]));
      p.terms = level.terms[o];
      if (level.modified && level.mod_terms[o] > 0) {
        p.mvar = level.mod_sum_sq[o] / (2.0 * mm * mm * mm * mm * static_cast<double>(level.mod_terms[o]));
        p.mod_terms = level.mod_terms[o];
      }
      p.stride = stride;
      p.m_at_stride = mm;
      p.phase_points = {static_cast<double>(level.count + 1)};
      out.push_back(p);
    }
  }
  std::sort(out.begin(), out.end(), [](const AllanPoint& a, const AllanPoint& b) { return a.tau < b.tau; });
  return out;
}

std::vector<AllanPoint> pool(const std::vector<std::vector<AllanPoint>>& stretches) {
  std::vector<AllanPoint> out;
  for (const auto& points : stretches) {
    for (const AllanPoint& p : points) {
      auto it = std::find_if(out.begin(), out.end(), [&](const AllanPoint& q) { return q.m == p.m; });
      if (it == out.end()) {
        out.push_back(p);
        continue;
      }
      const double n = static_cast<double>(it->terms + p.terms);
      it->avar = (it->avar * static_cast<double>(it->terms) + p.avar * static_cast<double>(p.terms)) / n;
      it->terms += p.terms;
      if (std::isfinite(p.mvar) && std::isfinite(it->mvar)) {
        const double nm = static_cast<double>(it->mod_terms + p.mod_terms);
        it->mvar = (it->mvar * static_cast<double>(it->mod_terms) + p.mvar * static_cast<double>(p.mod_terms)) / nm;
        it->mod_terms += p.mod_terms;
      }
      it->phase_points.insert(it->phase_points.end(), p.phase_points.begin(), p.phase_points.end());
    }
  }
  std::sort(out.begin(), out.end(), [](const AllanPoint& a, const AllanPoint& b) { return a.tau < b.tau; });
  return out;
}

double allan_variance_direct(const Eigen::Ref<const Eigen::VectorXd>& y, std::int64_t m) {
  const std::int64_t n = y.size();
  if (n < 2 * m || m < 1) return std::nan("");
  double sum = 0.0;
  for (std::int64_t i = 0; i + 2 * m <= n; ++i) {
    double a = 0.0, b = 0.0;
    for (std::int64_t j = 0; j < m; ++j) {
      a += y(i + j);
      b += y(i + m + j);
    }
    sum += (b - a) * (b - a);
  }
  const auto mm = static_cast<double>(m);
  return sum / (2.0 * mm * mm * static_cast<double>(n - 2 * m + 1));
}

double modified_allan_variance_direct(const Eigen::Ref<const Eigen::VectorXd>& y, std::int64_t m) {
  const std::int64_t n = y.size();
  if (n < 3 * m - 1 || m < 1) return std::nan("");
  // Second differences d_i over windows [i, i + 2m), then sums of m consecutive ones.
  std::vector<double> d;
  for (std::int64_t i = 0; i + 2 * m <= n; ++i) {
    double a = 0.0, b = 0.0;
    for (std::int64_t j = 0; j < m; ++j) {
      a += y(i + j);
      b += y(i + m + j);
    }
    d.push_back(b - a);
  }
  double sum = 0.0;
  std::int64_t terms = 0;
  for (std::size_t i = 0; i + static_cast<std::size_t>(m) <= d.size(); ++i) {
    double s = 0.0;
    for (std::int64_t j = 0; j < m; ++j) s += d[i + static_cast<std::size_t>(j)];
    sum += s * s;
    ++terms;
  }
  const auto mm = static_cast<double>(m);
  return sum / (2.0 * mm * mm * mm * mm * static_cast<double>(terms));
}

double point_edf(const AllanPoint& p, int alpha) {
  double edf = 0.0;
  for (double n : p.phase_points)
    if (n > 2.0 * p.m_at_stride + 1.0) edf += std::max(overlapping_edf(n, p.m_at_stride, alpha), 1.0);
  return std::max(edf, 1.0);
}

std::pair<double, double> variance_interval(double estimate, double edf, double level) {
  const boost::math::chi_squared chi(std::max(edf, 1e-3));
  const double tail = 0.5 * (1.0 - level);
  return {edf * estimate / boost::math::quantile(chi, 1.0 - tail), edf * estimate / boost::math::quantile(chi, tail)};
}

double overlapping_edf(double n, double m, int alpha) {
  switch (alpha) {
    case 2: return (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m));
    case 1: return std::exp(std::sqrt(std::log((n - 1.0) / (2.0 * m)) * std::log((2.0 * m + 1.0) * (n - 1.0) / 4.0)));
    case 0: return (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0);
    case -1: return m < 1.5 ? 2.0 * (n - 2.0) / (2.3 * n - 4.9) : 5.0 * n * n / (4.0 * m * (n + 3.0 * m));
    default:
      return (n - 2.0) / (m * (n - 3.0) * (n - 3.0)) * ((n - 1.0) * (n - 1.0) - 3.0 * m * (n - 1.0) + 4.0 * m * m);
  }
}

}  // namespace inertia::noise
