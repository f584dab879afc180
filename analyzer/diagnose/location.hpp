#pragma once
// Where the residual exceeds the model's own noise, by frequency band and by operating condition
// (issue 5, "locate the disagreement"). The per case/phase test lives in discrepancy.cpp; these
// two complete it:
//  - bands: per case, the residual's Welch PSD (Hann, 50% overlap) against the PSD the model's
//    noise explains, in octave bands up to Nyquist. The model's noise is white_sd passed through
//    C(q)/A(q): C from the noise terms e[k-j] (MA), A from the output lags y[k-j] (a free-run
//    residual of an ARMAX model is C/A e). Per band the statistic is the sum over segments and
//    bins of periodogram / expected, a quadratic form in the residual whose mean and variance
//    under the model are known exactly from the window (white within a few bins), so it is
//    compared with a scaled chi-square (Satterthwaite: dof = 2 mean^2 / variance).
//  - conditions: bins of the reference specific-force magnitude |a| (g) and of temperature;
//    residual RMS per bin against the model noise's RMS, chi-square with the dof the noise's
//    autocorrelation leaves (n for white noise).
// Every family (bands of all cases; condition bins) is Bonferroni-corrected at alpha.
#include <Eigen/Dense>
#include <array>
#include <string>
#include <vector>

#include "analyzer/model/model_file.hpp"
#include "analyzer/noise/noise_fit.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::diagnose {

/// The noise the model claims: e white with sd `white_sd`, residual = C(q)/A(q) e, plus the
/// power-law terms of its `[noise]` table (IEEE 952: Q quantization, B flicker, K random walk,
/// R ramp; `inertia-analyze noise` estimates them) beside it. Its N is the white part, which
/// white_sd already states, so N is not added a second time. Q stays even where nothing
/// quantizes: the fit puts there what rises above white plus flicker near Nyquist (the simulator's
/// pink noise flattens in its top octave), and without it the top band read 1.3 times the model.
struct NoiseModel {
  double white_sd = 0.0;
  Eigen::VectorXd ma;   // c_1..c_q: C(q) = 1 + sum c_j q^-j (terms e[k-j])
  Eigen::VectorXd ar;   // a_1..a_p: A(q) = 1 - sum a_j q^-j (terms y[k-j])
  std::array<double, noise::kNoiseTerms> power_law{};   // Q, N (kept 0), B, K, R

  /// From the model's e[k-j] and y[k-j] coefficients and `[noise]` Q, B, K, R, with `white_sd`
  /// (the model's or a stand-in).
  static NoiseModel of(const model::ModelFile& model, double white_sd);
  /// |C/A|^2 at f (Hz) for sample rate fs.
  [[nodiscard]] double gain2(double f_hz, double fs_hz) const;
  /// The power-law terms' one-sided PSD at f (unit^2/Hz); 0 without them.
  [[nodiscard]] double power_law_psd(double f_hz, double fs_hz) const;
  [[nodiscard]] bool has_power_law() const;
  /// Impulse response of C/A, until its energy has converged (at most `max_length` samples).
  [[nodiscard]] Eigen::VectorXd impulse_response(Eigen::Index max_length = 4096) const;
};

struct BandTest {
  double f_lo_hz = 0.0, f_hi_hz = 0.0;   // [lo, hi), bins of the Welch grid
  int bins = 0;
  double residual_psd = 0.0;   // mean residual PSD over the band, unit^2/Hz (one-sided)
  double model_psd = 0.0;      // mean PSD the model noise explains
  double ratio = 1.0;          // mean of residual/model over the band's bins and segments
  double dof = 0.0;            // of the scaled chi-square
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
