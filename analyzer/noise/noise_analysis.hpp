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

#include <filesystem>
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

/// The fewest rows a static stretch is analysed on.
inline constexpr Eigen::Index kMinStretchRows = 64;

/// The static stretches of `data` (of case `only_case` when non-empty) of at least min_samples rows.
std::vector<Stretch> static_stretches(const dataset::Dataset& data, const std::string& only_case = {},
                                      Eigen::Index min_samples = kMinStretchRows);

struct Psd {
  std::vector<double> frequency_hz;
  std::vector<double> density;          // output unit^2 / Hz, one-sided
  int segments = 0;
  Eigen::Index segment_length = 0;
};


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

/// The whole analysis of `data`'s output. Throws InputError when there is no static stretch. The
/// PSD is the one-sided Welch estimate (Hann window, 50 % overlap, each segment's mean removed)
/// over every segment of every stretch, segments of a power of two up to 2^16 samples and at
/// least four to the longest stretch.
NoiseAnalysis analyse_noise(const dataset::Dataset& data, const NoiseAnalysisOptions& options = {});

/// The same analysis of the dataset folder `dataset_dir`, its case files streamed
/// (dataset::CaseRowStream): the memory held is a block of rows and the accumulators, whatever
/// the record's length. Each case file is read twice: the first pass checks it (read_dataset's
/// errors) and finds its stretches, the second feeds them. The answer is analyse_noise's of
/// read_dataset(dataset_dir), to the bit.
NoiseAnalysis analyse_noise(const std::filesystem::path& dataset_dir, const NoiseAnalysisOptions& options = {});

}  // namespace inertia::noise
