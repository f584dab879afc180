#include "analyzer/noise/coloured_noise.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "analyzer/noise/allan.hpp"
#include "analyzer/noise/fourier.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "common/parallel.hpp"

namespace inertia::noise {
namespace {

Eigen::Index padded_length(Eigen::Index rows) {
  Eigen::Index length = 2;
  while (length < 2 * rows) length *= 2;
  return length;
}

/// The least even length >= `needed` of the form 2^j, 9 2^j, 5 2^j or 3 2^j: at most a third
/// above it (a power of two alone: up to twice). FFTW's estimated plans for these factors run
/// about as fast per point as a power of two's; other small factors (7, 11, 15) gave plans several
/// times slower per point beyond the cache (docs/validation.md).
Eigen::Index fast_length(Eigen::Index needed) {
  needed = std::max<Eigen::Index>(needed, 2);
  Eigen::Index best = 2;
  while (best < needed) best *= 2;
  for (const Eigen::Index factor : {9, 5, 3})
    for (Eigen::Index length = 2 * factor; length < best; length *= 2)
      if (length >= needed) {
        best = length;
        break;
      }
  return best;
}

/// `out`'s autocovariance, lags 0 .. rows-1, from its density on the bins, by one inverse
/// transform on `fourier` (of out.length).
void set_autocovariance(SegmentSpectrum& out, RealFourier& fourier) {
  fourier.spectrum() = out.density.cast<std::complex<double>>();
  fourier.inverse();   // (1/L) sum_k S_k e^{2 pi i k tau / L}
  out.autocovariance = fourier.samples().head(out.rows);
}

/// The circulant that R x is taken through, from `out`'s autocovariance.
void set_circulant(SegmentSpectrum& out) {
  // R is the Toeplitz matrix of these lags. A circulant of any length M >= 2n - 1 whose first
  // column is r(0 .. n-1), zeros, r(n-1 .. 1) holds R as its leading n x n block, so R x is the
  // first n samples of that circulant times the zero-padded x, whatever M: the products take the
  // shortest fast M rather than the density's power of two L, which sets the lags' aliasing.
  const Eigen::Index n = out.rows;
  out.circulant_length = fast_length(2 * n - 1);
  RealFourier embedding(out.circulant_length);
  auto c = embedding.samples();
  c.setZero();
  c.head(n) = out.autocovariance;
  for (Eigen::Index tau = 1; tau < n; ++tau) c(out.circulant_length - tau) = out.autocovariance(tau);
  embedding.forward();
  out.circulant = embedding.spectrum().real();
}

}  // namespace

SegmentSpectrum spectrum_of(Eigen::Index rows, const std::function<double(double)>& density) {
  if (rows < 1) throw std::invalid_argument("spectrum_of: no rows");
  SegmentSpectrum out;
  out.rows = rows;
  out.length = padded_length(rows);
  const Eigen::Index half = out.length / 2;
  out.density.resize(half + 1);
  for (Eigen::Index k = 0; k <= half; ++k) out.density(k) = density(static_cast<double>(k) / static_cast<double>(out.length));
  // A flicker or random-walk spectrum is infinite at DC: there it is taken at half a bin, and what
  // lies below the record's lowest frequency is the offsets between cases (cluster_offsets).
  if (!std::isfinite(out.density(0))) out.density(0) = density(0.5 / static_cast<double>(out.length));
  {
    RealFourier fourier(out.length);
    set_autocovariance(out, fourier);
  }
  set_circulant(out);
  return out;
}

FittedDensity fitted_density(const Eigen::Ref<const Eigen::VectorXd>& residual, const std::function<double(double)>& below_record) {
  const Eigen::Index n = residual.size();
  std::optional<NoiseFit> fit;
  if (n >= 64) {
    AllanAccumulator allan(1.0);
    allan.push(residual);
    NoiseFitOptions options;
    // A rate ramp is a drift, not a stationary noise: its spectrum (1/f^3) would put an unbounded
    // variance on the DC bin. The offsets between cases carry what drift there is.
    options.terms[static_cast<std::size_t>(NoiseTerm::R)] = false;
    try {
      fit = fit_noise(allan.points(), options);
    } catch (const std::invalid_argument&) {
      fit.reset();   // too few octaves: white below
    }
  }
  FittedDensity out;
  const double lowest = 1.0 / static_cast<double>(std::max<Eigen::Index>(n, 1));
  if (fit) {
    // Below the record's lowest frequency (one cycle in n samples) the residual cannot tell a
    // flicker or random walk from an offset of the whole stretch: there only the white part, or
    // what `below_record` knows; the offsets between stretches beyond that are the cluster
    // offsets' (ident::cluster_offsets).
    NoiseFit white = *fit;
    for (const NoiseTerm t : {NoiseTerm::B, NoiseTerm::K, NoiseTerm::R}) white.terms[static_cast<std::size_t>(t)].value = 0.0;
    out.density = [full = *fit, white, lowest, below_record](double f) {
      if (f >= lowest) return 0.5 * model_psd(full, f, 1.0);
      const double floor = 0.5 * model_psd(white, f, 1.0);
      return below_record ? std::max(floor, below_record(f)) : floor;
    };
    std::string terms;
    for (int t = 0; t < kNoiseTerms; ++t) {
      const NoiseCoefficient& c = fit->terms[static_cast<std::size_t>(t)];
      if (c.value > 0.0) terms += fmt::format("{}{} {:.3g}", terms.empty() ? "" : ", ", noise_term_name(NoiseTerm(t)), c.value);
    }
    out.model = terms.empty() ? std::string("no noise") : terms;
    out.fit = std::move(fit);
  } else {
    const double variance = n > 0 ? residual.squaredNorm() / static_cast<double>(n) : 0.0;
    out.density = [variance, lowest, below_record](double f) {
      return f < lowest && below_record ? std::max(variance, below_record(f)) : variance;
    };
    out.model = fmt::format("white {:.3g} (too short for the Allan fit)", variance);
  }
  return out;
}

SegmentSpectrum fitted_spectrum(const Eigen::Ref<const Eigen::VectorXd>& residual, const std::function<double(double)>& below_record) {
  FittedDensity fitted = fitted_density(residual, below_record);
  SegmentSpectrum out = spectrum_of(std::max<Eigen::Index>(residual.size(), 1), fitted.density);
  out.fit = std::move(fitted.fit);
  out.model = std::move(fitted.model);
  return out;
}

SegmentSpectrum fitted_spectrum_through_ar(const Eigen::Ref<const Eigen::VectorXd>& innovation, const Eigen::VectorXd& ar,
                                           Eigen::Index rows, const std::function<double(double)>& below_record) {
  if (rows < innovation.size()) throw std::invalid_argument("fitted_spectrum_through_ar: fewer rows than the innovation's");
  FittedDensity fitted = fitted_density(innovation, below_record);
  SegmentSpectrum out;
  out.rows = std::max<Eigen::Index>(rows, 1);
  out.length = padded_length(out.rows);
  const auto length = static_cast<double>(out.length);
  {
    // A(e^{2 pi i f}) = 1 - sum a_j e^{-2 pi i f j} on every bin f = k / L at once: the DFT of A's
    // coefficients (folded modulo L, which the bins cannot tell apart), one transform instead of
    // an order's worth of sines per bin.
    RealFourier fourier(out.length);
    fourier.samples().setZero();
    fourier.samples()(0) = 1.0;
    for (Eigen::Index j = 1; j <= ar.size(); ++j) fourier.samples()(j % out.length) -= ar(j - 1);
    fourier.forward();
    const Eigen::Index half = out.length / 2;
    out.density.resize(half + 1);
    for (Eigen::Index k = 0; k <= half; ++k) out.density(k) = fitted.density(static_cast<double>(k) / length) / std::norm(fourier.spectrum()(k));
    if (!std::isfinite(out.density(0))) {   // as spectrum_of: half a bin
      const double f = 0.5 / length;
      std::complex<double> a = 1.0;
      for (Eigen::Index j = 1; j <= ar.size(); ++j) a -= ar(j - 1) * std::polar(1.0, -2.0 * std::numbers::pi * f * static_cast<double>(j));
      out.density(0) = fitted.density(f) / std::norm(a);
    }
    set_autocovariance(out, fourier);
  }
  set_circulant(out);
  out.fit = std::move(fitted.fit);
  out.model = fmt::format("{} through AR({})", fitted.model, ar.size());
  return out;
}

namespace {

/// R x of one column through `fourier` (of the spectrum's circulant_length): the circulant's
/// leading n x n block is the Toeplitz R, so the first n samples of the circular convolution of
/// the zero-padded column are R x.
/// R x is left in fourier.samples().head(n).
template <class Column>
void covariance_column(RealFourier& fourier, const SegmentSpectrum& spectrum, const Column& column) {
  const Eigen::Index n = column.size();
  fourier.samples().head(n) = column;
  fourier.samples().tail(spectrum.circulant_length - n).setZero();   // the inverse of the column before filled them
  fourier.forward();
  fourier.spectrum().array() *= spectrum.circulant.array();
  fourier.inverse();
}

}  // namespace

Eigen::MatrixXd quadratic_form(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x) {
  std::vector<Eigen::Index> all(static_cast<std::size_t>(x.cols()));
  std::iota(all.begin(), all.end(), Eigen::Index{0});
  return quadratic_form(spectrum, x, all);
}

Eigen::MatrixXd quadratic_form(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x,
                               std::span<const Eigen::Index> columns) {
  if (x.rows() != spectrum.rows) throw std::invalid_argument("quadratic_form: rows differ from the spectrum's");
  for (const Eigen::Index c : columns)
    if (c < 0 || c >= x.cols()) throw std::invalid_argument("quadratic_form: a column beyond x's");
  // x_S'(R x_S) a column of S at a time: R x_j in the transform's own buffer, then x_i'(R x_j)
  // for the columns i of S alone (x in place). A thread holds its transform's buffers and nothing
  // of the rows' size besides.
  const auto p = static_cast<Eigen::Index>(columns.size());
  const Eigen::Index n = x.rows();
  Eigen::MatrixXd out(p, p);
  // The columns split over parallel::jobs() threads, each with its own transform (its plan cache);
  // a column's arithmetic does not depend on its thread.
#ifdef _OPENMP
#pragma omp parallel num_threads(parallel::threads_for(p))
#endif
  {
    RealFourier fourier(spectrum.circulant_length);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
    for (Eigen::Index j = 0; j < p; ++j) {
      covariance_column(fourier, spectrum, x.col(columns[std::size_t(j)]));
      const auto r_xj = fourier.samples().head(n);
      for (Eigen::Index i = 0; i < p; ++i) out(i, j) = x.col(columns[std::size_t(i)]).dot(r_xj);
    }
  }
  return 0.5 * (out + out.transpose());
}

Eigen::MatrixXd covariance_times(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x) {
  if (x.rows() != spectrum.rows) throw std::invalid_argument("covariance_times: rows differ from the spectrum's");
  Eigen::MatrixXd out(x.rows(), x.cols());
  // The columns split over threads as in quadratic_form.
#ifdef _OPENMP
#pragma omp parallel num_threads(parallel::threads_for(x.cols()))
#endif
  {
    RealFourier fourier(spectrum.circulant_length);
#ifdef _OPENMP
#pragma omp for schedule(static)
#endif
    for (Eigen::Index j = 0; j < x.cols(); ++j) {
      covariance_column(fourier, spectrum, x.col(j));
      out.col(j) = fourier.samples().head(x.rows());
    }
  }
  return out;
}

namespace {

/// Sums of r(i - j) over blocks of rows from the autocovariance's running sums, in extended
/// precision: a block's sum is a difference of second running sums that grow with n^2.
///   P1(k) = sum_{t = -(n-1)}^{k-1} r(t),  P2(k) = sum_{u = -(n-1)}^{k-1} P1(u),
///   sum_{j = b0}^{b1-1} r(i - j) = P1(i - b0 + 1) - P1(i - b1 + 1),
///   sum_{i = a0}^{a1-1} sum_{j = b0}^{b1-1} r(i - j) = P2(a1 - b0 + 1) - P2(a0 - b0 + 1) - P2(a1 - b1 + 1) + P2(a0 - b1 + 1).
class LagSums {
 public:
  /// For row(): the first running sums at every lag (16 B a lag).
  explicit LagSums(const Eigen::VectorXd& autocovariance) : n_(autocovariance.size()) {
    first_.assign(static_cast<std::size_t>(2 * n_), 0.0L);
    for (Eigen::Index i = 0; i + 1 < 2 * n_; ++i) first_[std::size_t(i + 1)] = first_[std::size_t(i)] + lag(autocovariance, i);
  }

