#include "analyzer/diagnose/diagnose_report.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace inertia::diagnose {
namespace {

std::string slug(const std::string& s) {
  std::string out;
  for (char ch : s) out += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return out;
}

bool run_gnuplot(const std::filesystem::path& script) {
  const std::string command = "gnuplot '" + script.string() + "' >/dev/null 2>&1";
  return std::system(command.c_str()) == 0;   // NOLINT(cert-env33-c): gnuplot is the plotting tool we chose
}

/// t, before, after; at most ~4000 points (every k-th sample) so the plot stays small.
void write_traces(const std::filesystem::path& file, const Eigen::VectorXd& t, const Eigen::VectorXd& before,
                  const Eigen::VectorXd& after) {
  std::ofstream f(file);
  const Eigen::Index step = std::max<Eigen::Index>(1, t.size() / 4000);
  for (Eigen::Index k = 0; k < t.size(); k += step) f << fmt::format("{:.6f} {:.9g} {:.9g}\n", t(k), before(k), after(k));
}

}  // namespace

std::filesystem::path write_diagnose_report(const dataset::Dataset& data, const DiagnoseResult& r,
                                            const std::string& dataset_label, const std::filesystem::path& out,
                                            bool plots) {
  std::filesystem::create_directories(out);
  std::ostringstream md;
  const std::string& unit = data.output_unit;
  const ResidualSummary& first = r.steps.front();
  const ResidualSummary& last = r.steps.back();
  md << fmt::format("# Discrepancy diagnosis of {} ({})\n\n", dataset_label, dataset::to_string(data.sensor));
  md << fmt::format("Residual = measured output - free-run simulation of the model on the measured references. "
                    "Noise reference {:.4g} {}; location test: {}. A segment is marked `excess` when its p-value "
                    "is below alpha / number of segments.\n\n",
                    r.noise_reference, unit, r.location_test);
  md << fmt::format("Overall residual RMS: baseline {:.5g} {}, final {:.5g} {} (ratio final/baseline {:.3f}).\n\n",
                    first.overall, unit, last.overall, unit, last.overall / first.overall);

  if (r.refit_only) {
    md << fmt::format("Re-estimating only the given terms would leave {:.5g} {}: the rest of the baseline gap is "
                      "coefficient error, not a missing effect.\n\n",
                      r.refit_only->overall, unit);
  }
  md << "## Findings (in the order found)\n\n";
  if (r.findings.empty()) {
    md << "No candidate term is significant: nothing the library can name is missing.\n\n";
  } else {
    md << "| # | term | effect | coefficient | std | t | p | p needed | ERR | dAIC | AR order | acts most in |\n";
    md << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (std::size_t i = 0; i < r.findings.size(); ++i) {
      const Finding& f = r.findings[i];
      md << fmt::format("| {} | `{}` | {} | {:.6g} | {:.3g} | {:.1f} | {:.2g} | {:.2g} | {:.3g} | {:.1f} | {} | {} / {} ({:.3g} {}) |\n",
                        i + 1, f.term, f.effect, f.coefficient, f.std, f.t, f.p_value, f.threshold_p, f.err,
                        f.delta_aic, f.ar_order, f.where_case, f.where_phase, f.where_rms, unit);
    }
    md << "\n";
  }
  if (!r.held_fixed.empty()) {
    md << fmt::format("Held at their given values (the data cannot estimate them): {}.\n\n",
                      fmt::join(r.held_fixed, ", "));
  }

  md << "## Residual RMS per case and phase, before and after every step\n\n";
  md << "| case | phase | samples |";
  for (const ResidualSummary& s : r.steps) md << fmt::format(" {} |", s.label);
  md << " ratio before | p before | ratio after | p after |\n|---|---|---|";
  for (std::size_t i = 0; i < r.steps.size() + 4; ++i) md << "---|";
  md << "\n";
  for (std::size_t k = 0; k < first.segments.size(); ++k) {
    const SegmentStats& b = first.segments[k];
    const SegmentStats& a = last.segments[k];
    md << fmt::format("| {} | {} | {} |", r.case_names[b.case_index], b.phase, b.samples);
    for (const ResidualSummary& s : r.steps) md << fmt::format(" {:.4g} |", s.segments[k].rms);
    md << fmt::format(" {:.3f} | {:.2g}{} | {:.3f} | {:.2g}{} |\n", b.ratio, b.p_value, b.excess ? " excess" : "",
                      a.ratio, a.p_value, a.excess ? " excess" : "");
  }
  md << "\n| case |";
  for (const ResidualSummary& s : r.steps) md << fmt::format(" {} |", s.label);
  md << "\n|---|";
  for (std::size_t i = 0; i < r.steps.size(); ++i) md << "---|";
  md << "\n";
  for (std::size_t c = 0; c < r.case_names.size(); ++c) {
    md << fmt::format("| {} |", r.case_names[c]);
    for (const ResidualSummary& s : r.steps) md << fmt::format(" {:.4g} |", s.per_case[c]);
    md << "\n";
  }
  md << "| overall |";
  for (const ResidualSummary& s : r.steps) md << fmt::format(" {:.4g} |", s.overall);
  md << "\n\n";

  if (plots) {
    const std::filesystem::path dir = out / "plots";
    std::filesystem::create_directories(dir);
    std::ofstream gp(dir / "residuals.gp");
    gp << "set terminal pngcairo size 1200,400\nset grid\n";
    gp << fmt::format("set xlabel 't (s)'\nset ylabel 'residual ({})'\n", unit);
    for (std::size_t c = 0; c < r.case_names.size(); ++c) {
      const std::string name = "residual_" + slug(r.case_names[c]);
      write_traces(dir / (name + ".dat"), r.time[c], r.residual_before[c], r.residual_after[c]);
      gp << fmt::format("set output '{}'\nset title 'residual, case {}: before and after'\n", (dir / (name + ".png")).string(),
                        r.case_names[c]);
      gp << fmt::format("plot '{0}' using 1:2 with lines lc rgb '#cc4444' title 'baseline', "
                        "'{0}' using 1:3 with lines lc rgb '#2255aa' title 'final'\n", (dir / (name + ".dat")).string());
    }
    {
      std::ofstream bars(dir / "segments.dat");
      for (std::size_t k = 0; k < first.segments.size(); ++k) {
        bars << fmt::format("\"{}/{}\" {:.9g} {:.9g}\n", r.case_names[first.segments[k].case_index],
                            first.segments[k].phase, first.segments[k].rms, last.segments[k].rms);
      }
    }
    gp << fmt::format("set output '{}'\nset title 'residual RMS per case and phase'\nset style data histograms\n"
                      "set style histogram clustered\nset style fill solid 0.8\nset xtics rotate by -45\nunset xlabel\n"
                      "set logscale y\n"
                      "set ylabel 'RMS ({})'\nplot '{}' using 2:xtic(1) title 'baseline', '' using 3 title 'final', "
                      "{} with lines lc rgb 'black' title 'noise reference'\n",
                      (dir / "segments.png").string(), unit, (dir / "segments.dat").string(), r.noise_reference);
    gp.close();
    md << "## Plots\n\n";
    if (run_gnuplot(dir / "residuals.gp")) {
      md << "![RMS per segment](plots/segments.png)\n\n";
      for (const std::string& c : r.case_names) md << fmt::format("![residual {0}](plots/residual_{1}.png)\n\n", c, slug(c));
    } else {
      md << "gnuplot did not run (is `gnuplot` installed?): the data files and scripts are in plots/.\n";
    }
  }
  const std::filesystem::path file = out / "report.md";
  std::ofstream(file) << md.str();
  return file;
}

}  // namespace inertia::diagnose
