// The parameter sheet's conversions against hand-computed values, its delta-method uncertainty
// against the covariance, and its refusal to write an undetermined parameter as a number; its
// plots' data against closed forms, and its HTML page self-contained with the plots inline.
#include "analyzer/report/parameter_sheet.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <regex>
#include <set>
#include <string_view>

#include "analyzer/report/gnuplot.hpp"
#include "tests/support/skip_or_fail.hpp"
#include "common/units.hpp"

namespace inertia::report {
namespace {

const SheetEntry& entry(const ParameterSheet& s, const std::string& name) {
  for (const SheetEntry& e : s.entries) {
    if (e.name == name) return e;
  }
  throw std::runtime_error("no entry " + name);
}

const SheetPlot& plot(const ParameterSheet& s, const std::string& name) {
  for (const SheetPlot& p : s.plots) {
    if (p.name == name) return p;
  }
  throw std::runtime_error("no plot " + name);
}

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

model::ModelFile accelerometer() {
  model::ModelFile m;
  m.sensor = dataset::SensorKind::Accelerometer;
  m.output_unit = "mA";
  m.t_ref = 25.0;
  const double k1 = 0.86 / kStandardGravity;   // mA per m/s^2
  const std::vector<std::pair<const char*, double>> terms = {
      {"1", 3.44e-3}, {"a_i", k1}, {"a_i^2", k1 * 60e-6 / kStandardGravity}, {"a_i*a_p", k1 * 1e-3 / kStandardGravity},
      {"T", 0.86 * 2e-6}, {"a_i*T", k1 * 50e-6}, {"y[k-1]", 0.2}};
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  const auto n = static_cast<Eigen::Index>(m.terms.size());
  m.covariance = Eigen::MatrixXd::Zero(n, n);
  m.covariance(0, 0) = std::pow(1e-5, 2);    // the bias term's variance only
  m.range[ident::Variable::Ai] = {-2.0 * kStandardGravity, 2.0 * kStandardGravity};
  m.undetermined = {{"a_p*a_o", "its column is a combination of 1 and a_p^2 here"}};
  m.noise.values[1] = 0.86 * 30e-6;   // N on the output, mA sqrt(s)
  m.noise.sd[1] = 0.86 * 1e-6;
  return m;
}

TEST(ParameterSheet, AccelerometerParametersInIeee1293UnitsAndTheirUncertainty) {
  const ParameterSheet s = parameter_sheet(accelerometer());
  // y = (c0 + K1 a + ...) / (1 - 0.2): K1 and every coefficient gain 1/0.8; over K1 the ratios hold.
  EXPECT_NEAR(entry(s, "scale factor").value, 0.86 / 0.8, 1e-12);
  EXPECT_NEAR(entry(s, "bias").value, 3.44e-3 / 0.86 * 1e6, 1e-6);   // 4000 ug
  EXPECT_NEAR(entry(s, "second-order nonlinearity").value, 60.0, 1e-9);
  EXPECT_NEAR(entry(s, "cross-coupling i-p").value, 1000.0, 1e-9);
  EXPECT_NEAR(entry(s, "vibration rectification coefficient").value, 60.0, 1e-9);
  EXPECT_NEAR(entry(s, "bias temperature coefficient").value, 2.0, 1e-6);            // ug/degC
  EXPECT_NEAR(entry(s, "scale-factor temperature coefficient").value, 50.0, 1e-6);   // ppm/degC
  // K2 a^2 at 2 g over K1 times 2 g: 60e-6 * 4 / 2 = 120 ppm of full scale.
  EXPECT_NEAR(entry(s, "scale-factor nonlinearity over the tested range").value, 120.0, 1e-6);
  // The output's N over the static scale factor (0.86 / 0.8 mA/g): 30 x 0.8 ug/sqrt(Hz).
  EXPECT_NEAR(entry(s, "velocity random walk").value, 24.0, 1e-9);
  EXPECT_NEAR(entry(s, "velocity random walk").expanded_uncertainty, 1.6, 1e-9);
  // U of the bias: 2 x its coefficient's sd over K1 (the covariance holds nothing else), in ug.
  EXPECT_NEAR(entry(s, "bias").expanded_uncertainty, 2.0 * 1e-5 / 0.86 * 1e6, 1e-3);
  EXPECT_EQ(entry(s, "cross-coupling p-o").status, SheetEntry::Status::Undetermined);
  EXPECT_NE(entry(s, "cross-coupling p-o").reason.find("combination of 1 and a_p^2"), std::string::npos);
  EXPECT_EQ(entry(s, "odd quadratic").status, SheetEntry::Status::NotSelected);
  EXPECT_EQ(entry(s, "input-axis misalignment about p").status, SheetEntry::Status::Undetermined);
  EXPECT_EQ(entry(s, "acceleration random walk").status, SheetEntry::Status::Undetermined);
  const std::string md = sheet_markdown(s);
  EXPECT_EQ(md.find("| odd quadratic | Koq | 0"), std::string::npos) << md;   // never 0 for not selected
  EXPECT_EQ(sheet_json(s)["parameters"][0]["status"], "determined");
  EXPECT_NE(sheet_html(s).find("<table>"), std::string::npos);
}

TEST(ParameterSheet, GyroscopeParametersInIeee952Units) {
  model::ModelFile m;
  m.sensor = dataset::SensorKind::Gyroscope;
  const double sf = 2.0;   // output per rad/s
  const double drift = 10.0 / (180.0 / std::numbers::pi * 3600.0);   // 10 deg/h in rad/s
  const std::vector<std::pair<const char*, double>> terms = {
      {"1", sf * drift}, {"w_i", sf}, {"a_i", sf * drift / kStandardGravity}, {"y*T", 30e-6}};
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  const ParameterSheet s = parameter_sheet(m);
  EXPECT_NEAR(entry(s, "bias").value, 10.0, 1e-9);
  EXPECT_NEAR(entry(s, "g-sensitivity along i").value, 10.0, 1e-9);   // (deg/h)/g
  EXPECT_NEAR(entry(s, "scale-factor temperature coefficient").value, -30.0, 0.01);   // y (1 + 30e-6 T): -30 ppm/degC
  EXPECT_EQ(entry(s, "g-sensitivity along p").status, SheetEntry::Status::NotSelected);
}

TEST(ParameterSheet, NonlinearityPlotIsTheStaticResponseLessItsLeastSquaresLine) {
  model::ModelFile m = accelerometer();
  const double lo = -1.0 * kStandardGravity, hi = 3.0 * kStandardGravity;   // asymmetric: the line's slope matters
  m.range[ident::Variable::Ai] = {lo, hi};
  const double sd_k2 = 1e-3 * m.terms[2].coefficient;
  m.covariance(2, 2) = sd_k2 * sd_k2;
  const ParameterSheet s = parameter_sheet(m);
  const SheetPlot& p = plot(s, "scale-factor nonlinearity");
  ASSERT_TRUE(p.not_drawable.empty()) << p.not_drawable;
  ASSERT_EQ(p.series.size(), 1U);
  const std::vector<double>& deviation = p.series[0].y;
  const std::vector<double>& band = p.series[0].expanded_uncertainty;
  ASSERT_EQ(p.x.size() % 2, 1U);   // a middle point
  ASSERT_EQ(deviation.size(), p.x.size());
  ASSERT_EQ(band.size(), p.x.size());
  const std::size_t n = (p.x.size() - 1) / 2, middle = n;
  EXPECT_NEAR(p.x.front(), -1.0, 1e-12);   // in g
  EXPECT_NEAR(p.x.back(), 3.0, 1e-12);
  EXPECT_NEAR(p.x[middle], 1.0, 1e-12);
  // On the settled response (c0 + K1 a + c2 a^2) / (1 - 0.2) only the parabola c a^2, c = c2 / 0.8,
  // departs from a line. With m the range's middle and h its half-width, a^2 = (a - m)^2 + 2 m a - m^2,
  // and (a - m)^2 is even about m on the evenly spaced points a_j = m + h j / n (j = -n .. n), so its
  // least-squares line there is its mean h^2 (1/(2n+1)) sum_j (j/n)^2 = h^2 (n + 1) / (3 n). The
  // deviation is c ((a - m)^2 - h^2 (n + 1) / (3 n)): -c h^2 / 3 = -c (hi - lo)^2 / 12 in the middle
  // for many points.
  const double c = m.terms[2].coefficient / 0.8;
  const double h = (hi - lo) / 2.0;
  const double mean_square = h * h * static_cast<double>(n + 1) / (3.0 * static_cast<double>(n));
  const double scale = std::abs(c) * h * h;
  EXPECT_NEAR(deviation.front(), c * (h * h - mean_square), 1e-9 * scale);
  EXPECT_NEAR(deviation.back(), c * (h * h - mean_square), 1e-9 * scale);
  EXPECT_NEAR(deviation[middle], -c * mean_square, 1e-9 * scale);
  // The deviation is linear in c2 and the bias (the other coefficient with a variance) drops out
  // with the line: U = 2 sd(c2) / 0.8 |(a - m)^2 - mean|.
  EXPECT_NEAR(band.front(), 2.0 * sd_k2 / 0.8 * (h * h - mean_square), 1e-6 * 2.0 * sd_k2 / 0.8 * h * h);
  EXPECT_NEAR(band[middle], 2.0 * sd_k2 / 0.8 * mean_square, 1e-6 * 2.0 * sd_k2 / 0.8 * h * h);
  // The right axis: ppm of full scale (3 g) over the static scale factor K1 / 0.8.
  EXPECT_NEAR(p.y2_per_y, 1e6 / (m.terms[1].coefficient / 0.8 * hi), 1e-6 * p.y2_per_y);
}

TEST(ParameterSheet, AllanDeviationPlotOfTheNoiseTerms) {
  model::ModelFile m = accelerometer();
  m.noise.values[2] = 0.86 * 10e-6;   // B on the output, mA
  const ParameterSheet s = parameter_sheet(m);
  const SheetPlot& p = plot(s, "Allan deviation of the noise terms");
  ASSERT_TRUE(p.not_drawable.empty()) << p.not_drawable;
  EXPECT_TRUE(p.log_log);
  EXPECT_NEAR(p.x.front(), 1e-3, 1e-15);
  EXPECT_NEAR(p.x.back(), 1e4, 1e-8);
  ASSERT_EQ(p.series.size(), 3U);   // the sum, N, B
  EXPECT_FALSE(p.series[0].dashed);
  EXPECT_TRUE(p.series[1].dashed && p.series[2].dashed);
  const double n = entry(s, "velocity random walk").value, b = entry(s, "bias instability").value;   // ug/sqrt(Hz), ug
  for (std::size_t i = 0; i < p.x.size(); ++i) {
    const double tau = p.x[i];
    EXPECT_NEAR(p.series[1].y[i], n / std::sqrt(tau), 1e-9 * n / std::sqrt(tau));
    EXPECT_NEAR(p.series[2].y[i], std::sqrt(2.0 * std::numbers::ln2 / std::numbers::pi) * b, 1e-9 * b);
    EXPECT_NEAR(p.series[0].y[i], std::hypot(p.series[1].y[i], p.series[2].y[i]), 1e-9 * p.series[0].y[i]);
  }
}

TEST(ParameterSheet, BiasOverTheTestedTemperatures) {
  model::ModelFile m = accelerometer();
  m.range[ident::Variable::T] = {-10.0, 10.0};
  const ParameterSheet s = parameter_sheet(m);
  const SheetPlot& p = plot(s, "bias over temperature");
  ASSERT_TRUE(p.not_drawable.empty()) << p.not_drawable;
  EXPECT_NEAR(p.x.front(), 15.0, 1e-12);   // t_ref 25 degC
  EXPECT_NEAR(p.x.back(), 35.0, 1e-12);
  const double bias = entry(s, "bias").value, slope = entry(s, "bias temperature coefficient").value;
  EXPECT_NEAR(p.series[0].y.front(), bias - 10.0 * slope, 1e-6);
  EXPECT_NEAR(p.series[0].y.back(), bias + 10.0 * slope, 1e-6);
  // Only the bias term has a variance: the band is the bias entry's U at every temperature.
  ASSERT_EQ(p.series[0].expanded_uncertainty.size(), p.x.size());
  EXPECT_NEAR(p.series[0].expanded_uncertainty.front(), entry(s, "bias").expanded_uncertainty, 1e-6);
}

TEST(ParameterSheet, PageSaysWhyAPlotIsNotDrawn) {
  model::ModelFile m = accelerometer();
  m.range.clear();
  m.noise = {};
  const std::string html = sheet_html(parameter_sheet(m));
  EXPECT_EQ(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("Scale-factor nonlinearity is not plotted: the model states no characterized range of a_i"), std::string::npos)
      << html;
  EXPECT_NE(html.find("Allan deviation of the noise terms is not plotted: the model has no [noise] terms"), std::string::npos);
  EXPECT_NE(html.find("Bias over temperature is not plotted: the model states no characterized temperature range"), std::string::npos);

  model::ModelFile straight;
  straight.sensor = dataset::SensorKind::Gyroscope;
  for (const auto& [name, c] : std::vector<std::pair<const char*, double>>{{"1", 1e-4}, {"w_i", 2.0}})
    straight.terms.push_back({ident::parse_term(name), c, std::nullopt});
  straight.range[ident::Variable::Wi] = {-3.0, 5.0};
  EXPECT_NE(plot(parameter_sheet(straight), "scale-factor nonlinearity").not_drawable.find("is a straight line"), std::string::npos);
}

TEST(ParameterSheet, HtmlInlinesItsPlotsWithoutExternalResources) {
  // NOLINTNEXTLINE(cert-env33-c): whether gnuplot, which draws the plots, is on the PATH
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0)
    INERTIA_SKIP_OR_FAIL_IN_CI("gnuplot is not installed (package gnuplot-nox): the page cannot draw its plots");
  model::ModelFile m = accelerometer();
  m.range[ident::Variable::T] = {-10.0, 10.0};
  m.covariance(2, 2) = std::pow(1e-3 * m.terms[2].coefficient, 2);
  // The page's scratch directories go under a TMPDIR of the test's own, which must be empty after.
  const ScratchDirectory tmp("parameter-sheet-test");
  const char* saved = std::getenv("TMPDIR");
  const std::string saved_tmpdir = saved ? saved : "";
  ::setenv("TMPDIR", tmp.path().c_str(), 1);
  const std::string html = sheet_html(parameter_sheet(m));
  if (saved) ::setenv("TMPDIR", saved_tmpdir.c_str(), 1);
  else ::unsetenv("TMPDIR");
  EXPECT_TRUE(std::filesystem::is_empty(tmp.path()));

