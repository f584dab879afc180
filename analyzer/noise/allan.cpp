#include "analyzer/noise/allan.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <boost/math/distributions/chi_squared.hpp>

namespace inertia::noise {

/// One octave level: its samples (raw less the record's first, or 2^j-averages of those) and the
/// sums of its octaves.
struct AllanAccumulator::Level {
  struct Octave {
    double sum_sq = 0.0;        // sum of d^2, d the second difference of the phase at lag m
    std::int64_t terms = 0;
    double mod_sum_sq = 0.0;    // sum of (sum of m consecutive d)^2
    std::int64_t mod_terms = 0;
  };

  int first_octave = 0, last_octave = 0;   // octaves k (m = 2^k of this level's samples)
  bool modified = false;
  Eigen::Index history = 0;          // samples kept for the next block (its differences reach back)
  // [0, fill): `history` older samples, then the block. Aligned as Eigen aligns its own arrays, so
  // that a reduction over it (the centre) adds in the same order whatever the heap hands out.
  std::vector<double, Eigen::aligned_allocator<double>> samples;
  Eigen::Index fill = 0, fresh = 0;  // [fresh, fill): not yet in the sums
  std::int64_t count = 0;            // samples received
  std::optional<double> centre;      // taken off in the phase: the previous block's mean
  std::vector<Octave> octaves;

  // History: 2m samples for d, 3m - 1 for the modified variance's sums of m of them. Each block
  // integrates the phase over the history again, so the block is at least as long: 2 additions a
  // sample at a decimated level (32 kB with K = 10), 7/4 at level 0, which has every sample and
  // every octave; at least 1024, so that the per-block passes are long.
  Level(int first, int last, bool with_modified)
      : first_octave(first), last_octave(last), modified(with_modified),
        history((with_modified ? 3 : 2) * (Eigen::Index{1} << last)),
        samples(static_cast<std::size_t>(history + std::max(Eigen::Index{1024}, Eigen::Index{with_modified ? 4 : 2} << last))),
        octaves(static_cast<std::size_t>(last - first + 1)) {}

  [[nodiscard]] Eigen::Index capacity() const { return static_cast<Eigen::Index>(samples.size()); }
  [[nodiscard]] Eigen::Index room() const { return capacity() - fill; }
  [[nodiscard]] double* unfilled() { return samples.data() + fill; }

  /// n samples written at unfilled(): true when the block is full (then process it).
  bool added(Eigen::Index n) {
    fill += n;
    count += n;
    return fill == capacity();
  }

  /// The differences completed by samples [fresh, fill) into the octaves' sums.
  void accumulate(Scratch& scratch);

  /// The block done: a full one gives way to the next, keeping the history.
  void retire() {
    fresh = fill;
    if (fill < capacity()) return;
    std::copy(samples.end() - history, samples.end(), samples.begin());
    fill = fresh = history;
  }
};

void AllanAccumulator::Level::accumulate(Scratch& scratch) {
  // The phase x(p) (after p samples), integrated afresh over the whole buffer about a centre
  // near the samples' mean: its size, and so the rounding of every difference of it, is that of
  // the noise over one buffer, whatever the record's length or the output's level.
  const Eigen::Index n = fill;
  const Eigen::Map<const Eigen::ArrayXd> y(samples.data(), n);
  if (!centre) centre = y.mean();
  Eigen::ArrayXd& x = scratch.phase;
  x(0) = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) x(i + 1) = x(i) + (y(i) - *centre);
  *centre += x(n) / static_cast<double>(n);

  // z(p) - 2 z(p - m) + z(p - 2m) for p in [begin, n]: the newer lag-m difference less the older.
  const auto second_difference = [n](const Eigen::ArrayXd& z, Eigen::Index begin, Eigen::Index m) {
    const Eigen::Index len = n + 1 - begin;
    return (z.segment(begin, len) - z.segment(begin - m, len)) - (z.segment(begin - m, len) - z.segment(begin - 2 * m, len));
  };
  // w(p) = x(p - m + 1) + .. + x(p), for p >= m - 1: the sum of m consecutive d is its second
  // difference. Octave m's is two of octave m/2's, so it costs one addition a point and rounds
  // like a pairwise sum.
  const Eigen::ArrayXd* w = &x;
  for (int k = first_octave; k <= last_octave; ++k) {
    const Eigen::Index m = Eigen::Index{1} << k;
    const Eigen::Index begin = std::max(fresh + 1, 2 * m);   // d needs 2m samples of the record
    if (begin > n) break;
    Octave& octave = octaves[static_cast<std::size_t>(k - first_octave)];
    octave.sum_sq += second_difference(x, begin, m).square().sum();
    octave.terms += n + 1 - begin;
    if (!modified) continue;

    if (m > 1) {
      Eigen::ArrayXd& wider = w == &scratch.sums ? scratch.wider_sums : scratch.sums;
      const Eigen::Index len = n + 2 - m;
      wider.segment(m - 1, len) = w->segment(m - 1, len) + w->segment(m / 2 - 1, len);
      w = &wider;
    }
    const Eigen::Index mod_begin = std::max(fresh + 1, 3 * m - 1);   // m of d: 3m - 1 samples
    if (mod_begin > n) continue;
    octave.mod_sum_sq += second_difference(*w, mod_begin, m).square().sum();
    octave.mod_terms += n + 1 - mod_begin;
  }
}

