#include "analyzer/noise/noise_analysis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <complex>
#include <functional>
#include <iostream>
#include <numbers>
#include <stdexcept>

#include "analyzer/noise/fourier.hpp"
#include "common/input_error.hpp"

namespace inertia::noise {
namespace {

bool is_rest_label(std::string label) {
  std::transform(label.begin(), label.end(), label.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return label == "dwell" || label == "static" || label == "rest";
}

}  // namespace

namespace {

/// The rest runs of one case, found a block of rows at a time: the rows whose phase label is a
/// rest label (every row when `every_row`), in contiguous runs of at least min_samples.
class RestRuns {
 public:
  RestRuns(std::size_t case_index, std::string case_name, bool every_row, Eigen::Index min_samples)
      : case_index_(case_index), case_name_(std::move(case_name)), every_row_(every_row), min_samples_(min_samples) {}

  void add(const dataset::CaseData& block, Eigen::Index first_row) {
    for (std::size_t p = rest_phase_.size(); p < block.phase_names.size(); ++p) rest_phase_.push_back(is_rest_label(block.phase_names[p]));
    for (Eigen::Index k = 0; k < block.size(); ++k) {
      const bool rest = every_row_ || (!block.phase.empty() && rest_phase_[block.phase[static_cast<std::size_t>(k)]]);
      if (rest && !open_) {
        open_ = true;
        begin_ = first_row + k;
      } else if (!rest && open_) {
        close(first_row + k);
      }
    }
    end_ = first_row + block.size();
  }

  /// The runs, the last one closed at the case's end; durations at `sample_period_s`.
  void finish(double sample_period_s, std::vector<Stretch>& out) {
    if (open_) close(end_);
    for (Stretch& s : runs_) {
      s.duration_s = static_cast<double>(s.end - s.begin) * sample_period_s;
      out.push_back(std::move(s));
    }
    runs_.clear();
  }

 private:
  void close(Eigen::Index end) {
    open_ = false;
    if (end - begin_ >= min_samples_) runs_.push_back({case_index_, case_name_, begin_, end, 0.0});
  }

  std::size_t case_index_;
  std::string case_name_;
  bool every_row_;
  Eigen::Index min_samples_;
  std::vector<bool> rest_phase_;   // each label judged once
  std::vector<Stretch> runs_;
  bool open_ = false;
  Eigen::Index begin_ = 0, end_ = 0;
};

/// Whether every row of a case is at rest: the case named, or a static case without labels. A
/// case with neither labels nor that: none of its rows.
bool every_row_at_rest(CaseKind kind, bool labelled, const std::string& only_case) {
  return !only_case.empty() || (kind == CaseKind::Static && !labelled);
}

/// Welch's sums (Hann window, 50 % overlap, each segment's mean removed) fed stretch by stretch a
/// block of rows at a time: segments at 0, L/2, L, ... of each stretch, as from the whole stretch.
class WelchSums {
 public:
  explicit WelchSums(Eigen::Index length)
      : length_(length), window_(length), sum_(Eigen::VectorXd::Zero(length / 2 + 1)), buffer_(length), fourier_(length) {
    for (Eigen::Index i = 0; i < length; ++i)
      window_(i) = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(length));
  }

  void start_stretch() { filled_ = 0; }

  void push(const Eigen::Ref<const Eigen::VectorXd>& x) {
    for (Eigen::Index at = 0; at < x.size();) {
      const Eigen::Index take = std::min(length_ - filled_, x.size() - at);
      buffer_.segment(filled_, take) = x.segment(at, take);
      filled_ += take;
      at += take;
      if (filled_ < length_) break;
      fourier_.samples() = (buffer_.array() - buffer_.mean()) * window_.array();
      fourier_.forward();
      sum_ += fourier_.spectrum().cwiseAbs2();
      ++segments_;
      const Eigen::Index half = length_ / 2;   // the next segment starts half a segment on
      buffer_.head(length_ - half) = buffer_.tail(length_ - half).eval();
      filled_ = length_ - half;
    }
  }

