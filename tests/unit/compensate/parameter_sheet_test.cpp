// The parameter sheet's conversions against hand-computed values, its delta-method uncertainty
// against the covariance, and its refusal to write an undetermined parameter as a number.
#include "analyzer/report/parameter_sheet.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "common/units.hpp"

namespace inertia::report {
namespace {

const SheetEntry& entry(const ParameterSheet& s, const std::string& name) {
  for (const SheetEntry& e : s.entries) {
    if (e.name == name) return e;
  }
  throw std::runtime_error("no entry " + name);
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

}  // namespace
}  // namespace inertia::report
