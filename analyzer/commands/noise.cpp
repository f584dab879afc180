#include "analyzer/commands/noise.hpp"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <cmath>
#include <fstream>
#include <iostream>

#include "analyzer/fusion/log_dataset.hpp"
#include "analyzer/noise/noise_analysis.hpp"
#include "analyzer/report/gnuplot.hpp"
#include "common/dataset/dataset.hpp"
#include "common/input_error.hpp"
#include "common/output_folder.hpp"
#include "common/toml_text.hpp"

namespace inertia::commands {
namespace {

using noise::NoiseTerm;

std::string units_of(NoiseTerm t, const std::string& unit) {
  switch (t) {
    case NoiseTerm::Q: return unit + " s";
    case NoiseTerm::N: return unit + " s^1/2";
    case NoiseTerm::B: return unit;
    case NoiseTerm::K: return unit + " s^-1/2";
    case NoiseTerm::R: return unit + " s^-1";
  }
  return unit;
}

void write_toml(const std::filesystem::path& file, const noise::NoiseAnalysis& a, const std::string& unit,
                const std::string& source) {
  std::ofstream f(file);
  f << "# Noise of the sensor's output at rest (inertia-analyze noise) from " << source << ".\n";
  f << "# [noise] is a model file's table (IEEE 952 Annex C: sigma^2(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 +\n";
  f << "# K^2 tau/3 + R^2 tau^2/2); [interval] the 95 % intervals, [tau_range] where each term dominates.\n";
  f << "output_unit = " << toml_quote(unit) << "\n";
  f << "tau0_s = " << toml_float(a.tau0_s) << "\n";
  f << "stretches = " << a.stretches.size() << "\n";
  if (!a.fit) {
    f << "# no fit: " << a.fit_error << "\n";
  } else {
    const noise::NoiseFit& fit = *a.fit;
    f << "\n[noise]\n";
    const double n = fit.terms[static_cast<std::size_t>(NoiseTerm::N)].value;
    if (n > 0.0) f << "white_sd = " << toml_float(n / std::sqrt(a.tau0_s)) << "   # N / sqrt(tau0): per sample\n";
    for (int t = 0; t < noise::kNoiseTerms; ++t) {
      if (!fit.fitted[static_cast<std::size_t>(t)]) continue;
      const noise::NoiseCoefficient& c = fit.terms[static_cast<std::size_t>(t)];
      f << noise::noise_term_name(static_cast<NoiseTerm>(t)) << " = " << toml_float(c.value) << "   # "
        << units_of(static_cast<NoiseTerm>(t), unit) << (c.determined ? "" : ", not determined (interval reaches 0)") << "\n";
    }
    f << "\n[interval]\n";
    for (int t = 0; t < noise::kNoiseTerms; ++t) {
      if (!fit.fitted[static_cast<std::size_t>(t)]) continue;
      const noise::NoiseCoefficient& c = fit.terms[static_cast<std::size_t>(t)];
      f << noise::noise_term_name(static_cast<NoiseTerm>(t)) << " = [" << toml_float(c.lower) << ", " << toml_float(c.upper) << "]\n";
    }
    f << "\n[tau_range]\n";
    for (int t = 0; t < noise::kNoiseTerms; ++t) {
      const noise::NoiseCoefficient& c = fit.terms[static_cast<std::size_t>(t)];
      if (c.tau_max > 0.0)
        f << noise::noise_term_name(static_cast<NoiseTerm>(t)) << " = [" << toml_float(c.tau_min) << ", " << toml_float(c.tau_max) << "]\n";
    }
  }
  for (const noise::AllanPoint& p : a.points) {
    f << "\n[[allan]]\ntau = " << toml_float(p.tau) << "\nadev = " << toml_float(std::sqrt(p.avar));
    if (std::isfinite(p.mvar)) f << "\nmdev = " << toml_float(std::sqrt(p.mvar));
    f << "\nterms = " << p.terms << "\nstride = " << p.stride << "\n";
  }
}

/// Dominant-noise edf of each point (from the fit, else white noise).
double edf_of(const noise::NoiseAnalysis& a, std::size_t i) {
  if (a.fit && i < a.fit->edf.size()) return a.fit->edf[i];
  return noise::point_edf(a.points[i], 0);
}

bool plot(const std::filesystem::path& dir, const noise::NoiseAnalysis& a, const std::string& unit) {
  {
    std::ofstream d(dir / "adev.dat");
    for (std::size_t i = 0; i < a.points.size(); ++i) {
      const noise::AllanPoint& p = a.points[i];
      const auto [lo, hi] = noise::variance_interval(p.avar, edf_of(a, i));
      d << p.tau << ' ' << std::sqrt(p.avar) << ' ' << std::sqrt(lo) << ' ' << std::sqrt(hi) << ' '
        << (std::isfinite(p.mvar) ? std::sqrt(p.mvar) : std::nan("")) << ' ' << (a.fit ? std::sqrt(a.fit->avar(p.tau)) : std::nan(""))
        << '\n';
    }
  }
  {
    std::ofstream d(dir / "psd.dat");
    for (std::size_t i = 0; i < a.psd.frequency_hz.size(); ++i) {
      const double f = a.psd.frequency_hz[i];
      d << f << ' ' << a.psd.density[i] << ' ' << (a.fit ? noise::model_psd(*a.fit, f, a.tau0_s) : std::nan("")) << '\n';
    }
  }
  {
    std::ofstream g(dir / "noise.gp");
    g << report::png_terminal(900, 600) << "set logscale xy\nset grid\n";
    g << "set output 'adev.png'\n";   // names relative to the script's folder, where gnuplot runs
    g << "set xlabel 'tau [s]'\nset ylabel 'Allan deviation [" << unit << "]'\n";
    g << "plot 'adev.dat' u 1:2:3:4 w yerrorbars t 'ADEV (95 % interval)', '' u 1:5 w lp t 'MDEV', '' u 1:6 w l lw 2 t 'fitted Q N B K R'\n";
    g << "set output 'psd.png'\n";
    g << "set xlabel 'frequency [Hz]'\nset ylabel 'PSD [" << unit << "^2/Hz]'\n";
    g << "plot 'psd.dat' u 1:2 w l t 'Welch (Hann, 50 % overlap)', '' u 1:3 w l lw 2 t 'fitted model'\n";
  }
  return report::run_gnuplot(dir / "noise.gp");
}

}  // namespace

void write_noise_section(std::ostream& md, std::ostream& out, const noise::NoiseAnalysis& a, const std::string& unit,
                         const std::string& source, const std::filesystem::path& plots_dir) {
  double total = 0.0;
  for (const noise::Stretch& s : a.stretches) total += s.duration_s;
  const auto both = [&](const std::string& text) {
    out << text;
    md << text;
  };
  both(fmt::format("noise of {} ({}): {} static stretch(es), {:.4g} s in all, tau0 {:.4g} s\n", source, unit,
                   a.stretches.size(), total, a.tau0_s));
  for (const noise::Stretch& s : a.stretches)
    md << fmt::format("- case {}: rows {}..{} ({:.4g} s)\n", s.case_name, s.begin, s.end, s.duration_s);
  for (const std::string& n : a.notes) both("note: " + n + "\n");
  if (a.fit) {
    const noise::NoiseFit& fit = *a.fit;
    both(fmt::format("\nfit of sigma^2(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2 over tau {:.4g} .. {:.4g} s "
                     "(chi-square {:.1f} on {} dof):\n\n",
                     fit.tau_min, fit.tau_max, fit.chi_square, fit.dof));
    both("| term | meaning | value | 95 % interval | unit | read from tau (s) |\n|---|---|---|---|---|---|\n");
    for (int t = 0; t < noise::kNoiseTerms; ++t) {
      if (!fit.fitted[static_cast<std::size_t>(t)]) continue;
      const auto term = static_cast<NoiseTerm>(t);
      const noise::NoiseCoefficient& c = fit.terms[static_cast<std::size_t>(t)];
      const std::string range = c.tau_max > 0.0 ? fmt::format("{:.3g} .. {:.3g}", c.tau_min, c.tau_max) : "-";
      both(fmt::format("| {} | {} | {:.4g} | [{:.4g}, {:.4g}]{} | {} | {} |\n", noise::noise_term_name(term),
                       noise::noise_term_meaning(term), c.value, c.lower, c.upper, c.determined ? "" : " (not determined)",
                       units_of(term, unit), range));
    }
  } else {
    both("\nno fit: " + a.fit_error + "\n");
  }
  md << "\n| tau (s) | ADEV | 95 % interval | MDEV | terms | stride |\n|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    const noise::AllanPoint& p = a.points[i];
    const auto [lo, hi] = noise::variance_interval(p.avar, edf_of(a, i));
    md << fmt::format("| {:.4g} | {:.4g} | [{:.4g}, {:.4g}] | {} | {} | {} |\n", p.tau, std::sqrt(p.avar), std::sqrt(lo),
                      std::sqrt(hi), std::isfinite(p.mvar) ? fmt::format("{:.4g}", std::sqrt(p.mvar)) : std::string("-"),
                      p.terms, p.stride);
  }
  md << "\nThe Allan variance: overlapping at every octave up to 2^10 samples, octave decimation beyond (stride "
        "column); intervals from the equivalent degrees of freedom (NIST SP 1065 table 5) of the noise the fit says "
        "dominates each octave. The PSD: Welch, Hann windows of " << a.psd.segment_length << " samples, 50 % overlap, "
     << a.psd.segments << " segments, one-sided.\n";
  if (!plots_dir.empty()) {
    std::filesystem::create_directories(plots_dir);
    if (plot(plots_dir, a, unit)) md << "\n![Allan deviation](plots/adev.png)\n\n![PSD](plots/psd.png)\n";
    else md << "\n(plots not drawn: gnuplot failed)\n";
  }
}

