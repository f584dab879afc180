#pragma once
// Where the residual exceeds the model's own noise, by frequency band and by operating condition.
// The per case/phase test lives in discrepancy.cpp (on NoiseModel::stretch); these two complete it:
//  - bands: per case, the residual's Welch PSD (Hann, 50% overlap) against the PSD the model's
//    noise explains (NoiseModel), in octave bands up to Nyquist. Per band the statistic is the sum
//    over segments and bins of periodogram / expected, a quadratic form in the residual whose mean
//    and variance under the model are known exactly from the window (white within a few bins; the
//    lowest bins integrated against the model's spectrum), so it is compared with a scaled
//    chi-square (Satterthwaite: dof = 2 mean^2 / variance).
//  - conditions: bins of the reference specific-force magnitude |a| (g) and of temperature;
//    residual sum of squares per bin against what the model's noise puts there, scaled
//    chi-square with the dof of the runs the bin's samples come from.
// Under slow noise (flicker, random walk) every stretch is taken about its own mean.
// Every family (bands of all cases; condition bins) is Bonferroni-corrected at alpha.
#include <Eigen/Dense>
#include <array>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/noise/noise_fit.hpp"
#include "analyzer/noise/quadratic_form_law.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::diagnose {

/// The noise the model claims. Two descriptions, not added together:
///  - its `[noise]` law when that states N: Q, N, B, K, R (IEEE 952: quantization, white, flicker,
///    random walk, ramp), as `inertia-analyze noise` or characterize measure them on the sensor's
///    own output. That output's noise is what the free-run residual holds (an ARMAX model's C/A is
///    inside it), and the law's terms come from one fit: its N and Q share the top octaves (their
///    estimates trade off), so N is not replaced by white_sd: with white_sd in N's place and the
///    law's Q, a white band can read above the model (DiagnoseScenario's pink-noise seeds;
///    docs/validation.md, 'Evidence behind choices in the code').
///  - otherwise e white with sd `white_sd`, residual = C(q)/A(q) e, plus whatever slow terms the
///    law states (B, K, R without N).
struct NoiseModel {
  double white_sd = 0.0;   // of e through C/A; 0 when the law states N (the law is then the whole noise)
  Eigen::VectorXd ma;   // c_1..c_q: C(q) = 1 + sum c_j q^-j (terms e[k-j])
  Eigen::VectorXd ar;   // a_1..a_p: A(q) = 1 - sum a_j q^-j (terms y[k-j])
  std::array<double, noise::kNoiseTerms> power_law{};   // Q, N, B, K, R
  std::array<double, noise::kNoiseTerms> power_law_sd{};   // their sd ([noise.std]); 0: taken as exact

  /// From the model's e[k-j] and y[k-j] coefficients and `[noise]`, with `white_sd` (the model's
  /// or a stand-in) where the law does not state N.
  static NoiseModel of(const model::ModelFile& model, double white_sd);
  /// |C/A|^2 at f (Hz) for sample rate fs.
  [[nodiscard]] double gain2(double f_hz, double fs_hz) const;
  /// The law's one-sided PSD at f (unit^2/Hz); 0 without it.
  [[nodiscard]] double power_law_psd(double f_hz, double fs_hz) const;
  [[nodiscard]] bool has_power_law() const;
  /// Flicker, random walk or ramp: noise slower than any stretch, whose offsets between stretches
  /// have no level the model states; the tests then look at each stretch about its own mean.
  [[nodiscard]] bool has_slow_noise() const;
  /// Whether the model states any noise to test against.
  [[nodiscard]] bool has_reference() const;
  /// The relative variance of the power the model expects between f_lo and f_hi (Hz), from the
  /// law's sds: its terms' shares of the PSD over the band, each known to 2 sd/value of itself.
  [[nodiscard]] double band_relative_variance(double f_lo_hz, double f_hi_hz, double fs_hz) const;
  /// One line for the report: which noise the tests expect.
  [[nodiscard]] std::string describe() const;

