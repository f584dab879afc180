#include "analyzer/diagnose/diagnose_report.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "analyzer/report/gnuplot.hpp"

namespace inertia::diagnose {
namespace {

std::string slug(const std::string& s) {
  std::string out;
  for (char ch : s) out += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return out;
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
    md << "Coefficient, std, t and p are those of the step that found the term; the final columns hold the "
          "augmented model's, every finding refitted together.\n\n";
    if (r.estimated_square_corner_rad_s) {
      md << fmt::format("The given model had no squares and no high pass; the squares found act through eq. 12's "
                        "s/(s+b) with b = {:.5g} rad/s estimated from the data (written to the augmented model).\n\n",
                        *r.estimated_square_corner_rad_s);
    }
    md << "| # | term | effect | coefficient | std | t | p | p needed | ERR | dAIC | AR order | acts most in | final coefficient | final std |\n";
    md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (std::size_t i = 0; i < r.findings.size(); ++i) {
      const Finding& f = r.findings[i];
      md << fmt::format("| {} | `{}` | {} | {:.6g} | {:.3g} | {:.1f} | {:.2g} | {:.2g} | {:.3g} | {:.1f} | {} | {} / {} ({:.3g} {}) | {:.6g} | {:.3g} |\n",
                        i + 1, f.term, f.effect, f.coefficient, f.std, f.t, f.p_value, f.threshold_p, f.err,
                        f.delta_aic, f.ar_order, f.where_case, f.where_phase, f.where_rms, unit, f.final_coefficient,
                        f.final_std);
    }
    md << "\n";
  }
  if (!r.case_misalignments.empty()) {
    md << "## Case misalignments (test setup, not sensor effects)\n\n"
          "A rotation of a mounting (cases sharing a `mounting` label) about a case axis that the dataset's nominal "
          "m_ec does not hold; estimated on the exact rotated references, not added to the model file.\n\n";
    md << "| mounting | cases | axis | angle (deg) | std (deg) | t | p | p needed |\n|---|---|---|---|---|---|---|---|\n";
    for (const Finding& f : r.case_misalignments) {
      md << fmt::format("| {} | {} | {} | {:.5f} | {:.2g} | {:.1f} | {:.2g} | {:.2g} |\n", f.mounting,
                        fmt::join(f.mounting_cases, ", "), "xyz"[f.axis], f.angle_deg, f.angle_std_deg, f.t, f.p_value,
                        f.threshold_p);
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

  const Location& lb = r.location_before;
  const Location& la = r.location_after;
  md << "## Location by frequency band\n\n";
  md << fmt::format("Residual Welch PSD (Hann, 50% overlap{}) against the PSD the model's noise explains ({}), per "
                    "octave band; ratio = residual / model power; scaled chi-square with the Welch dof, `excess` below "
                    "alpha / all bands of all cases.\n\nBaseline: {}.\n\nFinal: {}.\n\n",
                    lb.about_means ? ", each segment about its mean" : "",
                    lb.noise, lb.verdict, la.verdict);
  for (std::size_t c = 0; c < lb.bands.size() && c < la.bands.size(); ++c) {
    const CaseBands& b = lb.bands[c];
    if (b.bands.empty()) continue;
    md << fmt::format("Case {} ({:.6g} Hz, {} segments of {}):\n\n", r.case_names[b.case_index], b.sample_rate_hz,
                      b.segments, b.segment_length);
    md << "| band (Hz) | dof | ratio before | p before | ratio after | p after |\n|---|---|---|---|---|---|\n";
    for (std::size_t k = 0; k < b.bands.size() && k < la.bands[c].bands.size(); ++k) {
      const BandTest& x = b.bands[k];
      const BandTest& y = la.bands[c].bands[k];
      md << fmt::format("| {:.4g}-{:.4g} | {:.0f} | {:.3g} | {:.2g}{} | {:.3g} | {:.2g}{} |\n", x.f_lo_hz, x.f_hi_hz, x.dof,
                        x.ratio, x.p_value, x.excess ? " excess" : "", y.ratio, y.p_value, y.excess ? " excess" : "");
    }
    md << "\n";
  }
  md << "## Location by condition\n\n";
  md << "Residual RMS per bin of reference specific-force magnitude |a| and of temperature, against the RMS the "
        "model's noise puts there; scaled chi-square, `excess` below alpha / number of bins.\n\n";
  md << "| quantity | bin | samples | expected RMS | RMS before | ratio | p | RMS after | ratio | p |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t k = 0; k < lb.conditions.size() && k < la.conditions.size(); ++k) {
    const ConditionBin& x = lb.conditions[k];
    const ConditionBin& y = la.conditions[k];
    const std::string bin = x.hi > 1e299 ? fmt::format(">= {:.3g}", x.lo) : fmt::format("{:.3g}-{:.3g}", x.lo, x.hi);
    md << fmt::format("| {} ({}) | {} | {} | {:.4g} | {:.4g} | {:.3g} | {:.2g}{} | {:.4g} | {:.3g} | {:.2g}{} |\n", x.quantity,
                      x.quantity == "T" ? "degC" : "g", bin, x.samples, x.expected_rms, x.rms, x.ratio, x.p_value,
                      x.excess ? " excess" : "", y.rms, y.ratio, y.p_value, y.excess ? " excess" : "");
  }
  md << "\n";

  if (plots) {
    const std::filesystem::path dir = out / "plots";
    std::filesystem::create_directories(dir);
    std::ofstream gp(dir / "residuals.gp");   // files named relative to plots/, where gnuplot runs
    gp << report::png_terminal(1200, 400) << "set grid\n";
    gp << fmt::format("set xlabel 't (s)'\nset ylabel 'residual ({})'\n", unit);
    for (std::size_t c = 0; c < r.case_names.size(); ++c) {
      const std::string name = "residual_" + slug(r.case_names[c]);
      write_traces(dir / (name + ".dat"), r.time[c], r.residual_before[c], r.residual_after[c]);
      gp << fmt::format("set output '{}'\nset title 'residual, case {}: before and after'\n", name + ".png",
                        r.case_names[c]);
      gp << fmt::format("plot '{0}' using 1:2 with lines lc rgb '#cc4444' title 'baseline', "
                        "'{0}' using 1:3 with lines lc rgb '#2255aa' title 'final'\n", name + ".dat");
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
                      "segments.png", unit, "segments.dat", r.noise_reference);
    // Spectra: baseline and final residual PSD with the model's noise PSD, log-log.
    gp << "unset style\nset style data lines\nset xtics norotate\nset logscale xy\nset xlabel 'f (Hz)'\n";
    gp << fmt::format("set ylabel 'PSD ({}^2/Hz)'\n", unit);
    std::vector<std::string> spectra;
    for (std::size_t c = 0; c < lb.bands.size() && c < la.bands.size(); ++c) {
      const CaseBands& b = lb.bands[c];
      if (b.plot_f.size() == 0 || b.plot_f.size() != la.bands[c].plot_f.size()) continue;
      const std::string name = "psd_" + slug(r.case_names[b.case_index]);
      {
        std::ofstream f(dir / (name + ".dat"));
        for (Eigen::Index k = 0; k < b.plot_f.size(); ++k) {
          f << fmt::format("{:.6g} {:.6g} {:.6g} {:.6g}\n", b.plot_f(k), b.plot_psd(k), la.bands[c].plot_psd(k), b.plot_model(k));
        }
      }
      gp << fmt::format("set output '{}'\nset title 'residual PSD, case {}'\n", name + ".png",
                        r.case_names[b.case_index]);
      gp << fmt::format("plot '{0}' using 1:2 lc rgb '#cc4444' title 'baseline', '{0}' using 1:3 lc rgb '#2255aa' "
                        "title 'final', '{0}' using 1:4 lc rgb 'black' dt 2 title 'model noise'\n",
                        name + ".dat");
      spectra.push_back(r.case_names[b.case_index]);
    }
    if (!lb.conditions.empty() && lb.conditions.size() == la.conditions.size()) {
      {
        std::ofstream f(dir / "conditions.dat");
        for (std::size_t k = 0; k < lb.conditions.size(); ++k) {
          const ConditionBin& x = lb.conditions[k];
          const std::string bin = x.hi > 1e299 ? fmt::format(">={:.3g}", x.lo) : fmt::format("{:.3g}-{:.3g}", x.lo, x.hi);
          f << fmt::format("\"{} {}\" {:.6g} {:.6g}\n", x.quantity, bin, x.ratio, la.conditions[k].ratio);
        }
      }
      gp << fmt::format("set output '{}'\nset title 'residual RMS / model noise RMS per condition bin'\n"
                        "unset logscale x\nset logscale y\nset style data histograms\nset style histogram clustered\n"
                        "set style fill solid 0.8\nset xtics rotate by -45\nunset xlabel\nset ylabel 'RMS ratio'\n"
                        "plot '{}' using 2:xtic(1) title 'baseline', '' using 3 title 'final', 1 with lines lc rgb "
                        "'black' title 'model noise'\n",
                        "conditions.png", "conditions.dat");
    }
    gp.close();
    md << "## Plots\n\n";
    if (report::run_gnuplot(dir / "residuals.gp")) {
      md << "![RMS per segment](plots/segments.png)\n\n";
      for (const std::string& c : spectra) md << fmt::format("![PSD {0}](plots/psd_{1}.png)\n\n", c, slug(c));
      if (!lb.conditions.empty()) md << "![RMS per condition](plots/conditions.png)\n\n";
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
