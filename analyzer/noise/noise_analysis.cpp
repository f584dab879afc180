#include "analyzer/noise/noise_analysis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <complex>
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

std::vector<Stretch> static_stretches(const dataset::Dataset& data, const std::string& only_case, Eigen::Index min_samples) {
  std::vector<Stretch> out;
  for (std::size_t c = 0; c < data.cases.size(); ++c) {
    const dataset::CaseData& cd = data.cases[c];
    if (!only_case.empty() && cd.name != only_case) continue;
    const Eigen::Index n = cd.y.size();
    std::vector<bool> rest(static_cast<std::size_t>(n), false);
    if (!only_case.empty() || (cd.kind == CaseKind::Static && cd.phase.empty())) {
      std::fill(rest.begin(), rest.end(), true);   // the case named, or a static case: all of it
    } else if (!cd.phase.empty()) {
      std::vector<bool> rest_phase(cd.phase_names.size());   // each phase's label judged once
      for (std::size_t p = 0; p < cd.phase_names.size(); ++p) rest_phase[p] = is_rest_label(cd.phase_names[p]);
      for (Eigen::Index k = 0; k < n; ++k) rest[static_cast<std::size_t>(k)] = rest_phase[cd.phase[static_cast<std::size_t>(k)]];
    }
    for (Eigen::Index k = 0; k < n;) {
      if (!rest[static_cast<std::size_t>(k)]) {
        ++k;
        continue;
      }
      Eigen::Index j = k;
      while (j < n && rest[static_cast<std::size_t>(j)]) ++j;
      if (j - k >= min_samples) out.push_back({c, cd.name, k, j, static_cast<double>(j - k) * cd.sample_period_s});
      k = j;
    }
  }
  return out;
}

Psd welch(const std::vector<Eigen::VectorXd>& stretches, double sample_period_s, Eigen::Index segment_length) {
  Psd out;
  out.segment_length = segment_length;
  const Eigen::Index l = segment_length;
  const Eigen::Index bins = l / 2 + 1;
  Eigen::VectorXd window(l), sum = Eigen::VectorXd::Zero(bins);
  for (Eigen::Index i = 0; i < l; ++i) window(i) = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(l));
  const double window_energy = window.squaredNorm();
  RealFourier fourier(l);
  for (const Eigen::VectorXd& x : stretches) {
    for (Eigen::Index start = 0; start + l <= x.size(); start += l / 2) {
      const auto seg = x.segment(start, l);
      fourier.samples() = (seg.array() - seg.mean()) * window.array();
      fourier.forward();
      sum += fourier.spectrum().cwiseAbs2();
      ++out.segments;
    }
  }
  if (out.segments == 0) return out;
  const double fs = 1.0 / sample_period_s;
  // One-sided density: |X|^2 / (fs sum w^2), doubled except at DC and Nyquist. The DC bin (the
  // segment mean is removed) is left out.
  for (Eigen::Index b = 1; b < bins; ++b) {
    const double two = b == bins - 1 ? 1.0 : 2.0;
    out.frequency_hz.push_back(static_cast<double>(b) * fs / static_cast<double>(l));
    out.density.push_back(two * sum(b) / (static_cast<double>(out.segments) * fs * window_energy));
  }
  return out;
}

double model_psd(const NoiseFit& fit, double f_hz, double tau0_s) {
  std::array<double, kNoiseTerms> c{};
  for (int j = 0; j < kNoiseTerms; ++j) c[static_cast<std::size_t>(j)] = fit.terms[static_cast<std::size_t>(j)].value;
  return model_psd(c, f_hz, tau0_s);
}

NoiseAnalysis analyse_noise(const dataset::Dataset& data, const NoiseAnalysisOptions& options) {
  NoiseAnalysis out;
  out.stretches = static_stretches(data, options.only_case);
  if (!options.only_case.empty() &&
      std::none_of(data.cases.begin(), data.cases.end(), [&](const dataset::CaseData& c) { return c.name == options.only_case; }))
    throw InputError("noise: the dataset has no case '" + options.only_case + "'");
  if (out.stretches.empty())
    throw InputError(options.only_case.empty()
                         ? std::string("noise: no static stretch in the dataset (a case of kind static, or rows whose phase is "
                                       "dwell, static or rest, at least 64 samples); name one with --case")
                         : "noise: case '" + options.only_case + "' has fewer than 64 samples");
  out.tau0_s = data.cases[out.stretches.front().case_index].sample_period_s;
  std::vector<std::vector<AllanPoint>> per_stretch;
  std::vector<Eigen::VectorXd> series;
  double longest = 0.0;
  for (const Stretch& s : out.stretches) {
    const dataset::CaseData& cd = data.cases[s.case_index];
    if (std::abs(cd.sample_period_s - out.tau0_s) > 1e-9 * out.tau0_s) {
      out.notes.push_back(fmt::format("case {}: sampled every {} s, not {} s: left out", cd.name, cd.sample_period_s, out.tau0_s));
      continue;
    }
    AllanAccumulator acc(out.tau0_s);
    acc.push(cd.y.segment(s.begin, s.end - s.begin));
    per_stretch.push_back(acc.points());
    series.emplace_back(cd.y.segment(s.begin, s.end - s.begin));
    longest = std::max(longest, s.duration_s);
  }
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
  // Welch: segments of a power of two, at most 2^16 samples, at least 4 per longest stretch.
  Eigen::Index longest_rows = 0;
  for (const Eigen::VectorXd& x : series) longest_rows = std::max(longest_rows, x.size());
  Eigen::Index l = 64;
  while (l * 2 <= std::min<Eigen::Index>(longest_rows / 4, Eigen::Index{1} << 16)) l *= 2;
  if (longest_rows >= l) out.psd = welch(series, out.tau0_s, l);
  return out;
}

}  // namespace inertia::noise
