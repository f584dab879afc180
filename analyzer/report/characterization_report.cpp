#include "analyzer/report/characterization_report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/procedure/batch_stage.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/report/gnuplot.hpp"
#include "common/units.hpp"

namespace inertia::report {
namespace {

struct CaseTraces {
  // The batch fit's residual on this case's rows: the one-step-ahead prediction error of the
  // model with its noise model (the AR-whitened innovation the t-tests and AIC use).
  Eigen::VectorXd t_innovation, innovation;
  // Free run: the model driven by the case's references alone (noise terms zero) minus the
  // measured output, as the paper's Fig. 7. A case-to-case offset or a slow misfit shows here,
  // where the noise model cannot absorb it.
  Eigen::VectorXd t, verification;
  Eigen::VectorXd a_i;           // the input at the innovation's rows, for the independence check
  std::vector<std::uint16_t> phase;   // of the free-run rows
};

CaseTraces traces_of(const dataset::Dataset& data, const procedure::CaseOutcome& outcome, const procedure::PipelineResult& r,
                     const procedure::BatchVerification& verification, std::size_t case_position, const std::string& label) {
  const procedure::BatchInnovation& innovation = verification.innovation;
  const dataset::CaseData& c = data.cases[outcome.case_index];
  const ident::SignalSet signals = ident::signals_from_case(c, outcome.m_es, data.t_ref, label);
  CaseTraces tr;
  const Eigen::Index first = ident::first_usable_row(r.terms), rows = c.size() - first;
  tr.verification = verification.free_run[case_position];
  tr.t = c.t.tail(rows);
  if (!c.phase.empty()) tr.phase.assign(c.phase.end() - rows, c.phase.end());
  const auto rows_of_case = std::find_if(innovation.cases.begin(), innovation.cases.end(),
                                         [&](const procedure::CaseRows& k) { return k.case_index == outcome.case_index; });
  if (rows_of_case == innovation.cases.end()) return tr;
  tr.innovation = innovation.values.segment(rows_of_case->begin, rows_of_case->rows);
  tr.t_innovation = c.t.segment(rows_of_case->first_sample, rows_of_case->rows);
  tr.a_i = signals.get(data.sensor == dataset::SensorKind::Gyroscope ? ident::Variable::Wi : ident::Variable::Ai)
               .segment(rows_of_case->first_sample, rows_of_case->rows);
  return tr;
}

std::string angle_cell(double angle_rad, double sd_rad) {
  if (std::isnan(angle_rad)) return "not observable (single axis)";
  if (sd_rad == 0.0) return fmt::format("{:+.4f} (held)", rad_to_deg(angle_rad));
  return fmt::format("{:+.4f} +- {:.4f}", rad_to_deg(angle_rad), rad_to_deg(sd_rad));
}

/// The turn about i: a single axis does not see it, but one set of cross-axis terms does across
/// mountings (PipelineOptions::batch_relative_twist): each further mounting's against the reference.
std::string about_i_cell(const procedure::PipelineResult& r, const procedure::MountingResult& m) {
  if (!m.twist_reference.empty()) return angle_cell(m.angles(0), m.angles_sd(0)) + " against " + m.twist_reference;
  const bool reference = std::any_of(r.mountings.begin(), r.mountings.end(),
                                     [&](const procedure::MountingResult& o) { return o.twist_reference == m.mounting; });
  return reference ? std::string("reference (its nominal frame gives p and o)") : angle_cell(std::nan(""), 0.0);
}

double rms(const Eigen::VectorXd& v) { return v.size() ? std::sqrt(v.squaredNorm() / static_cast<double>(v.size())) : NAN; }

std::string slug(const std::string& s) {
  std::string out;
  for (char ch : s) out += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return out;
}

/// Writes t, value pairs, at most ~4000 points (every k-th sample), for gnuplot.
void write_trace(const std::filesystem::path& file, const Eigen::VectorXd& t, const Eigen::VectorXd& v) {
  std::ofstream f(file);
  const Eigen::Index step = std::max<Eigen::Index>(1, t.size() / 4000);
  for (Eigen::Index k = 0; k < t.size(); k += step) f << fmt::format("{:.6f} {:.9g}\n", t(k), v(k));
}

}  // namespace

std::vector<ident::StaticGain> sensor_static_gains(const procedure::PipelineResult& result) {
  std::vector<ident::StaticGain> gains = ident::static_gains(result.fit);
  if (result.square_corner_rad_s) {
    std::erase_if(gains, [](const ident::StaticGain& g) { return procedure::is_square_term(ident::parse_term(g.term)); });
  }
  return gains;
}

WrittenReport write_characterization_report(const ReportInputs& in, const std::filesystem::path& out) {
  if (in.data == nullptr || in.result == nullptr) throw std::invalid_argument("report: no dataset or result");
  const dataset::Dataset& data = *in.data;
  const procedure::PipelineResult& r = *in.result;
  // What the model leaves of each case, computed here unless the caller has it.
  std::optional<procedure::BatchVerification> computed;
  if (in.verification == nullptr) computed = procedure::batch_verification(data, r, in.dataset_label);
  const procedure::BatchVerification& verification = in.verification != nullptr ? *in.verification : *computed;
  std::filesystem::create_directories(out);
  const std::filesystem::path plots = out / "plots";
  if (in.plots) std::filesystem::create_directories(plots);

  std::ostringstream md;
  md << fmt::format("# Characterization of {} ({})\n\n", in.dataset_label, dataset::to_string(data.sensor));
  md << fmt::format("Output unit: {}. Temperature reference t_ref = {} degC. {} test case(s).\n\n", data.output_unit,
                    data.t_ref, data.cases.size());

  if (!r.notes.empty()) {
    md << "## What this plan determines\n\n";
    for (const std::string& note : r.notes) md << "- " << note << "\n";
    md << "\n";
  }
  md << "## Misalignment (blocks 5-6, algorithm 2)\n\n"
        "Angles of the sensor frame F_S from each mounting's nominal case frame (deg; a turn about o tilts the input "
        "axis toward p, a negative turn about p tilts it toward o). The turn about i does not change a single-axis "
        "output's linear part: algorithm 1 fixes it by convention (the reference mounting's nominal frame), and the "
        "batch finds each further mounting's turn about i against it from the cross-axis terms, which one sensor "
        "shares across its mountings. An angle the mounting's excitation does not "
        "determine is held at the nominal frame; the tolerance assumed for it is in the batch's sd.\n\n";
  md << "| mounting | cases | aligned | about i | about p | about o | AR order | bias |\n|---|---|---|---|---|---|---|---|\n";
  for (const procedure::MountingResult& m : r.mountings) {
    std::string cases;
    for (std::size_t index : m.cases) cases += (cases.empty() ? "" : ", ") + data.cases[index].name;
    md << fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} |\n", m.mounting, cases, m.aligned ? "yes" : "no (held)",
                      about_i_cell(r, m),
                      angle_cell(m.angles(1), m.aligned ? m.angles_sd(1) : 0.0),
                      angle_cell(m.angles(2), m.aligned ? m.angles_sd(2) : 0.0), m.whitening_order,
                      m.known_bias ? fmt::format("{:.6g} from the other mountings", *m.known_bias) : "estimated");
  }
  md << "\n";
  for (const procedure::MountingResult& m : r.mountings) {
    if (m.aligned) {
      md << fmt::format("Mounting **{}**: {} candidate model(s) tried, fitness {:.3g}.\n\n", m.mounting, m.candidates_tried,
                        m.fitness);
      md << fmt::format("- F_E-and-F_S model: `{}`\n- its F_S model: `{}`\n", fmt::join(m.es_terms, " "),
                        fmt::join(m.s_terms, " "));
    } else {
      md << fmt::format("Mounting **{}**: not aligned.\n\n", m.mounting);
    }
    for (const std::string& h : m.held) md << "- " << h << "\n";
    if (!m.excluded.empty()) md << fmt::format("- left out (not identifiable here): `{}`\n", fmt::join(m.excluded, " "));
    md << "\n";
  }
  {
    const Eigen::Vector3d a = procedure::rotation_vector(r.m_cs);
    md << fmt::format("The sensor's M_C^S (model file): about p {:+.4f} deg, about o {:+.4f} deg, from the first aligned "
                      "mounting.\n\n",
                      rad_to_deg(a(1)), rad_to_deg(a(2)));
  }
  md << "| case | kind | M_E^S input axis | angle to nominal IRA (deg) |" << (in.truth ? " error vs truth (deg) |" : "") << "\n";
  md << "|---|---|---|---|" << (in.truth ? "---|" : "") << "\n";
  for (const procedure::CaseOutcome& c : r.cases) {
    const dataset::CaseData& cd = data.cases[c.case_index];
    const double to_nominal = rad_to_deg(frames::axis_angle_between(cd.m_ec.row(0).transpose(), c.m_es.row(0).transpose()));
    md << fmt::format("| {} | {} | [{:+.6f}, {:+.6f}, {:+.6f}] | {:.4f} |", cd.name, dataset::to_string(cd.kind), c.m_es(0, 0),
                      c.m_es(0, 1), c.m_es(0, 2), to_nominal);
    if (in.truth) {
      const auto it = in.truth->m_es.find(cd.name);
      md << (it == in.truth->m_es.end() ? std::string(" - |")
                                        : fmt::format(" {:.5f} |", rad_to_deg(procedure::input_axis_error(it->second, c.m_es))));
    }
    md << "\n";
  }

  md << fmt::format("\n## Model (blocks 9-11)\n\n{} rows; innovation standard deviation {:.4g} {} (the residual after "
                    "the AR({}) noise model); AIC {:.6g}.{}\n\n",
                    r.fit.residuals.size(), std::sqrt(verification.innovation.variance), data.output_unit,
                    r.whitening.size(), r.aic,
                    r.rows_filtered ? ""
                                    : " The rows were not filtered by the noise model: ULS's correction for the "
                                      "output-multiplied terms holds for a white equation error, so the noise model "
                                      "enters the coefficients' covariance instead (the sandwich under its spectrum), "
                                      "and AIC is the unfiltered residual's.");
  if (r.fit.noise_iterations > 0 && !r.fit.converged)
    md << fmt::format("The noise lags' extended least squares did not settle: after {} passes the coefficients still moved "
                      "by {:.2g} of their norm from one pass to the next. ELS converges only when the noise's moving "
                      "average C(q) makes 1/C(q) - 1/2 strictly positive real; these coefficients carry that wander "
                      "beside their standard deviations. A fit without noise lags (`--noise-lags 0`) has no such pass.\n\n",
                      r.fit.noise_iterations, r.fit.noise_last_change);
  md << fmt::format("Inference: the cases' contiguous phases are {} clusters; the offsets between them that the noise model "
                    "does not explain (placement of a pose, drift, 1/f noise below the AR model's reach) have sd {:.3g} {} "
                    "(between-phase dof {}), and every standard deviation includes what they do to the estimate; a term "
                    "they dominate is tested on the between-phase dof (samples within a phase are not independent "
                    "information).\n\n",
                    r.inference.clusters, std::sqrt(r.inference.tau2), data.output_unit, r.inference.between_dof);
  if (r.inference.weights.size() != 0)
    md << fmt::format("The offsets reach the phases unequally{}, so each phase's mean is weighed by the share of its "
                      "information its offset leaves (random effects; weights {:.3g} to {:.3g}): what the phases the "
                      "offsets hardly reach determine comes from those (on a tumble, the bias and scale factor from the "
                      "poses with the input axis vertical, as the classical six-position formulas take them).\n\n",
                      r.inference.tau2_per_loading > 0.0 ? " (a placement tilt moves a pose's output in proportion to the "
                                                           "specific force across the input axis)"
                                                         : "",
                      r.inference.weights.minCoeff(), r.inference.weights.maxCoeff());
  if (!r.undetermined.empty()) {
    md << "Not determined by this plan:\n\n";
    for (const procedure::UndeterminedTerm& u : r.undetermined) md << fmt::format("- `{}`: {}\n", u.term, u.reason);
    md << "\n";
  }
  // A dynamic model's coefficients are not the sensor's gains; its truth is scored on the static
  // gains below instead.
  const std::vector<ident::StaticGain> gains = sensor_static_gains(r);
  const bool score_coefficients = in.truth && gains.empty();
  // "truth | (est - truth)/std" cells for an estimate of `term`.
  const auto truth_cells = [&](const std::string& term, double estimate, double std_dev) {
    const auto it = in.truth->terms.find(term);
    return it == in.truth->terms.end() ? std::string(" - | - |")
                                       : fmt::format(" {:.6g} | {:+.1f} |", it->second, (estimate - it->second) / std_dev);
  };
  md << "| term | physical meaning | coefficient | std | t | p |" << (score_coefficients ? " truth | (est - truth)/std |" : "") << "\n";
  md << "|---|---|---|---|---|---|" << (score_coefficients ? "---|---|" : "") << "\n";
  for (Eigen::Index j = 0; j < r.fit.theta.size(); ++j) {
    const std::string& name = r.fit.labels[static_cast<std::size_t>(j)];
    const bool process = j < r.fit.process_terms;
    const std::string meaning = ident::physical_name(ident::parse_term(name), data.sensor);
    const double t = process ? r.t_test.t(j) : r.fit.theta(j) / r.fit.std_dev(j);
    const double p = process ? r.t_test.p_value(j) : ident::student_t_two_sided_p(t, static_cast<double>(r.fit.residuals.size()));
    md << fmt::format("| `{}` | {} | {:.6g} | {:.3g} | {:.1f} | {:.2g} |", name, meaning, r.fit.theta(j), r.fit.std_dev(j), t, p);
    if (score_coefficients) md << truth_cells(name, r.fit.theta(j), r.fit.std_dev(j));
    md << "\n";
  }
  if (!gains.empty()) {
    md << "\nStatic gains: with output lags a coefficient is not the sensor's gain. A term with its lagged copies, "
          "over 1 - the sum of the y-lag coefficients, is (sd by the delta method from the fit's covariance). Squares "
          "under eq. 12's high pass have no static response and are left out.\n\n";
    md << "| term | from | static gain | std |" << (in.truth ? " truth | (est - truth)/std |" : "") << "\n";
    md << "|---|---|---|---|" << (in.truth ? "---|---|" : "") << "\n";
    for (const ident::StaticGain& g : gains) {
      md << fmt::format("| `{}` | `{}` | {:.6g} | {:.3g} |", g.term, fmt::join(g.lagged, " "), g.gain, g.std_dev);
      if (in.truth) md << truth_cells(g.term, g.gain, g.std_dev);
      md << "\n";
    }
  }

  md << "\n## Residuals and verification per case and phase\n\n"
        "Free run: the model driven by the case's references alone (noise terms zero) minus the measured output, as "
        "the paper's Fig. 7; its mean per case is tested against its own long-run variance (effective N from the lag-1 "
        "autocorrelation), so an offset between cases shows here even where the noise model absorbs it. Innovation: "
        "the batch fit's one-step residual after the AR noise model; whiteness: its autocorrelation, lags 1-20, and "
        "its cross-correlation with the sensitive input, lags -20..20, against 95% bands.\n\n";
  md << "| case | phase | samples | free-run RMS | free-run mean | mean test p | innovation RMS | whiteness | independent of input |\n";
  md << "|---|---|---|---|---|---|---|---|---|\n";
  const int plot_height = 260 * static_cast<int>(std::max<std::size_t>(1, data.cases.size()));
  std::ostringstream gp;
  if (in.plots) {
    gp << png_terminal(1200, plot_height);
    gp << "set output 'verification.png'\n";   // names relative to plots/, where gnuplot runs
    gp << "set multiplot layout " << data.cases.size() << ",1 title 'Free-run error per case (model - measured, "
       << data.output_unit << ")'\nset grid\nset xlabel 't (s)'\n";
  }
  std::ostringstream gp_res;
  if (in.plots) {
    gp_res << png_terminal(1200, plot_height);
    gp_res << "set output 'residuals.png'\n";
    gp_res << "set multiplot layout " << data.cases.size() << ",1 title 'Innovation per case (one-step residual after the noise model, "
           << data.output_unit << ")'\nset grid\nset xlabel 't (s)'\n";
  }
  for (std::size_t position = 0; position < r.cases.size(); ++position) {
    const procedure::CaseOutcome& c = r.cases[position];
    const dataset::CaseData& cd = data.cases[c.case_index];
    const CaseTraces tr = traces_of(data, c, r, verification, position, in.dataset_label);
    // Up to 20 lags: a case a lossy log cut short may have fewer rows (then none is tested).
    const int lags = static_cast<int>(std::min<Eigen::Index>(20, tr.innovation.size() - 1));
    ident::CorrelationCheck white, indep;
    const auto verdict = [](const ident::CorrelationCheck& c) { return c.lags.size() == 0 ? "too short" : c.pass ? "pass" : "fail"; };
    if (lags >= 1) {
      white = ident::residual_autocorrelation(tr.innovation, lags);
      indep = ident::residual_input_correlation(tr.innovation, tr.a_i, lags);
    }
    const ident::ResidualMeanTest mean = ident::residual_mean_test(tr.verification);
    const std::string innovation_rms = tr.innovation.size() > 0 ? fmt::format("{:.4g}", rms(tr.innovation)) : "-";
    md << fmt::format("| {} | all | {} | {:.4g} | {:+.3g} | {:.2g} | {} | {} ({}/{} lags out) | {} ({}/{}) |\n", cd.name,
                      tr.verification.size(), rms(tr.verification), tr.verification.mean(), mean.p_value, innovation_rms,
                      verdict(white), white.outside, white.lags.size(), verdict(indep),
                      indep.outside, indep.lags.size());
    for (std::size_t p = 0; p < cd.phase_names.size() && !tr.phase.empty(); ++p) {
      const auto rows = static_cast<Eigen::Index>(std::count(tr.phase.begin(), tr.phase.end(), p));
      if (rows == 0) continue;
      // Eigen's own storage: a vectorized sum starts at the first aligned element, which for a
      // map over malloc'd memory would depend on where the heap put it.
      Eigen::VectorXd vv(rows);
      Eigen::Index i = 0;
      for (std::size_t k = 0; k < tr.phase.size(); ++k) {
        if (tr.phase[k] == p) vv(i++) = tr.verification(static_cast<Eigen::Index>(k));
      }
      md << fmt::format("| {} | {} | {} | {:.4g} | {:+.3g} | | | | |\n", cd.name, cd.phase_names[p], rows, rms(vv), vv.mean());
    }
    if (in.plots) {
      const std::filesystem::path ver_file = plots / ("verification_" + slug(cd.name) + ".dat");
      const std::filesystem::path res_file = plots / ("residual_" + slug(cd.name) + ".dat");
      write_trace(ver_file, tr.t, tr.verification);
      write_trace(res_file, tr.t_innovation, tr.innovation);
      gp << "set title " << gnuplot_quoted(cd.name) << "\nplot " << gnuplot_quoted(ver_file.filename().string())
         << " with lines notitle\n";
      gp_res << "set title " << gnuplot_quoted(cd.name) << "\nplot " << gnuplot_quoted(res_file.filename().string())
             << " with lines notitle\n";
    }
  }
  if (in.plots) {
    gp << "unset multiplot\n";
    gp_res << "unset multiplot\n";
    std::ofstream(plots / "verification.gp") << gp.str();
    std::ofstream(plots / "residuals.gp") << gp_res.str();
  }
  WrittenReport written;
  written.file = out / "report.md";
  std::ofstream(written.file) << md.str();
  if (in.plots) written.plots = std::make_unique<GnuplotRuns>(std::array{plots / "verification.gp", plots / "residuals.gp"});
  return written;
}

void finish_report_plots(WrittenReport& report) {
  if (!report.plots) return;
  const std::vector<bool> drawn_each = report.plots->wait();
  report.plots.reset();
  std::ofstream md(report.file, std::ios::app);
  md << "\n## Plots\n\n";
  if (std::all_of(drawn_each.begin(), drawn_each.end(), [](bool drawn) { return drawn; })) {
    md << "![verification error per case](plots/verification.png)\n\n![residuals per case](plots/residuals.png)\n";
  } else {
    md << "gnuplot did not run (is `gnuplot` installed?): the data files and scripts are in plots/.\n";
  }
}

}  // namespace inertia::report