AllanAccumulator::AllanAccumulator(double tau0_s, int exact_octaves) : tau0_(tau0_s), exact_octaves_(exact_octaves) {
  if (!(tau0_s > 0.0) || !std::isfinite(tau0_s)) throw std::invalid_argument("AllanAccumulator: tau0 must be > 0");
  if (exact_octaves < 1 || exact_octaves > 20) throw std::invalid_argument("AllanAccumulator: exact_octaves in 1..20");
  levels_.emplace_back(0, exact_octaves, true);
  const Eigen::Index longest = levels_.front().capacity() + 1;   // level 0's buffer is the longest
  scratch_.phase.resize(longest);
  scratch_.sums.resize(longest);
  scratch_.wider_sums.resize(longest);
}

AllanAccumulator::~AllanAccumulator() = default;
AllanAccumulator::AllanAccumulator(const AllanAccumulator&) = default;
AllanAccumulator::AllanAccumulator(AllanAccumulator&&) noexcept = default;
AllanAccumulator& AllanAccumulator::operator=(AllanAccumulator&&) noexcept = default;

void AllanAccumulator::push(double y) {
  if (!offset_) offset_ = y;
  Level& level = levels_.front();
  *level.unfilled() = y - *offset_;
  if (level.added(1)) process(0);
}

void AllanAccumulator::push(const Eigen::Ref<const Eigen::VectorXd>& y) {
  if (y.size() > 0 && !offset_) offset_ = y(0);
  for (Eigen::Index k = 0; k < y.size();) {
    Level& level = levels_.front();
    const Eigen::Index n = std::min(y.size() - k, level.room());
    Eigen::Map<Eigen::ArrayXd>(level.unfilled(), n) = y.segment(k, n).array() - *offset_;
    k += n;
    if (level.added(n)) process(0);
  }
}

void AllanAccumulator::process(std::size_t j) {
  levels_[j].accumulate(scratch_);
  // The next level's samples: the averages of the pairs whose second sample is new (the first is
  // in the history when the pair straddles two blocks). Processing the next level can add a level
  // to levels_ and move them all, so no reference is held across it.
  const Eigen::Index end = levels_[j].fill;
  Eigen::Index i = levels_[j].fresh;
  if (((levels_[j].count - end + i) & 1) == 0) ++i;   // i: a pair's second (odd in the record)
  while (i < end) {
    if (j + 1 == levels_.size()) levels_.emplace_back(exact_octaves_, exact_octaves_, false);
    Level& next = levels_[j + 1];
    const double* pair = levels_[j].samples.data() + i - 1;
    const Eigen::Index n = std::min((end - i + 1) / 2, next.room());
    double* out = next.unfilled();
    for (Eigen::Index k = 0; k < n; ++k) out[k] = 0.5 * (pair[2 * k] + pair[2 * k + 1]);
    i += 2 * n;
    if (next.added(n)) process(j + 1);
  }
  levels_[j].retire();
}

void AllanAccumulator::flush() {
  for (std::size_t j = 0; j < levels_.size(); ++j)
    if (levels_[j].fresh < levels_[j].fill) process(j);
}

std::int64_t AllanAccumulator::samples() const { return levels_.front().count; }

std::size_t AllanAccumulator::memory_bytes() const {
  std::size_t doubles = 0;
  for (const Level& l : levels_) doubles += l.samples.size();
  doubles += static_cast<std::size_t>(scratch_.phase.size() + scratch_.sums.size() + scratch_.wider_sums.size());
  return doubles * sizeof(double);
}

std::vector<AllanPoint> AllanAccumulator::points() const {
  if (std::any_of(levels_.begin(), levels_.end(), [](const Level& l) { return l.fresh < l.fill; })) {
    // A block part-filled: its differences summed on a copy, so that pushing on goes on as if
    // nothing was asked.
    AllanAccumulator all(*this);
    all.flush();
    return all.points();
  }
  std::vector<AllanPoint> out;
  for (std::size_t j = 0; j < levels_.size(); ++j) {
    const Level& level = levels_[j];
    const std::int64_t stride = std::int64_t{1} << j;
    for (int k = level.first_octave; k <= level.last_octave; ++k) {
      const Level::Octave& octave = level.octaves[static_cast<std::size_t>(k - level.first_octave)];
      if (octave.terms == 0) continue;
      const std::int64_t m_level = std::int64_t{1} << k;
      AllanPoint p;
      p.m = m_level * stride;
      p.tau = static_cast<double>(p.m) * tau0_;
      const auto mm = static_cast<double>(m_level);
      p.avar = octave.sum_sq / (2.0 * mm * mm * static_cast<double>(octave.terms));
      p.terms = octave.terms;
      if (octave.mod_terms > 0) {
        p.mvar = octave.mod_sum_sq / (2.0 * mm * mm * mm * mm * static_cast<double>(octave.mod_terms));
        p.mod_terms = octave.mod_terms;
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
