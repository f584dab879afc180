#pragma once
// A sensor's noise from the static stretches of a dataset: the Allan analysis of each stretch,
// pooled (allan.hpp), the noise terms' fit (noise_fit.hpp) and the one-sided Welch PSD beside it
// in the same units, with the fitted model's PSD:
//     S(f) = 2 [ Q^2 (2 pi f)^2 tau0 + N^2 + B^2 / (2 pi f) + K^2 / (2 pi f)^2 + R^2 / (2 pi f)^3 ]
// (IEEE 952 Annex C's two-sided densities, doubled). Used by `inertia-analyze noise` and by
// characterize's report.
//
// Static stretches: the rows of a case of kind static, or of any case whose phase label is
// "dwell", "static" or "rest", in contiguous runs (a gap or another phase ends a run). Stretches
// are analysed separately and pooled: at each tau their second differences average together and
// their degrees of freedom add (nothing is averaged across a gap).
#include <Eigen/Dense>

#include <optional>
#include <string>
#include <vector>

#include "analyzer/noise/allan.hpp"
#include "analyzer/noise/noise_fit.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::noise {

struct Stretch {
  std::size_t case_index = 0;
  std::string case_name;
  Eigen::Index begin = 0, end = 0;     // rows [begin, end)
  double duration_s = 0.0;
};

/// The static stretches of `data` (of case `only_case` when non-empty) of at least min_samples rows.
std::vector<Stretch> static_stretches(const dataset::Dataset& data, const std::string& only_case = {},
                                      Eigen::Index min_samples = 64);

struct Psd {
  std::vector<double> frequency_hz;
  std::vector<double> density;          // output unit^2 / Hz, one-sided
  int segments = 0;
  Eigen::Index segment_length = 0;
};

/// One-sided Welch PSD (Hann window, 50 % overlap) of several stretches of one rate, averaged over
/// every segment of every stretch at least segment_length long. segment_length: a power of two.
Psd welch(const std::vector<Eigen::VectorXd>& stretches, double sample_period_s, Eigen::Index segment_length);

/// The fitted model's one-sided PSD at f (Hz).
double model_psd(const NoiseFit& fit, double f_hz, double tau0_s);

struct NoiseAnalysis {
  std::vector<Stretch> stretches;
  double tau0_s = 0.0;
  std::vector<AllanPoint> points;       // pooled
  std::optional<NoiseFit> fit;          // none: too few octaves (fit_error says why)
  std::string fit_error;
  Psd psd;
  /// What the data could not give: e.g. "tau clipped at 12.8 s: the longest stretch is 30 s".
  std::vector<std::string> notes;
};

struct NoiseAnalysisOptions {
  std::string only_case;
  double tau_max_s = 0.0;               // > 0: fit no octave beyond it (and say when the data stop short of it)
  NoiseFitOptions fit;
};

/// The whole analysis of `data`'s output. Throws InputError when there is no static stretch.
NoiseAnalysis analyse_noise(const dataset::Dataset& data, const NoiseAnalysisOptions& options = {});

}  // namespace inertia::noise
