// The discrepancy workflow's contract at the edges: the candidate library, bad input (unknown
// term, wrong sensor kind, a missing column) as InputError naming what is wrong, and a small
// synthetic case where the hidden term and its coefficient are known exactly.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <unistd.h>

#include "analyzer/commands/diagnose.hpp"
#include "analyzer/diagnose/candidate_library.hpp"
#include "analyzer/diagnose/discrepancy.hpp"
#include "analyzer/ident/regressors.hpp"
#include "common/input_error.hpp"

namespace inertia::diagnose {
namespace {

namespace fs = std::filesystem;

/// One rotation-free "shaker" case: white references on three axes, y from `truth` plus white noise.
dataset::Dataset synthetic(const std::vector<std::pair<std::string, double>>& truth, double noise_sd, unsigned seed,
                           bool with_temp = false) {
  dataset::Dataset d;
  d.output_unit = "mA";
  dataset::CaseData c;
  c.name = "vib";
  c.kind = dataset::CaseKind::Shaker;
  c.file = "vib.csv";
  const Eigen::Index n = 20000;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-3);
  c.sample_period_s = 1e-3;
  c.a_e.resize(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) {
    c.a_e(k, 0) = 30.0 * g(rng);
    c.a_e(k, 1) = 20.0 * g(rng);
    c.a_e(k, 2) = 9.80665 + 10.0 * g(rng);
  }
  if (with_temp) c.temp = Eigen::VectorXd::LinSpaced(n, 10.0, 40.0);
  c.y = Eigen::VectorXd::Zero(n);
  d.cases.push_back(c);
  ident::SignalSet s = ident::signals_from_case(d.cases[0], Eigen::Matrix3d::Identity(), d.t_ref);
  for (const auto& [name, coefficient] : truth) {
    const ident::Term t = ident::parse_term(name);
    const ident::Regression reg = ident::build_regression(std::span<const ident::Term>(&t, 1), s);
    d.cases[0].y += coefficient * reg.phi.col(0);
  }
  for (Eigen::Index k = 0; k < n; ++k) d.cases[0].y(k) += noise_sd * g(rng);
  return d;
}

model::ModelFile model_of(const std::vector<std::pair<std::string, double>>& terms, double white_sd) {
  model::ModelFile m;
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  m.white_sd = white_sd;
  return m;
}

TEST(CandidateLibrary, CoversTheEquationsAndIsCanonical) {
  const auto acc = candidate_library(dataset::SensorKind::Accelerometer);
  std::set<std::string> names;
  for (const ident::Term& t : acc) names.insert(t.to_string());
  EXPECT_EQ(names.size(), acc.size()) << "duplicates";
  for (const char* need : {"1", "a_i", "a_p", "a_o", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o", "abs(a_i)",
                           "a_i*abs(a_i)", "sign(a_i)", "T", "a_i*T", "y[k-1]", "a_i^2[k-1]"}) {
    EXPECT_TRUE(names.count(need)) << need;
  }
  std::set<std::string> gyro;
  for (const ident::Term& t : candidate_library(dataset::SensorKind::Gyroscope)) gyro.insert(t.to_string());
  for (const char* need : {"w_i", "a_i", "a_p", "a_o", "y*w_i", "y*T", "T"}) EXPECT_TRUE(gyro.count(need)) << need;
  EXPECT_STREQ(ident::physical_name(ident::parse_term("a_i"), dataset::SensorKind::Gyroscope), "g-sensitivity");
}

TEST(Diagnose, NamesAHiddenTermWithItsCoefficient) {
  const double sd = 1e-3;
  const auto d = synthetic({{"1", 0.01}, {"a_i", 0.09}, {"a_i*a_o", 4e-5}}, sd, 1);
  const DiagnoseResult r = diagnose(d, model_of({{"1", 0.01}, {"a_i", 0.09}}, sd), DiagnoseOptions{}, "synthetic");
  ASSERT_EQ(r.findings.size(), 1U);
  EXPECT_EQ(r.findings[0].term, "a_i*a_o");
  EXPECT_LT(std::abs(r.findings[0].coefficient - 4e-5), 3.0 * r.findings[0].std);
  EXPECT_GT(r.steps.front().overall, 2.0 * sd);
  EXPECT_LT(std::abs(r.steps.back().overall / sd - 1.0), 0.05);   // 20000 samples: RMS to ~0.5%
  EXPECT_TRUE(r.steps.front().segments.front().excess);
  EXPECT_FALSE(r.steps.back().segments.front().excess);
}

TEST(Diagnose, NothingMissingNothingFound) {
  const double sd = 1e-3;
  const auto truth = std::vector<std::pair<std::string, double>>{{"1", 0.01}, {"a_i", 0.09}};
  const DiagnoseResult r = diagnose(synthetic(truth, sd, 2), model_of(truth, sd), DiagnoseOptions{}, "synthetic");
  EXPECT_TRUE(r.findings.empty()) << r.findings.front().term;
  EXPECT_EQ(r.steps.size(), 1U);
}

TEST(Diagnose, GyroscopeModelOnAccelerometerDataIsBadInput) {
  const auto d = synthetic({{"a_i", 0.09}}, 1e-3, 3);
  model::ModelFile m = model_of({{"w_i", 1.0}}, 1e-3);
  m.sensor = dataset::SensorKind::Gyroscope;
  try {
    (void)diagnose(d, m, DiagnoseOptions{}, "synthetic");
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gyroscope"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("accelerometer"), std::string::npos) << e.what();
  }
}

TEST(Diagnose, MissingColumnNamesTermAndColumn) {
  const auto d = synthetic({{"a_i", 0.09}}, 1e-3, 4);   // no temp column
  try {
    (void)diagnose(d, model_of({{"a_i", 0.09}, {"a_i*T", 1e-5}}, 1e-3), DiagnoseOptions{}, "synthetic");
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a_i*T"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("temp"), std::string::npos) << e.what();
  }
}

class DiagnoseCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("diagnose_cmd_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    dataset::write_dataset(dir_ / "data", synthetic({{"1", 0.01}, {"a_i", 0.09}, {"a_i*a_p", 5e-5}}, 1e-3, 5));
  }
  void TearDown() override { fs::remove_all(dir_); }
  commands::DiagnoseCommandOptions options(const std::string& model_text) {
    std::ofstream(dir_ / "model.toml") << model_text;
    commands::DiagnoseCommandOptions o;
    o.model = dir_ / "model.toml";
    o.dataset = dir_ / "data";
    o.json = dir_ / "out" / "diag.json";
    o.plots = false;
    return o;
  }
  fs::path dir_;
};

