// Model file contract (docs/design.md, "Model file"; analyzer/model/model_file.hpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "analyzer/model/model_file.hpp"
#include "common/input_error.hpp"

namespace inertia::model {
namespace {

using ident::parse_term;

ModelFile sample_model() {
  ModelFile m;
  m.sensor = dataset::SensorKind::Accelerometer;
  m.m_cs = frames::about_third_axis(1.4e-3) * frames::about_second_axis(-1.4e-3);
  // Not in canonical order on purpose: the file keeps the order it is given.
  m.terms = {{parse_term("a_i"), 0.0877, 2.5e-6},
             {parse_term("1"), 3.44e-3, std::nullopt},
             {parse_term("a_p*a_i"), -1.0 / 3.0, 1e-9},
             {parse_term("a_o[k-1]^2"), 6e-5, std::nullopt},
             {parse_term("y[k-1]"), 0.5, std::nullopt}};
  m.white_sd = 1.0e-4;
  m.noise.values[1] = 2.5e-6;   // N
  m.noise.values[2] = 2.0e-5;   // B
  m.noise.sd[2] = 1.0 / 3.0 * 1e-6;
  return m;
}

InputError parse_error(const std::string& text) {
  try {
    (void)parse_model(text, "model.toml");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return InputError("none");
}

TEST(ModelFile, RoundTripIsExactAndKeepsOrder) {
  const ModelFile m = sample_model();
  const std::filesystem::path dir = std::filesystem::path(INERTIA_BINARY_DIR) / "test-data" / "model";
  std::filesystem::create_directories(dir);
  write_model(dir / "model.toml", m);
  const ModelFile r = read_model(dir / "model.toml");
  EXPECT_EQ(r.sensor, m.sensor);
  EXPECT_EQ(r.m_cs, m.m_cs);   // bitwise
  ASSERT_EQ(r.terms.size(), m.terms.size());
  for (std::size_t i = 0; i < m.terms.size(); ++i) {
    EXPECT_EQ(r.terms[i].term, m.terms[i].term) << i;
    EXPECT_EQ(r.terms[i].coefficient, m.terms[i].coefficient) << i;
    EXPECT_EQ(r.terms[i].std, m.terms[i].std) << i;
  }
  EXPECT_EQ(r.white_sd, m.white_sd);
  EXPECT_EQ(r.noise.values, m.noise.values);
  EXPECT_EQ(r.noise.sd, m.noise.sd);
  EXPECT_EQ(format_model(r), format_model(m));
  EXPECT_EQ(r.coefficient(parse_term("a_i*a_p")), -1.0 / 3.0);
  EXPECT_FALSE(r.coefficient(parse_term("a_i^2")).has_value());

  const std::string text = format_model(m);
  EXPECT_NE(text.find("[terms]\n\"a_i\" = 0.0877\n\"1\" = 0.00344\n\"a_i*a_p\" = "), std::string::npos) << text;
  EXPECT_NE(text.find("\"a_o^2[k-1]\" = 6e-05\n"), std::string::npos) << text;
  EXPECT_NE(text.find("[noise]\nwhite_sd = 1e-04\nN = 2.5e-06\nB = 2e-05\n\n[noise.std]\nB = 3.333333333333333e-07\n"),
            std::string::npos)
      << text;
}

TEST(ModelFile, ReadsTheDesignExampleWithIntegersAndWithoutOptionalTables) {
  const ModelFile m = parse_model(R"(sensor = "gyroscope"
m_cs = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
[terms]
"1" = 3.44e-3
"w_i" = 1
"w_i * y" = -2e-7
)",
                                  "example.toml");
  EXPECT_EQ(m.sensor, dataset::SensorKind::Gyroscope);
  EXPECT_EQ(m.m_cs, frames::Dcm::Identity());
  ASSERT_EQ(m.terms.size(), 3u);
  EXPECT_EQ(m.terms[2].term.to_string(), "y*w_i");
  EXPECT_EQ(m.terms[1].coefficient, 1.0);
  EXPECT_FALSE(m.white_sd.has_value());
  EXPECT_FALSE(m.terms[0].std.has_value());
}

TEST(ModelFile, UnknownTermIsNamedWithItsLine) {
  const InputError e = parse_error(R"(sensor = "accelerometer"
m_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[terms]
"1" = 3.44e-3
"a_q" = 0.0877
)");
  EXPECT_EQ(e.where().file, "model.toml");
  EXPECT_EQ(e.where().line, 5u);
  EXPECT_NE(std::string(e.what()).find("unknown variable 'a_q'"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("model.toml:5:"), std::string::npos) << e.what();
}

TEST(ModelFile, OtherErrorsNameTheirLine) {
  const std::string head = "sensor = \"accelerometer\"\nm_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n";
  struct Bad {
    std::string text;
    std::size_t line;
    const char* part;
  };
  for (const Bad& b : {Bad{head + "[terms]\n\"a_i*a_p\" = 1.0\n\"a_p*a_i\" = 2.0\n", 5, "same term"},
                       Bad{head + "[terms]\n\"y\" = 1.0\n", 4, "y(k) cannot explain itself"},
                       Bad{head + "[terms]\n\"a_i\" = \"big\"\n", 4, "finite number"},
                       Bad{head + "[terms]\n\"a_i\" = nan\n", 4, "finite number"},
                       Bad{head + "[terms]\n\"a_i\" = 1.0\n[std]\n\"a_p\" = 1.0\n", 6, "not in [terms]"},
                       Bad{head + "[terms]\n\"a_i\" = 1.0\n[std]\n\"a_i\" = -1.0\n", 6, "negative"},
                       Bad{head + "[terms]\n\"a_i\" = 1.0\n[noise]\nB = 1e-5\n[noise.std]\nK = 1e-7\n", 8, "no K"},
                       Bad{head + "[terms]\n\"a_i\" = 1.0\n[noise]\nB = 1e-5\n[noise.std]\nB = -1e-7\n", 8, "negative"},
                       Bad{"sensor = \"accelerometer\"\nm_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]\n"
                           "[terms]\n\"a_i\" = 1.0\n",
                           2, "not a rotation"},
                       Bad{"sensor = \"barometer\"\n", 1, "accelerometer"},
                       Bad{head + "[terms]\n", 0, "empty [terms]"},
                       Bad{head + "[terms\n", 3, ""}}) {
    const InputError e = parse_error(b.text);
    EXPECT_EQ(e.where().line, b.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(b.part), std::string::npos) << e.what();
  }
}

TEST(ModelFile, WhatCompensationNeedsRoundTripsWithTheCovarianceInTheTermsOrder) {
  ModelFile m = sample_model();
  m.name = "acc1";
  m.output_unit = "mA";
  m.t_ref = 25.0;
  m.sample_period_s = 1.0 / 3.0 * 1e-3;
  m.output_sd = 2.5e-4;
  const auto n = static_cast<Eigen::Index>(m.terms.size());
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(n, n);
  m.covariance = a * a.transpose() / 7.0;
  m.range[ident::Variable::Ai] = {-9.81, 9.81 / 3.0};
  m.range[ident::Variable::T] = {-15.0, 40.0};
  m.misalignment = ModelFile::Misalignment{1.4e-3, -1.0 / 3.0 * 1e-3, 2e-5, 3e-5};
  m.undetermined = {{"a_i^2", "no case excites a_i beyond 1 g"}, {"T", "no \"temperature\" step"}};
  m.conditions.duration_s = 109.0;
  m.conditions.source = "acc1";
  m.conditions.cases = {"multipoint", "rate-series"};
  m.conditions.software = "inertia 0.1.0";
  m.conditions.date = "2026-11-29T13:40:00Z";
  m.case_frames.push_back({"shaker-ia", frames::about_third_axis(0.02)});
  m.case_frames.push_back({"table", frames::about_second_axis(-1.0 / 3.0)});
  const ModelFile r = parse_model(format_model(m), "model.toml");
  EXPECT_EQ(r.name, "acc1");
  EXPECT_EQ(r.output_unit, "mA");
  EXPECT_EQ(r.t_ref, 25.0);
  EXPECT_EQ(r.sample_period_s, m.sample_period_s);
  EXPECT_EQ(r.output_sd, 2.5e-4);
  EXPECT_EQ(r.covariance, m.covariance);   // bitwise
  ASSERT_EQ(r.range.size(), 2u);
  EXPECT_EQ(r.range.at(ident::Variable::Ai).highest, 9.81 / 3.0);
  EXPECT_EQ(r.range.at(ident::Variable::T).lowest, -15.0);
  ASSERT_TRUE(r.misalignment.has_value());
  EXPECT_EQ(r.misalignment->about_o, -1.0 / 3.0 * 1e-3);
  EXPECT_EQ(r.undetermined, m.undetermined);
  EXPECT_EQ(r.conditions.cases, m.conditions.cases);
  EXPECT_EQ(r.conditions.duration_s, 109.0);
  EXPECT_EQ(r.conditions.date, m.conditions.date);
  ASSERT_EQ(r.case_frames.size(), 2u);
  EXPECT_EQ(r.case_frames[1].case_name, "table");
  EXPECT_EQ(r.case_frames[1].m_es, m.case_frames[1].m_es);
  EXPECT_EQ(format_model(r), format_model(m));

  // A file may list the covariance's terms in its own order and spelling: read into [terms]' order.
  const ModelFile s = parse_model(R"(sensor = "accelerometer"
m_cs = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
[terms]
"1" = 1e-3
"a_i*a_p" = 2e-4
"a_i" = 0.09
[covariance]
terms = ["a_i", "a_p * a_i", "1"]
matrix = [[9.0, 2.0, 1.0], [2.0, 4.0, 0.5], [1.0, 0.5, 1.0]]
)",
                                  "model.toml");
  Eigen::Matrix3d expected;
  expected << 1.0, 0.5, 1.0, 0.5, 4.0, 2.0, 1.0, 2.0, 9.0;
  EXPECT_EQ(s.covariance, Eigen::MatrixXd(expected));
}

TEST(ModelFile, BadCovarianceAndRangeNameTheirLine) {
  const std::string head = "sensor = \"accelerometer\"\nm_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
                           "[terms]\n\"1\" = 1.0\n\"a_i\" = 2.0\n";
  struct Bad {
    std::string text;
    std::size_t line;
    const char* part;
  };
  for (const Bad& b : {Bad{head + "[covariance]\nterms = [\"1\", \"a_p\"]\nmatrix = [[1.0, 0.0], [0.0, 1.0]]\n", 7, "not in [terms]"},
                       Bad{head + "[covariance]\nterms = [\"1\", \"1\"]\nmatrix = [[1.0, 0.0], [0.0, 1.0]]\n", 7, "twice"},
                       Bad{head + "[covariance]\nterms = [\"1\"]\nmatrix = [[1.0]]\n", 7, "[terms] has 2"},
                       Bad{head + "[covariance]\nterms = [\"1\", \"a_i\"]\nmatrix = [[1.0, 0.0]]\n", 8, "2 needed"},
                       Bad{head + "[covariance]\nterms = [\"1\", \"a_i\"]\nmatrix = [[1.0, 0.1], [0.2, 1.0]]\n", 8, "not symmetric"},
                       Bad{head + "[covariance]\nterms = [\"1\", \"a_i\"]\nmatrix = [[-1.0, 0.0], [0.0, 1.0]]\n", 8, "negative"},
                       Bad{head + "[covariance]\nmatrix = [[1.0]]\n", 6, "needs 'terms'"},
                       Bad{head + "[range]\na_q = [0.0, 1.0]\n", 7, "not an input variable"},
                       Bad{head + "[range]\n\"a_i^2\" = [0.0, 1.0]\n", 7, "not an input variable"},
                       Bad{head + "[range]\na_i = [1.0, 0.0]\n", 7, "above highest"},
                       Bad{head + "[range]\na_i = [1.0]\n", 7, "[lowest, highest]"},
                       Bad{"sample_period_s = -1.0\n" + head, 1, "positive"},
                       Bad{head + "[[case_frame]]\ncase = \"a\"\n", 6, "needs 'case'"},
                       Bad{head + "[[case_frame]]\ncase = \"a\"\nm_es = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
                                  "[[case_frame]]\ncase = \"a\"\nm_es = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n", 9, "twice"},
                       Bad{head + "[[case_frame]]\ncase = \"a\"\nm_es = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]\n", 8, "not a rotation"},
                       Bad{"sensor_name = 3\n" + head, 1, "string"}}) {
    const InputError e = parse_error(b.text);
    EXPECT_EQ(e.where().line, b.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(b.part), std::string::npos) << e.what();
  }
}

TEST(ModelFile, WriteRefusesNonFiniteNumbers) {
  ModelFile m = sample_model();
  m.terms[0].coefficient = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)format_model(m), InputError);
}

}  // namespace
}  // namespace inertia::model