  /// For block(): the second running sums at the points `second_at` alone (each a k of P2(k)),
  /// taken in one pass of both running sums, the same additions in the same order: nothing of the
  /// stretch's length is held.
  LagSums(const Eigen::VectorXd& autocovariance, std::vector<Eigen::Index> second_at) : n_(autocovariance.size()) {
    std::sort(second_at.begin(), second_at.end());
    second_at.erase(std::unique(second_at.begin(), second_at.end()), second_at.end());
    for (const Eigen::Index k : second_at)
      if (k + n_ - 1 < 0 || k + n_ - 1 > 2 * n_) throw std::invalid_argument("LagSums: a point beyond the stretch's lags");
    second_points_ = std::move(second_at);
    second_values_.resize(second_points_.size());
    long double first = 0.0L, second = 0.0L;   // P1 and P2 at index i = k + n - 1
    std::size_t next = 0;
    for (Eigen::Index i = 0; i <= 2 * n_ && next < second_points_.size(); ++i) {
      while (next < second_points_.size() && second_points_[next] + n_ - 1 == i) second_values_[next++] = second;
      second += first;
      if (i + 1 < 2 * n_) first += lag(autocovariance, i);
    }
  }

  /// sum over j in [b0, b1) of r(i - j), rows i, b0, b1 of the stretch. The first constructor only.
  [[nodiscard]] long double row(Eigen::Index i, Eigen::Index b0, Eigen::Index b1) const { return p1(i - b0 + 1) - p1(i - b1 + 1); }

