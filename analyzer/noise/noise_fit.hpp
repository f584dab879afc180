#pragma once
// The sensor's noise terms from its Allan variance (IEEE Std 952 Annex C, IEEE Std 1293 12.3.6):
//     sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2
// Q quantization, N white rate noise (angle / velocity random walk), B bias instability (flicker),
// K rate random walk, R rate ramp; in the output unit: Q in unit*s, N in unit*s^(1/2) (unit/sqrt(Hz)),
// B in unit, K in unit/s^(1/2), R in unit/s.
//
// The fit is in the variance domain, where the model is linear in Q^2 .. R^2: weighted least
// squares with each octave's variance 2 sigma^4 / edf (its equivalent degrees of freedom for the
// noise type that dominates it, allan.hpp), the weights iterated on the model's own values (not
// the estimates: weights from estimates bias a variance fit low), every coefficient kept >= 0
// (the best of the non-negative subsets). Adjacent octaves of the overlapping estimator share
// samples, so their estimates are correlated (0.5 between neighbours for white noise, 0.9 for a
// random walk; measured, noise_fit.cpp): the coefficients' covariance is the sandwich of the
// weighted fit with that full covariance (its coverage and width over simulated records: test
// NoiseFit.TermsLieInTheirIntervalsAndTheIntervalsMatchTheSpread). Each term's interval is its
// variance coefficient's, clipped at 0.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/noise/allan.hpp"

namespace inertia::noise {

enum class NoiseTerm { Q = 0, N = 1, B = 2, K = 3, R = 4 };
inline constexpr int kNoiseTerms = 5;
const char* noise_term_name(NoiseTerm t);          // "Q", "N", ...
const char* noise_term_meaning(NoiseTerm t);       // "quantization", "white noise (random walk)", ...
/// The power-law exponent alpha (S_y ~ f^alpha) of a term's noise, for its edf.
int noise_term_alpha(NoiseTerm t);

struct NoiseCoefficient {
  double value = 0.0;          // in the units of the header
  double lower = 0.0, upper = 0.0;   // 95 % interval
  bool determined = false;     // the interval excludes 0
  double tau_min = 0.0, tau_max = 0.0;   // the taus where this term carries most of the model
};

struct NoiseFit {
  std::array<NoiseCoefficient, kNoiseTerms> terms;
  std::array<bool, kNoiseTerms> fitted{};     // offered to the fit (a term can be switched off)
  double chi_square = 0.0;                    // of the weighted fit
  int dof = 0;
  double tau_min = 0.0, tau_max = 0.0;        // the taus fitted
  std::vector<double> model;                  // the fitted sigma^2 at each point
  std::vector<double> edf;                    // of each point, for its dominant noise
  [[nodiscard]] double avar(double tau) const;
};

struct NoiseFitOptions {
  double level = 0.95;
  double min_edf = 2.0;                       // octaves with fewer degrees of freedom are not fitted
  std::array<bool, kNoiseTerms> terms = {true, true, true, true, true};
};

/// Fits the terms to the points of one (pooled) Allan analysis. Throws std::invalid_argument when
/// fewer points than terms have min_edf.
NoiseFit fit_noise(const std::vector<AllanPoint>& points, const NoiseFitOptions& options = {});

/// sigma^2(tau) of the terms `c` (Q, N, B, K, R values).
double model_avar(const std::array<double, kNoiseTerms>& c, double tau);

/// The one-sided PSD (unit^2/Hz) at f of the terms `c` (Q, N, B, K, R values; IEEE 952 Table C.1,
/// doubled): 2 (4 Q^2 sin^2(pi f tau0) / tau0 + N^2 + B^2 / (2 pi f) + K^2 / (2 pi f)^2 + R^2 / (2 pi f)^3).
/// Q's is the sampled spectrum (a white quantization error, differenced), whose Allan variance is
/// model_avar's 3 Q^2 / tau^2 at every tau; Table C.1's (2 pi f)^2 tau0 Q^2 is its low-frequency
/// limit, pi^2 / 4 times too high at Nyquist.
double model_psd(const std::array<double, kNoiseTerms>& c, double f_hz, double tau0_s);

}  // namespace inertia::noise