  EXPECT_EQ(occurrences(html, "<svg"), 3U) << html.substr(html.find("<h2>Plots"), 2000);
  EXPECT_EQ(occurrences(html, "<figcaption>"), 3U);
  EXPECT_EQ(html.find("not plotted"), std::string::npos);
  for (const char* absent : {"<?xml", "<!DOCTYPE svg", "<script", "<img", "src=", "<link", "@import", "url(http"})
    EXPECT_EQ(html.find(absent), std::string::npos) << absent;
  // The only absolute URLs are the SVG namespaces, which name a vocabulary and load nothing.
  std::string without_namespaces = html;
  for (const std::string_view ns : {"xmlns=\"http://www.w3.org/2000/svg\"", "xmlns:xlink=\"http://www.w3.org/1999/xlink\""}) {
    for (std::size_t at = without_namespaces.find(ns); at != std::string::npos; at = without_namespaces.find(ns))
      without_namespaces.erase(at, ns.size());
  }
  EXPECT_EQ(without_namespaces.find("http://"), std::string::npos);
  EXPECT_EQ(without_namespaces.find("https://"), std::string::npos);
  // Every link points inside the page, and no id is defined twice (each plot's ids are its own).
  const std::regex href(R"(href=["']([^"']*)["'])"), id(R"(\sid=["']([^"']*)["'])");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), href); it != std::sregex_iterator(); ++it)
    EXPECT_EQ((*it)[1].str().rfind('#', 0), 0U) << (*it)[0].str();
  std::set<std::string> ids;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), id); it != std::sregex_iterator(); ++it)
    EXPECT_TRUE(ids.insert((*it)[1].str()).second) << "id defined twice: " << (*it)[1].str();
  EXPECT_FALSE(ids.empty());
}

}  // namespace
}  // namespace inertia::report
