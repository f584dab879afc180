#include "analyzer/report/characterization_report.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/units.hpp"

namespace inertia::report {
namespace {

struct CaseTraces {
  Eigen::VectorXd t;             // s, of each row
  Eigen::VectorXd residual;      // one-step-ahead: y - Phi theta (measured y in the lags)
  Eigen::VectorXd verification;  // free-run model output - measured y
  Eigen::VectorXd a_i;           // the input, for the independence check
  std::vector<std::uint16_t> phase;
};

CaseTraces traces_of(const dataset::Dataset& data, std::size_t index, const procedure::PipelineResult& r,
                     const std::string& label) {
  const dataset::CaseData& c = data.cases[index];
  const ident::SignalSet signals = ident::signals_from_case(c, r.cases[index].m_es, data.t_ref, label);
  const Eigen::VectorXd theta = r.fit.process_theta();
  const ident::Regression reg = ident::build_regression(r.terms, signals);
  CaseTraces tr;
  const Eigen::Index first = reg.first_row, rows = reg.y.size();
  tr.residual = reg.y - reg.phi * theta;
  tr.verification = procedure::simulate_model(r.terms, theta, signals, first, r.square_corner_rad_s, c.sample_period_s) -
                    c.y.tail(rows);
  tr.t = c.t.tail(rows);
  tr.a_i = signals.get(ident::Variable::Ai).tail(rows);
  if (!c.phase.empty()) tr.phase.assign(c.phase.end() - rows, c.phase.end());
  return tr;
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

bool run_gnuplot(const std::filesystem::path& script) {
  const std::string command = "gnuplot '" + script.string() + "' >/dev/null 2>&1";
  return std::system(command.c_str()) == 0;   // NOLINT(cert-env33-c): gnuplot is the plotting tool we chose
}

}  // namespace

std::vector<ident::StaticGain> sensor_static_gains(const procedure::PipelineResult& result) {
  std::vector<ident::StaticGain> gains = ident::static_gains(result.fit);
  if (result.square_corner_rad_s) {
    std::erase_if(gains, [](const ident::StaticGain& g) { return procedure::is_square_term(ident::parse_term(g.term)); });
  }
  return gains;
}

std::filesystem::path write_characterization_report(const ReportInputs& in, const std::filesystem::path& out) {
  if (in.data == nullptr || in.result == nullptr) throw std::invalid_argument("report: no dataset or result");
  const dataset::Dataset& data = *in.data;
  const procedure::PipelineResult& r = *in.result;
  std::filesystem::create_directories(out);
  const std::filesystem::path plots = out / "plots";
  if (in.plots) std::filesystem::create_directories(plots);

  std::ostringstream md;
  md << fmt::format("# Characterization of {} ({})\n\n", in.dataset_label, dataset::to_string(data.sensor));
  md << fmt::format("Output unit: {}. Temperature reference t_ref = {} degC. {} test case(s).\n\n", data.output_unit,
                    data.t_ref, data.cases.size());

  md << "## Misalignment (blocks 5-6, algorithm 2)\n\n";
  for (const procedure::MountingResult& m : r.mountings) {
    md << fmt::format("Mounting **{}**: {} candidate model(s) tried, fitness {:.3g}, AR noise model order {}{}.\n\n",
                      m.mounting, m.candidates_tried, m.fitness, m.whitening_order,
                      m.known_bias ? fmt::format(", bias {:.6g} taken from the other mountings", *m.known_bias) : "");
    md << fmt::format("- F_E-and-F_S model: `{}`\n- its F_S model: `{}`\n", fmt::join(m.es_terms, " "),
                      fmt::join(m.s_terms, " "));
    if (!m.excluded.empty()) md << fmt::format("- left out (not identifiable here): `{}`\n", fmt::join(m.excluded, " "));
    md << "\n";
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

  md << fmt::format("\n## Model (blocks 9-11)\n\n{} rows; residual standard deviation {:.4g} {}; residual mean test p = {:.3g} "
                    "(effective N {:.0f}); AIC {:.6g}; AR noise model order {}.\n\n",
                    r.fit.residuals.size(), std::sqrt(r.fit.residual_variance), data.output_unit, r.residual_mean.p_value,
                    r.residual_mean.effective_samples, r.aic, r.whitening.size());
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
        "Residual: one-step-ahead prediction error with the measured output in the lags. Verification: the model run "
        "free on the case's references (noise terms zero) minus the measured output, as the paper's Fig. 7. Whiteness: "
        "residual autocorrelation, lags 1-20, and cross-correlation with a_i, lags -20..20, against 95% bands.\n\n";
  md << "| case | phase | samples | residual RMS | residual mean | verification RMS | whiteness | independent of a_i |\n";
  md << "|---|---|---|---|---|---|---|---|\n";
  std::ostringstream gp;
  if (in.plots) {
    gp << "set terminal pngcairo size 1200," << 260 * std::max<std::size_t>(1, data.cases.size()) << "\n";
    gp << "set output '" << (plots / "verification.png").string() << "'\n";
    gp << "set multiplot layout " << data.cases.size() << ",1 title 'Verification error per case (model - measured, "
       << data.output_unit << ")'\nset grid\nset xlabel 't (s)'\n";
  }
  std::ostringstream gp_res;
  if (in.plots) {
    gp_res << "set terminal pngcairo size 1200," << 260 * std::max<std::size_t>(1, data.cases.size()) << "\n";
    gp_res << "set output '" << (plots / "residuals.png").string() << "'\n";
    gp_res << "set multiplot layout " << data.cases.size() << ",1 title 'One-step-ahead residual per case ("
           << data.output_unit << ")'\nset grid\nset xlabel 't (s)'\n";
  }
  for (const procedure::CaseOutcome& c : r.cases) {
    const dataset::CaseData& cd = data.cases[c.case_index];
    const CaseTraces tr = traces_of(data, c.case_index, r, in.dataset_label);
    const auto white = ident::residual_autocorrelation(tr.residual, 20);
    const auto indep = ident::residual_input_correlation(tr.residual, tr.a_i, 20);
    md << fmt::format("| {} | all | {} | {:.4g} | {:+.3g} | {:.4g} | {} ({}/{} lags out) | {} ({}/{}) |\n", cd.name,
                      tr.residual.size(), rms(tr.residual), tr.residual.mean(), rms(tr.verification),
                      white.pass ? "pass" : "fail", white.outside, white.lags.size(), indep.pass ? "pass" : "fail",
                      indep.outside, indep.lags.size());
    for (std::size_t p = 0; p < cd.phase_names.size() && !tr.phase.empty(); ++p) {
      std::vector<double> res, ver;
      for (std::size_t k = 0; k < tr.phase.size(); ++k) {
        if (tr.phase[k] == p) {
          res.push_back(tr.residual(static_cast<Eigen::Index>(k)));
          ver.push_back(tr.verification(static_cast<Eigen::Index>(k)));
        }
      }
      if (res.empty()) continue;
      const Eigen::Map<Eigen::VectorXd> rv(res.data(), static_cast<Eigen::Index>(res.size()));
      const Eigen::Map<Eigen::VectorXd> vv(ver.data(), static_cast<Eigen::Index>(ver.size()));
      md << fmt::format("| {} | {} | {} | {:.4g} | {:+.3g} | {:.4g} | | |\n", cd.name, cd.phase_names[p], res.size(),
                        rms(rv), rv.mean(), rms(vv));
    }
    if (in.plots) {
      const std::filesystem::path ver_file = plots / ("verification_" + slug(cd.name) + ".dat");
      const std::filesystem::path res_file = plots / ("residual_" + slug(cd.name) + ".dat");
      write_trace(ver_file, tr.t, tr.verification);
      write_trace(res_file, tr.t, tr.residual);
      gp << "set title '" << cd.name << "'\nplot '" << ver_file.string() << "' with lines notitle\n";
      gp_res << "set title '" << cd.name << "'\nplot '" << res_file.string() << "' with lines notitle\n";
    }
  }
  if (in.plots) {
    gp << "unset multiplot\n";
    gp_res << "unset multiplot\n";
    std::ofstream(plots / "verification.gp") << gp.str();
    std::ofstream(plots / "residuals.gp") << gp_res.str();
    const bool drawn = run_gnuplot(plots / "verification.gp") && run_gnuplot(plots / "residuals.gp");
    md << "\n## Plots\n\n";
    if (drawn) {
      md << "![verification error per case](plots/verification.png)\n\n![residuals per case](plots/residuals.png)\n";
    } else {
      md << "gnuplot did not run (is `gnuplot` installed?): the data files and scripts are in plots/.\n";
    }
  }
  const std::filesystem::path file = out / "report.md";
  std::ofstream(file) << md.str();
  return file;
}

}  // namespace inertia::report