  /// sum over i in [a0, a1), j in [b0, b1) of r(i - j). The second constructor only, with the four
  /// points block_points gives among its points.
  [[nodiscard]] long double block(Eigen::Index a0, Eigen::Index a1, Eigen::Index b0, Eigen::Index b1) const {
    return (p2(a1 - b0 + 1) - p2(a0 - b0 + 1)) - (p2(a1 - b1 + 1) - p2(a0 - b1 + 1));
  }
  /// The points of P2 that block(a0, a1, b0, b1) reads.
  static std::array<Eigen::Index, 4> block_points(Eigen::Index a0, Eigen::Index a1, Eigen::Index b0, Eigen::Index b1) {
    return {a1 - b0 + 1, a0 - b0 + 1, a1 - b1 + 1, a0 - b1 + 1};
  }

 private:
  /// r at the lag of running index i, |i - (n - 1)|, widened.
  [[nodiscard]] long double lag(const Eigen::VectorXd& autocovariance, Eigen::Index i) const {
    return static_cast<long double>(autocovariance(std::abs(i - (n_ - 1))));
  }
  [[nodiscard]] long double p1(Eigen::Index k) const { return first_[std::size_t(k + n_ - 1)]; }
  [[nodiscard]] long double p2(Eigen::Index k) const {
    const auto at = std::lower_bound(second_points_.begin(), second_points_.end(), k);
    if (at == second_points_.end() || *at != k) throw std::logic_error("LagSums: P2 read at a point not taken");
    return second_values_[std::size_t(at - second_points_.begin())];
  }