  /// The covariance of n contiguous residual samples at fs under the model, about their own mean
  /// when it has slow noise: C = P R P, R the Toeplitz covariance of the model's spectrum
  /// (noise::spectrum_of) and P = I - 11'/n (or I).
  struct StretchCovariance {
    noise::SegmentSpectrum spectrum;   // R: its autocovariance r(d), d = 0 .. n-1, and R x
    Eigen::VectorXd row_sums;          // R 1 (about the mean only)
    double total = 0.0;                // 1'R1
    bool about_mean = false;
    [[nodiscard]] Eigen::Index rows() const { return spectrum.rows; }
    [[nodiscard]] double operator()(Eigen::Index i, Eigen::Index j) const;
    [[nodiscard]] Eigen::VectorXd times(const Eigen::VectorXd& x) const;   // C x, O(n log n)
  };
  [[nodiscard]] StretchCovariance stretch_covariance(Eigen::Index n, double fs_hz) const;

  /// The sum of squares of n contiguous residual samples at fs (about their mean when the model
  /// has slow noise), whose law is tr(C) (mean), 2 tr(C^2) (variance) and C's eigenvalues.
  struct StretchMoments {
    double mean_square = 0.0;          // tr(C) / n
    double dof = 0.0;                  // Satterthwaite: 2 mean^2 / variance (n for white noise)
    bool about_mean = false;
    noise::QuadraticFormLaw law;       // of the sum of squares; see stretch()
  };
  /// With the law's leading eigenvalues (exactly, by Lanczos on C x; all of them for a short
  /// stretch), so its upper tail holds where slow noise puts the power in a few modes.
  [[nodiscard]] StretchMoments stretch(Eigen::Index n, double fs_hz) const;
  /// The mean and dof alone (the law a scaled chi-square), O(n).
  [[nodiscard]] static StretchMoments moments(const StretchCovariance& c);
};

struct BandTest {
  double f_lo_hz = 0.0, f_hi_hz = 0.0;   // [lo, hi), bins of the Welch grid
  int bins = 0;
  double residual_psd = 0.0;   // mean residual PSD over the band, unit^2/Hz (one-sided)
  double model_psd = 0.0;      // mean PSD the model noise explains
  double ratio = 1.0;          // mean of residual/model over the band's bins and segments
  double dof = 0.0;            // of the scaled chi-square
  double reference_dof = 0.0;  // of the model's expected power, from the law's sds (0: exact)
  double p_value = 1.0;
  bool excess = false;         // p below alpha / (bands of every case)
};

struct CaseBands {
  std::size_t case_index = 0;
  double sample_rate_hz = 0.0;
  int segment_length = 0, segments = 0;
  std::vector<BandTest> bands;
  /// For plots: log-spaced frequency points, residual PSD and model PSD there (band means).
  Eigen::VectorXd plot_f, plot_psd, plot_model;
};

struct ConditionBin {
  std::string quantity;        // "|a|" (g) or "T" (degC)
  double lo = 0.0, hi = 0.0;   // [lo, hi)
  Eigen::Index samples = 0;
  double rms = 0.0, expected_rms = 0.0, ratio = 0.0;
  double dof = 0.0, p_value = 1.0;
  bool excess = false;         // p below alpha / (bins of both quantities)
};

struct Location {
  std::string noise;           // NoiseModel::describe() of the noise tested against
  bool about_means = false;    // slow noise: every stretch tested about its own mean
  std::vector<CaseBands> bands;
  std::vector<ConditionBin> conditions;
  std::string verdict;         // one line: where the excess is, or that there is none
};

/// One case's residual rows: residual(r) belongs to case sample first_sample + r.
struct CaseResidual {
  std::size_t case_index = 0;
  Eigen::Index first_sample = 0;
  Eigen::VectorXd residual;
};

Location locate(const dataset::Dataset& data, const std::vector<CaseResidual>& residuals, const NoiseModel& noise,
                double alpha);

}  // namespace inertia::diagnose
