// Stacking per-case regressions (block 9): a hand-worked two-case example whose every row, column,
// label and layout entry is written out below, with lags kept inside each case, the weights as
// sqrt(w) on the rows, the output-multiplied factors unweighted, and the bad inputs refused.
#include "analyzer/procedure/stacked_regression.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

using Eigen::Index;

constexpr double kTRef = 20.0;

dataset::CaseData make_case(const std::string& name, const std::vector<std::array<double, 3>>& a,
                            const std::vector<double>& temp, const std::vector<double>& y) {
  dataset::CaseData c;
  c.name = name;
  const auto n = static_cast<Index>(a.size());
  c.sample_period_s = 1e-3;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-3);
  c.a_e.resize(n, 3);
  for (Index k = 0; k < n; ++k) c.a_e.row(k) << a[k][0], a[k][1], a[k][2];
  if (!temp.empty()) c.temp = Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(temp.data(), n));
  c.y = Eigen::Map<const Eigen::VectorXd>(y.data(), n);
  return c;
}

// Case A, F_S = F_E: a_i = a_x, a_p = a_y, a_o = a_z; T = temp - 20 = 1 .. 5.
dataset::CaseData case_a() {
  return make_case("a", {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {-1, 0, 2}, {2, -3, 1}}, {21, 22, 23, 24, 25},
                   {10, 11, 12, 13, 14});
}

// Case B, turned by kPermutation: a_i = a_y, a_p = a_z, a_o = a_x; T = 0, -2, 1, 2.
dataset::CaseData case_b() {
  return make_case("b", {{1, 0, -2}, {3, 1, 2}, {0, -1, 4}, {5, 2, -3}}, {20, 18, 21, 22}, {1, 2, 3, 4});
}

Eigen::Matrix3d permutation() {
  Eigen::Matrix3d m;
  m << 0, 1, 0,   // n_i = y_E
      0, 0, 1,    // n_p = z_E
      1, 0, 0;    // n_o = x_E
  return m;
}

TEST(StackRegressions, TwoCasesByHand) {
  const dataset::CaseData a = case_a(), b = case_b();
  // "a_o*a_i" is spelled out of canonical order on purpose: the label is the canonical name.
  const std::vector<ident::Term> terms = ident::parse_terms({"a_i", "1", "a_p[k-1]", "a_o*a_i", "a_i*T"});
  const std::vector<StackInput> inputs = {StackInput{0, &a, Eigen::Matrix3d::Identity(), 1.0, {}},
                                          StackInput{7, &b, permutation(), 4.0, {}}};
  const StackedRegression s = stack_regressions(terms, inputs, kTRef, "test");

  EXPECT_EQ(s.labels, (std::vector<std::string>{"a_i", "1", "a_p[k-1]", "a_i*a_o", "a_i*T"}));
  // The largest lag is 1: each case loses its first sample; 4 + 3 rows.
  ASSERT_EQ(s.phi.rows(), 7);
  ASSERT_EQ(s.phi.cols(), 5);
  ASSERT_EQ(s.y.size(), 7);
  Eigen::MatrixXd phi(7, 5);
  Eigen::VectorXd y(7);
  // Case A, samples k = 1..4: a_i, 1, a_p(k-1), a_i*a_o, a_i*T.
  phi.row(0) << 4, 1, 2, 24, 8;
  phi.row(1) << 7, 1, 5, 63, 21;
  phi.row(2) << -1, 1, 8, -2, -4;
  phi.row(3) << 2, 1, 0, 2, 10;
  y.head(4) << 11, 12, 13, 14;
  // Case B, samples k = 1..3, times sqrt(4) = 2. Row 4's a_p(k-1) is case B's sample 0 (a_z = -2),
  // not case A's last sample: a lag never reaches across a case.
  phi.row(4) << 2 * 1, 2 * 1, 2 * -2, 2 * 3, 2 * -2;
  phi.row(5) << 2 * -1, 2 * 1, 2 * 2, 2 * 0, 2 * -1;
  phi.row(6) << 2 * 2, 2 * 1, 2 * 4, 2 * 10, 2 * 4;
  y.tail(3) << 2 * 2, 2 * 3, 2 * 4;
  EXPECT_EQ(s.phi, phi);
  EXPECT_EQ(s.y, y);

  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[0].case_index, 0u);
  EXPECT_EQ(s.cases[0].begin, 0);
  EXPECT_EQ(s.cases[0].rows, 4);
  EXPECT_EQ(s.cases[0].first_sample, 1);
  EXPECT_EQ(s.cases[1].case_index, 7u);
  EXPECT_EQ(s.cases[1].begin, 4);
  EXPECT_EQ(s.cases[1].rows, 3);
  EXPECT_EQ(s.cases[1].first_sample, 1);
  EXPECT_TRUE(s.rational.columns.empty());
  EXPECT_EQ(s.rational.factors.size(), 0);
}