  Eigen::Index n_;
  std::vector<long double> first_;
  std::vector<Eigen::Index> second_points_;
  std::vector<long double> second_values_;
};

/// Each group's maximal runs of consecutive rows, [begin, end).
std::vector<std::vector<std::pair<Eigen::Index, Eigen::Index>>> group_runs(const RowGroups& rows) {
  std::vector<std::vector<std::pair<Eigen::Index, Eigen::Index>>> runs(static_cast<std::size_t>(rows.groups));
  const auto n = static_cast<Eigen::Index>(rows.group.size());
  for (Eigen::Index k = 0; k < n;) {
    const Eigen::Index g = rows.group[std::size_t(k)];
    if (g < 0 || g >= rows.groups) throw std::invalid_argument("group_runs: a row's group is out of range");
    Eigen::Index end = k + 1;
    while (end < n && rows.group[std::size_t(end)] == g) ++end;
    runs[std::size_t(g)].emplace_back(k, end);
    k = end;
  }
  return runs;
}

}  // namespace

Eigen::MatrixXd group_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows) {
  if (static_cast<Eigen::Index>(rows.group.size()) != spectrum.rows) throw std::invalid_argument("group_covariance: rows differ from the spectrum's");
  const auto runs = group_runs(rows);
  std::vector<Eigen::Index> points;
  for (Eigen::Index g = 0; g < rows.groups; ++g)
    for (Eigen::Index h = 0; h <= g; ++h)
      for (const auto& [a0, a1] : runs[std::size_t(g)])
        for (const auto& [b0, b1] : runs[std::size_t(h)])
          for (const Eigen::Index k : LagSums::block_points(a0, a1, b0, b1)) points.push_back(k);
  const LagSums sums(spectrum.autocovariance, std::move(points));
  Eigen::MatrixXd out(rows.groups, rows.groups);
  for (Eigen::Index g = 0; g < rows.groups; ++g) {
    for (Eigen::Index h = 0; h <= g; ++h) {
      long double s = 0.0L;
      for (const auto& [a0, a1] : runs[std::size_t(g)])
        for (const auto& [b0, b1] : runs[std::size_t(h)]) s += sums.block(a0, a1, b0, b1);
      out(g, h) = out(h, g) = static_cast<double>(s);
    }
  }
  return out;
}

