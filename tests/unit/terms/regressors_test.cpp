// Regression matrix columns against values worked out by hand (analyzer/ident/regressors.hpp).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "analyzer/ident/regressors.hpp"
#include "common/input_error.hpp"

namespace inertia::ident {
namespace {

Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double d : v) x[i++] = d;
  return x;
}

SignalSet small_signals() {
  SignalSet s(6, "the test signals");
  s.set(Variable::Ai, vec({1, -2, 3, -4, 0.5, 0}));
  s.set(Variable::Ap, vec({0.5, 1, -1, 2, -3, 4}));
  s.set(Variable::Ao, vec({2, -1, 0, 3, 1, -2}));
  s.set(Variable::T, vec({0.1, 0.2, -0.3, 0.4, 0.5, -0.6}));
  s.set(Variable::Y, vec({10, 20, 30, 40, 50, 60}));
  s.set(Variable::E, vec({0.01, -0.02, 0.03, -0.04, 0.05, -0.06}));
  return s;
}

TEST(Regressors, ColumnsMatchHandComputedValues) {
  const std::vector<std::string> names = {"1",       "a_i",      "a_o^2[k-1]", "abs(a_i)", "sign(a_i)",      "a_i*abs(a_i)",
                                          "y[k-2]",  "a_i*T",    "e[k-1]",     "a_i*a_p",  "sign(a_p[k-2])", "y*T"};
  const std::vector<Term> terms = parse_terms(names);
  const Regression r = build_regression(terms, small_signals());
  // Largest lag is 2 (y[k-2], sign(a_p[k-2])): rows are samples k = 2..5.
  ASSERT_EQ(r.first_row, 2);
  ASSERT_EQ(r.phi.rows(), 4);
  ASSERT_EQ(r.phi.cols(), 12);
  // clang-format off
  const double expected[4][12] = {
      // 1   a_i   a_o^2[k-1] |a_i| sign  a_i|a_i|  y[k-2] a_i*T  e[k-1]  a_i*a_p sign(a_p[k-2]) y*T
      {1,   3,    1,          3,    1,    9,        10,    -0.9,  -0.02,  -3,     1,             -9},   // k = 2
      {1,  -4,    0,          4,   -1,  -16,        20,    -1.6,   0.03,  -8,     1,             16},   // k = 3
      {1,   0.5,  9,          0.5,  1,    0.25,     30,     0.25, -0.04,  -1.5,  -1,             25},   // k = 4
      {1,   0,    1,          0,    0,    0,        40,     0,     0.05,   0,     1,            -36},   // k = 5
  };
  // clang-format on
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 12; ++col) {
      EXPECT_DOUBLE_EQ(r.phi(row, col), expected[row][col]) << "row " << row << " term " << names[col];
    }
  }
  EXPECT_EQ(r.y, vec({30, 40, 50, 60}));
}

TEST(Regressors, MinimumFirstRowAlignsModelsOfDifferentOrders) {
  const std::vector<Term> terms = parse_terms({"a_i", "a_i[k-1]"});
  const Regression r = build_regression(terms, small_signals(), 4);
  EXPECT_EQ(r.first_row, 4);
  ASSERT_EQ(r.phi.rows(), 2);
  EXPECT_EQ(r.phi.col(0), vec({0.5, 0}));
  EXPECT_EQ(r.phi.col(1), vec({-4, 0.5}));
  EXPECT_EQ(r.y, vec({50, 60}));
  EXPECT_EQ(first_usable_row(terms), 1);
}

TEST(Regressors, FillIntoCallerMatrixChecksTheShape) {
  const std::vector<Term> terms = parse_terms({"a_i^2", "a_p^3[k-1]"});
  Eigen::MatrixXd phi(5, 2);
  fill_regressors(terms, small_signals(), 1, phi);
  EXPECT_EQ(phi.col(0), vec({4, 9, 16, 0.25, 0}));
  EXPECT_EQ(phi.col(1), vec({0.125, 1, -1, 8, -27}));
  Eigen::MatrixXd wrong(4, 2);
  EXPECT_THROW(fill_regressors(terms, small_signals(), 1, wrong), std::invalid_argument);
  EXPECT_THROW(fill_regressors(terms, small_signals(), 0, phi), std::invalid_argument);   // lag 1 needs row 1
}

TEST(Regressors, SignalsFromCaseRotateIntoTheSensorFrame) {
  dataset::CaseData c;
  c.name = "table";
  c.t = vec({0, 0.1});
  c.a_e.resize(2, 3);
  c.a_e << 1, 2, 3,
           -4, 5, 6;
  c.w_e.emplace(2, 3);
  *c.w_e << 0.1, 0.2, 0.3,
            0.0, 0.0, -1.0;
  c.temp = vec({30, 20});
  c.y = vec({7, 8});
  // F_S is F_E turned +90 deg about z: n_i = n_y, n_p = -n_x, n_o = n_z (rows of M_E^S).
  Eigen::Matrix3d m_es;
  m_es << 0, 1, 0,
          -1, 0, 0,
          0, 0, 1;
  const SignalSet s = signals_from_case(c, m_es, 25.0, "my-test");
  EXPECT_EQ(s.size(), 2);
  EXPECT_EQ(s.get(Variable::Ai), vec({2, 5}));
  EXPECT_EQ(s.get(Variable::Ap), vec({-1, 4}));
  EXPECT_EQ(s.get(Variable::Ao), vec({3, 6}));
  EXPECT_EQ(s.get(Variable::Ax), vec({1, -4}));
  EXPECT_EQ(s.get(Variable::Az), vec({3, 6}));
  EXPECT_EQ(s.get(Variable::Wi), vec({0.2, 0}));
  EXPECT_EQ(s.get(Variable::Wp), vec({-0.1, 0}));
  EXPECT_EQ(s.get(Variable::Wo), vec({0.3, -1}));
  EXPECT_EQ(s.get(Variable::T), vec({5, -5}));
  EXPECT_EQ(s.get(Variable::Y), vec({7, 8}));
  EXPECT_FALSE(s.has(Variable::E));
  EXPECT_EQ(s.origin(), "case 'table' of dataset my-test");
}

TEST(Regressors, MissingColumnNamesTermColumnCaseAndDataset) {
  dataset::CaseData c;
  c.name = "shaker-ia";
  c.t = vec({0, 0.1, 0.2});
  c.a_e = dataset::Matrix3Columns::Ones(3, 3);
  c.y = vec({1, 2, 3});
  const SignalSet s = signals_from_case(c, Eigen::Matrix3d::Identity(), 25.0, "my-test");
  const auto message = [&](const char* term) -> std::string {
    try {
      (void)build_regression(parse_terms({"a_i", term}), s);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(message("a_i*T"), "term 'a_i*T' needs column 'temp', which case 'shaker-ia' of dataset my-test lacks");
  EXPECT_EQ(message("y*w_i"), "term 'y*w_i' needs columns 'w_x, w_y, w_z', which case 'shaker-ia' of dataset my-test lacks");
  EXPECT_EQ(message("e[k-1]"),
            "term 'e[k-1]' needs the residual e, which the estimator has not supplied for case 'shaker-ia' of dataset my-test");
  EXPECT_NE(message("y[k-3]").find("3 samples, too few for terms lagged by up to 3"), std::string::npos);
}

TEST(Regressors, SetRejectsAWrongLength) {
  SignalSet s(3);
  EXPECT_THROW(s.set(Variable::Ai, vec({1, 2})), std::invalid_argument);
  EXPECT_THROW((void)s.get(Variable::Ai), std::out_of_range);
}

}  // namespace
}  // namespace inertia::ident