TEST(StackRegressions, MinFirstRowAlignsEveryCaseOnTheSameSample) {
  const dataset::CaseData a = case_a(), b = case_b();
  const std::vector<ident::Term> terms = ident::parse_terms({"a_i"});
  const std::vector<StackInput> inputs = {StackInput{0, &a, Eigen::Matrix3d::Identity(), 1.0, {}},
                                          StackInput{1, &b, permutation(), 1.0, {}}};
  const StackedRegression s = stack_regressions(terms, inputs, kTRef, "test", 3);
  // Samples 3.. of each case: a_x of A at k = 3, 4; a_y of B at k = 3.
  ASSERT_EQ(s.phi.rows(), 3);
  EXPECT_EQ(s.phi.col(0), Eigen::Vector3d(-1, 2, 2));
  EXPECT_EQ(s.y, Eigen::Vector3d(13, 14, 4));
  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[0].first_sample, 3);
  EXPECT_EQ(s.cases[0].rows, 2);
  EXPECT_EQ(s.cases[1].begin, 2);
  EXPECT_EQ(s.cases[1].rows, 1);
  EXPECT_EQ(s.cases[1].first_sample, 3);
}

TEST(StackRegressions, OutputMultipliedFactorsAreKeptUnweighted) {
  const dataset::CaseData a = case_a(), b = case_b();
  const std::vector<ident::Term> terms = ident::parse_terms({"1", "a_i", "y*a_i"});
  const std::vector<StackInput> inputs = {StackInput{0, &a, Eigen::Matrix3d::Identity(), 1.0, {}},
                                          StackInput{1, &b, permutation(), 4.0, {}}};
  const StackedRegression s = stack_regressions(terms, inputs, kTRef, "test");
  // No lags: every sample is a row.
  ASSERT_EQ(s.phi.rows(), 9);
  ASSERT_EQ(s.rational.columns, (std::vector<Index>{2}));
  ASSERT_EQ(s.rational.factors.rows(), 9);
  ASSERT_EQ(s.rational.factors.cols(), 1);
  // p_b = a_i per sample, without the case weight: A's a_x, then B's a_y.
  Eigen::VectorXd factor(9);
  factor << 1, 4, 7, -1, 2, 0, 1, -1, 2;
  EXPECT_EQ(s.rational.factors.col(0), factor);
  // The column itself is y * a_i, weighted like every other column: sqrt(4) on case B.
  Eigen::VectorXd column(9);
  column << 10 * 1, 11 * 4, 12 * 7, 13 * -1, 14 * 2, 2 * (1 * 0), 2 * (2 * 1), 2 * (3 * -1), 2 * (4 * 2);
  EXPECT_EQ(s.phi.col(2), column);
}

TEST(StackRegressions, RefusesMissingColumnsAndBadWeights) {
  dataset::CaseData a = case_a();
  a.temp.reset();
  const std::vector<ident::Term> with_t = ident::parse_terms({"1", "a_i*T"});
  const std::vector<StackInput> no_temp = {StackInput{0, &a, Eigen::Matrix3d::Identity(), 1.0, {}}};
  EXPECT_THROW(stack_regressions(with_t, no_temp, kTRef, "test"), InputError);

  const dataset::CaseData b = case_b();
  const std::vector<ident::Term> terms = ident::parse_terms({"1", "a_i"});
  for (const double w : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    const std::vector<StackInput> bad = {StackInput{0, &b, Eigen::Matrix3d::Identity(), w, {}}};
    EXPECT_THROW(stack_regressions(terms, bad, kTRef, "test"), std::invalid_argument) << "weight " << w;
  }
  const std::vector<StackInput> no_data = {StackInput{0, nullptr, Eigen::Matrix3d::Identity(), 1.0, {}}};
  EXPECT_THROW(stack_regressions(terms, no_data, kTRef, "test"), std::invalid_argument);
}

}  // namespace
}  // namespace inertia::procedure