Eigen::MatrixXd group_cross_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows,
                                       const Eigen::Ref<const Eigen::MatrixXd>& x) {
  return group_cross_covariance(spectrum, rows, x, Eigen::MatrixXd(x.rows(), 0));
}

Eigen::MatrixXd group_cross_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows,
                                       const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& w) {
  if (static_cast<Eigen::Index>(rows.group.size()) != spectrum.rows || x.rows() != spectrum.rows || w.rows() != spectrum.rows)
    throw std::invalid_argument("group_cross_covariance: rows differ from the spectrum's");
  const LagSums sums(spectrum.autocovariance);
  const auto runs = group_runs(rows);
  Eigen::MatrixXd out(x.cols() + w.cols(), rows.groups);
  // The groups split over parallel::jobs() threads; a group's column does not depend on its thread.
#ifdef _OPENMP
#pragma omp parallel num_threads(parallel::threads_for(rows.groups))
#endif
  {
    Eigen::VectorXd rz(x.rows());   // R z_h
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
    for (Eigen::Index h = 0; h < rows.groups; ++h) {
      for (Eigen::Index i = 0; i < x.rows(); ++i) {
        long double s = 0.0L;
        for (const auto& [b0, b1] : runs[std::size_t(h)]) s += sums.row(i, b0, b1);
        rz(i) = static_cast<double>(s);
      }
      out.col(h).head(x.cols()).noalias() = x.transpose() * rz;
      if (w.cols() > 0) out.col(h).tail(w.cols()).noalias() = w.transpose() * rz;
    }
  }
  return out;
}

}  // namespace inertia::noise
