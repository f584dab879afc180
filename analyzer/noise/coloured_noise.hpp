#pragma once
// The noise an AR prewhitening leaves behind, and what it does to a least-squares estimate.
//
// The identification whitens each case with an AR model chosen by AIC. At a bench's sample rates
// that model follows the noise down to a few tens of Hz; below, 1/f (flicker) and random-walk
// noise keep rising while the AR model's spectrum is flat. The whitened residual is then white
// at high frequency and coloured at low frequency, and the classical covariance sigma^2 (X'X)^-1
// weighs the low-frequency information (gravity in a pose, the table's slow rotation, the shaker's
// static orientation) as if the noise there were as quiet as at high frequency, and so is
// several times optimistic (plan-check --seeds measures it; docs/validation.md, 'Evidence behind
// choices in the code').
//
// Here the whitened residual of each case gets a noise model of its own, the sensor-noise terms
// of noise_fit.hpp (Q, N, B, K, R: white, flicker, random walk ..) fitted to its Allan variance,
// whose spectrum S(f) gives the covariance R of the residual; the estimate's covariance is then
// the sandwich (X'X)^-1 X'RX (X'X)^-1 (ident::ColouredNoise). R's lags r(0 .. n-1) are the inverse
// DFT of S on the bins of a power of two L >= 2n (the lags of the periodic noise of period L, which
// equal the stationary noise's wherever its correlation has decayed within L - n lags), and R x is
// taken through a circulant of the shortest fast length M >= 2n - 1 that embeds that Toeplitz R.
// Below the record's lowest frequency (one cycle per record), where a flicker or random-walk
// spectrum rises without bound, a fitted spectrum keeps its white part, or what the caller knows
// of the noise there from elsewhere (the plan's static stretches: StaticNoiseLaw in
// procedure/whitened_problem.hpp); what a stretch's offset holds beyond that is the offsets between
// stretches' business (ident::cluster_offsets), measured from their scatter.
#include <Eigen/Dense>

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "analyzer/noise/noise_fit.hpp"

namespace inertia::noise {

/// One contiguous stretch's stationary noise, on the bins of the DFT of length `length`.
struct SegmentSpectrum {
  Eigen::Index rows = 0;              // n
  Eigen::Index length = 0;            // L: a power of two >= 2n
  Eigen::VectorXd density;            // two-sided S(f_k), k = 0 .. L/2 (the rest by symmetry), per sample
  Eigen::VectorXd autocovariance;     // r(tau), tau = 0 .. n-1, of the same spectrum
  Eigen::Index circulant_length = 0;  // M >= 2n - 1: the length R x is transformed at
  Eigen::VectorXd circulant;          // the eigenvalues, bins 0 .. M/2, of the circulant embedding R
  std::optional<NoiseFit> fit;        // the terms fitted (tau0 = one sample); none: white (too short to fit)
  std::string model;                  // one line: which terms, for the report
};

/// A fitted noise's two-sided density per sample at f cycles per sample (f in 0..0.5), and what
/// it is: the terms of `residual`'s Allan variance (tau0 = 1 sample; no rate ramp, a drift), or
/// white with its mean square when the stretch is too short for the fit. Below one cycle per
/// record the white part, or `below_record(f)` where that is larger.
struct FittedDensity {
  std::function<double(double)> density;
  std::optional<NoiseFit> fit;
  std::string model;
};
FittedDensity fitted_density(const Eigen::Ref<const Eigen::VectorXd>& residual,
                             const std::function<double(double)>& below_record = {});

/// The spectrum of `residual`'s noise: its Allan variance's terms (fit_noise, tau0 = 1 sample), or
/// white with its mean square when the stretch is too short for the fit. Below one cycle per
/// record the white part, or `below_record(f)` (f in cycles per sample) where that is larger: what
/// is known of the noise there from elsewhere (the plan's static stretches).
SegmentSpectrum fitted_spectrum(const Eigen::Ref<const Eigen::VectorXd>& residual,
                                const std::function<double(double)>& below_record = {});

/// The spectrum on `rows` rows of a noise that the AR model A(q) = 1 - sum a_j q^-j (`ar`) turns
/// into `innovation` (the rows filtered by it, fewer by its order): `innovation`'s fitted spectrum
/// (as fitted_spectrum, `below_record` in the innovation's terms) over |A(e^{2 pi i f})|^2. The
/// covariance of rows kept unfiltered under the same noise model the filtered rows would have.
SegmentSpectrum fitted_spectrum_through_ar(const Eigen::Ref<const Eigen::VectorXd>& innovation, const Eigen::VectorXd& ar,
                                           Eigen::Index rows, const std::function<double(double)>& below_record = {});

/// A stationary noise of two-sided density `density(f)` (f in cycles per sample, 0..0.5) on n rows.
SegmentSpectrum spectrum_of(Eigen::Index rows, const std::function<double(double)>& density);

/// x' R x for the rows of x under the spectrum (x.rows() == spectrum.rows).
Eigen::MatrixXd quadratic_form(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x);

/// x_S' R x_S for the columns S = `columns` of x, in that order, without a copy of them.
Eigen::MatrixXd quadratic_form(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x,
                               std::span<const Eigen::Index> columns);

/// R x for the rows of x under the spectrum (x.rows() == spectrum.rows): the covariance of the
/// noise with each column's weighted sum of it, x'(R x) = quadratic_form, and z'(R x) for any
/// other columns z of the same rows.
Eigen::MatrixXd covariance_times(const SegmentSpectrum& spectrum, const Eigen::Ref<const Eigen::MatrixXd>& x);

/// The rows of a stretch sorted into groups (the phases of a case): `group[k]` in 0 .. groups-1
/// for row k. With Z the groups' indicator columns, Z'RZ is the covariance of the noise's sums
/// over the groups and X'RZ that of each column's weighted sum with them. Both are sums of the
/// autocovariance over blocks of rows, taken from its running sums: no transform, and Z is never
/// formed.
struct RowGroups {
  std::vector<Eigen::Index> group;
  Eigen::Index groups = 0;
};

/// Z'RZ (groups x groups) under the spectrum (group.size() == spectrum.rows).
Eigen::MatrixXd group_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows);

/// X'RZ (x.cols() x groups) under the spectrum (x.rows() == spectrum.rows == group.size()).
Eigen::MatrixXd group_cross_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows,
                                       const Eigen::Ref<const Eigen::MatrixXd>& x);

/// [X W]'RZ for columns of the same rows held apart, without a copy of them side by side.
Eigen::MatrixXd group_cross_covariance(const SegmentSpectrum& spectrum, const RowGroups& rows,
                                       const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& w);


}  // namespace inertia::noise