void noise_terms_into(const noise::NoiseAnalysis& a, model::ModelFile& model) {
  constexpr double kNormal975 = 1.959963984540054;
  if (!a.fit) return;
  static_assert(model::ModelFile::NoiseTerms::kKeys.size() == noise::kNoiseTerms);
  for (std::size_t i = 0; i < model.noise.values.size(); ++i) {
    const noise::NoiseCoefficient& c = a.fit->terms[i];
    if (!a.fit->fitted[i] || !c.determined) continue;
    model.noise.values[i] = c.value;
    // The interval is 95 % (NoiseFitOptions::level): its half-width over the normal quantile.
    model.noise.sd[i] = (c.upper - c.lower) / (2.0 * kNormal975);
  }
}

int run_noise(const NoiseCommandOptions& options, std::ostream& out) {
  if (options.dataset.empty() == options.event_log.empty())
    throw InputError("noise: give exactly one of --dataset DIR and --log FILE");
  if (!options.sensor.empty() && options.event_log.empty()) throw InputError("noise: --sensor goes with --log");
  if (options.tau_max_s < 0.0) throw InputError("noise: --tau-max must be >= 0");
  const bool from_log = !options.event_log.empty();
  OutputFolder folder(options.out, "noise");   // takes --out's place once whole
  noise::NoiseAnalysisOptions ao;
  ao.only_case = options.case_name;
  ao.tau_max_s = options.tau_max_s;
  // A dataset's case files are streamed (a record of hours at 10 kHz is not held); a log is fused
  // into rows first (fusion::log_dataset).
  std::string output_unit;
  const noise::NoiseAnalysis a = [&] {
    if (!from_log) {
      output_unit = dataset::read_dataset_description(options.dataset).output_unit;
      return noise::analyse_noise(options.dataset, ao);
    }
    const dataset::Dataset data = fusion::log_dataset(options.event_log, options.sensor, std::cerr);
    output_unit = data.output_unit;
    return noise::analyse_noise(data, ao);
  }();
  const std::string source = (from_log ? options.event_log : options.dataset).string();
  write_toml(folder.path() / "noise.toml", a, output_unit, source);
  {
    std::ofstream md(folder.path() / "report.md");
    write_noise_section(md, out, a, output_unit, source, options.plots ? folder.path() / "plots" : std::filesystem::path());
  }
  folder.commit();
  fmt::print(out, "wrote {} and {}\n", (folder.target() / "noise.toml").string(), (folder.target() / "report.md").string());
  return 0;
}

}  // namespace inertia::commands