TEST_F(DiagnoseCommand, UnknownTermInModelFileIsBadInput) {
  std::ostringstream out;
  try {
    (void)commands::run_diagnose(options("sensor = \"accelerometer\"\nm_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n[terms]\n\"1\" = 0.01\n\"a_q\" = 0.09\n"), out);
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a_q"), std::string::npos) << e.what();
  }
}

TEST_F(DiagnoseCommand, WritesJsonAugmentedModelAndReport) {
  auto o = options("sensor = \"accelerometer\"\nm_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n[terms]\n\"1\" = 0.01\n\"a_i\" = 0.09\n[noise]\nwhite_sd = 1e-3\n");
  o.report = dir_ / "report";
  std::ostringstream out;
  ASSERT_EQ(commands::run_diagnose(o, out), 0) << out.str();
  std::ifstream j(o.json);
  const std::string text((std::istreambuf_iterator<char>(j)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"findings\""), std::string::npos);
  EXPECT_NE(text.find("\"a_i*a_p\""), std::string::npos);
  // The contract (docs/design.md): residual_rms is a number, the per-case detail sits beside it.
  const nlohmann::json parsed = nlohmann::json::parse(text);
  for (const char* step : {"baseline", "final"}) {
    ASSERT_TRUE(parsed[step]["residual_rms"].is_number()) << step << ": " << parsed[step]["residual_rms"].dump();
    EXPECT_GT(parsed[step]["residual_rms"].get<double>(), 0.0) << step;
    EXPECT_TRUE(parsed[step]["residual_rms_by_case"].is_object()) << step;
  }
  // The missing a_i*a_p is found, so the final residual is smaller than the baseline's.
  EXPECT_LT(parsed["final"]["residual_rms"].get<double>(), parsed["baseline"]["residual_rms"].get<double>());
  const model::ModelFile m = model::read_model(o.report / "model-augmented.toml");
  ASSERT_TRUE(m.coefficient(ident::parse_term("a_i*a_p")).has_value());
  EXPECT_TRUE(fs::exists(o.report / "report.md"));
}

}  // namespace
}  // namespace inertia::diagnose