  [[nodiscard]] Psd psd(double sample_period_s) const {
    Psd out;
    out.segment_length = length_;
    out.segments = segments_;
    if (segments_ == 0) return out;
    const double fs = 1.0 / sample_period_s;
    const double window_energy = window_.squaredNorm();
    // One-sided density: |X|^2 / (fs sum w^2), doubled except at DC and Nyquist. The DC bin (the
    // segment mean is removed) is left out.
    const Eigen::Index bins = length_ / 2 + 1;
    for (Eigen::Index b = 1; b < bins; ++b) {
      const double two = b == bins - 1 ? 1.0 : 2.0;
      out.frequency_hz.push_back(static_cast<double>(b) * fs / static_cast<double>(length_));
      out.density.push_back(two * sum_(b) / (static_cast<double>(segments_) * fs * window_energy));
    }
    return out;
  }

 private:
  Eigen::Index length_;
  Eigen::VectorXd window_, sum_, buffer_;
  RealFourier fourier_;
  Eigen::Index filled_ = 0;
  int segments_ = 0;
};

/// Rows of a case, in order, for the stretches that lie in it: `feed(case_index, first_row, y)`.
using RowFeed = std::function<void(std::size_t, Eigen::Index, const Eigen::Ref<const Eigen::VectorXd>&)>;
/// Hands every case's rows, in case order and row order, to a RowFeed.
using RowSource = std::function<void(const RowFeed&)>;

/// The analysis once the stretches are known: `source` gives the rows; `periods` and `names`
/// are the cases' sample periods and names.
NoiseAnalysis analyse_stretches(std::vector<Stretch> stretches, const std::vector<double>& periods,
                                const NoiseAnalysisOptions& options, const RowSource& source) {
  NoiseAnalysis out;
  out.stretches = std::move(stretches);
  out.tau0_s = periods[out.stretches.front().case_index];
  std::vector<const Stretch*> used;
  double longest = 0.0;
  Eigen::Index longest_rows = 0;
  for (const Stretch& s : out.stretches) {
    const double period = periods[s.case_index];
    if (std::abs(period - out.tau0_s) > 1e-9 * out.tau0_s) {
      out.notes.push_back(fmt::format("case {}: sampled every {} s, not {} s: left out", s.case_name, period, out.tau0_s));
      continue;
    }
    used.push_back(&s);
    longest = std::max(longest, s.duration_s);
    longest_rows = std::max(longest_rows, s.end - s.begin);
  }
  // Welch: segments of a power of two, at most 2^16 samples, at least 4 per longest stretch.
  Eigen::Index l = 64;
  while (l * 2 <= std::min<Eigen::Index>(longest_rows / 4, Eigen::Index{1} << 16)) l *= 2;
  std::optional<WelchSums> welch;
  if (longest_rows >= l) welch.emplace(l);
  std::vector<AllanAccumulator> allan;
  for (std::size_t i = 0; i < used.size(); ++i) allan.emplace_back(out.tau0_s);
  // The stretches lie in case order and row order: the next one to feed is `next`.
  std::size_t next = 0;
  source([&](std::size_t case_index, Eigen::Index first_row, const Eigen::Ref<const Eigen::VectorXd>& y) {
    const Eigen::Index end_row = first_row + y.size();
    for (std::size_t i = next; i < used.size() && used[i]->case_index == case_index && used[i]->begin < end_row; ++i) {
      const Stretch& s = *used[i];
      const Eigen::Index from = std::max(s.begin, first_row), to = std::min(s.end, end_row);
      if (to <= from) continue;
      const auto rows = y.segment(from - first_row, to - from);
      if (welch && from == s.begin) welch->start_stretch();
      allan[i].push(rows);
      if (welch) welch->push(rows);
      if (to == s.end) next = i + 1;
    }
  });
  std::vector<std::vector<AllanPoint>> per_stretch;
  for (const AllanAccumulator& a : allan) per_stretch.push_back(a.points());
  out.points = pool(per_stretch);
  if (per_stretch.size() > 1)
    out.notes.push_back(fmt::format("{} stretches pooled: at each tau their second differences averaged together, their "
                                    "degrees of freedom added; nothing is averaged across a gap",
                                    per_stretch.size()));
  std::vector<AllanPoint> fitted = out.points;
  if (options.tau_max_s > 0.0) {
    std::erase_if(fitted, [&](const AllanPoint& p) { return p.tau > options.tau_max_s * (1.0 + 1e-9); });
    const double reached = out.points.empty() ? 0.0 : out.points.back().tau;
    if (reached < options.tau_max_s)
      out.notes.push_back(fmt::format("tau clipped at {:.4g} s (asked {:.4g} s): the longest stretch is {:.4g} s, and an Allan "
                                      "variance needs at least two averages of tau",
                                      reached, options.tau_max_s, longest));
  }
  try {
    out.fit = fit_noise(fitted, options.fit);
  } catch (const std::invalid_argument& e) {
    out.fit_error = e.what();
  }
  if (welch) out.psd = welch->psd(out.tau0_s);
  return out;
}

/// The errors of a dataset whose stretches are `stretches` (case names `names`).
void refuse_without_stretches(const std::vector<Stretch>& stretches, const std::vector<std::string>& names,
                              const NoiseAnalysisOptions& options) {
  if (!options.only_case.empty() && std::find(names.begin(), names.end(), options.only_case) == names.end())
    throw InputError("noise: the dataset has no case '" + options.only_case + "'");
  if (stretches.empty())
    throw InputError(options.only_case.empty()
                         ? fmt::format("noise: no static stretch in the dataset (a case of kind static, or rows whose phase is "
                                       "dwell, static or rest, at least {} samples); name one with --case",
                                       kMinStretchRows)
                         : fmt::format("noise: case '{}' has fewer than {} samples", options.only_case, kMinStretchRows));
}

}  // namespace

std::vector<Stretch> static_stretches(const dataset::Dataset& data, const std::string& only_case, Eigen::Index min_samples) {
  std::vector<Stretch> out;
  for (std::size_t c = 0; c < data.cases.size(); ++c) {
    const dataset::CaseData& cd = data.cases[c];
    if (!only_case.empty() && cd.name != only_case) continue;
    RestRuns runs(c, cd.name, every_row_at_rest(cd.kind, !cd.phase.empty(), only_case), min_samples);
    runs.add(cd, 0);
    runs.finish(cd.sample_period_s, out);
  }
  return out;
}

double model_psd(const NoiseFit& fit, double f_hz, double tau0_s) {
  std::array<double, kNoiseTerms> c{};
  for (int j = 0; j < kNoiseTerms; ++j) c[static_cast<std::size_t>(j)] = fit.terms[static_cast<std::size_t>(j)].value;
  return model_psd(c, f_hz, tau0_s);
}

NoiseAnalysis analyse_noise(const dataset::Dataset& data, const NoiseAnalysisOptions& options) {
  std::vector<Stretch> stretches = static_stretches(data, options.only_case);
  std::vector<std::string> names;
  std::vector<double> periods;
  for (const dataset::CaseData& c : data.cases) {
    names.push_back(c.name);
    periods.push_back(c.sample_period_s);
  }
  refuse_without_stretches(stretches, names, options);
  return analyse_stretches(std::move(stretches), periods, options, [&](const RowFeed& feed) {
    for (std::size_t c = 0; c < data.cases.size(); ++c) feed(c, 0, data.cases[c].y);
  });
}

NoiseAnalysis analyse_noise(const std::filesystem::path& dataset_dir, const NoiseAnalysisOptions& options) {
  const dataset::Dataset description = dataset::read_dataset_description(dataset_dir);
  std::vector<std::string> names;
  for (const dataset::CaseData& c : description.cases) names.push_back(c.name);
  std::vector<double> periods(description.cases.size(), 0.0);
  std::vector<Stretch> stretches;
  // First pass over each case file: checked whole, its rest runs found.
  std::vector<std::optional<dataset::CaseRowStream>> streams(description.cases.size());
  for (std::size_t c = 0; c < description.cases.size(); ++c) {
    const dataset::CaseData& cd = description.cases[c];
    if (!options.only_case.empty() && cd.name != options.only_case) continue;
    std::optional<RestRuns> runs;
    streams[c].emplace(dataset_dir / cd.file, std::cerr, [&](const dataset::CaseData& block, Eigen::Index first_row) {
      // The first block says whether the file has phase labels.
      if (!runs) runs.emplace(c, cd.name, every_row_at_rest(cd.kind, !block.phase.empty(), options.only_case), kMinStretchRows);
      runs->add(block, first_row);
    });
    periods[c] = streams[c]->sample_period_s();
    if (runs) runs->finish(periods[c], stretches);
  }
  refuse_without_stretches(stretches, names, options);
  // Second pass: the stretches' rows into their accumulators.
  return analyse_stretches(std::move(stretches), periods, options, [&](const RowFeed& feed) {
    for (std::size_t c = 0; c < streams.size(); ++c) {
      if (!streams[c]) continue;
      streams[c]->for_each_block([&](const dataset::CaseData& block, Eigen::Index first_row) { feed(c, first_row, block.y); });
    }
  });
}

}  // namespace inertia::noise
