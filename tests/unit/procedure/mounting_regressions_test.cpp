// A mounting's whitened regression from its monomials' whitened columns (MountingRegressions)
// against the same regression built directly (whitened_regression), for every kind of term: plain
// powers and products of sensor-frame variables, the squares through the high pass, frame-free and
// external-frame factors, terms that do not expand (abs, sign), output-multiplied terms, and lags
// beyond the mounting's first row.
#include "analyzer/procedure/mounting_regressions.hpp"
#include "analyzer/procedure/plan_validation.hpp"
#include "analyzer/procedure/stacked_regression.hpp"

#include <gtest/gtest.h>

#include <span>
#include <string>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "common/frames.hpp"
#include "tests/support/synthetic_cases.hpp"

namespace inertia::procedure {
namespace {

/// Two cases of one mounting, the second turned in F_E: what mounting_cases turns into the nominal
/// case frame.
dataset::Dataset two_case_mounting() {
  return testing::synthetic_shaker_cases(
      {{"fixture", 3000}, {"fixture", 3500, frames::frame_rotation(Eigen::Vector3d(1.0, 2.0, -0.5).normalized(), 0.4)}}, 5);
}

TEST(MountingRegressions, CombinedColumnsAreTheDirectlyBuiltOnesForEveryKindOfTerm) {
  const dataset::Dataset data = two_case_mounting();
  PipelineOptions options;
  options.case_weights = {{"case1", 2.5}};
  const MountingCases m = mounting_cases(data, {0, 1}, options, std::nullopt);
  // An AR(3) whitener and a corner: both filters act on every column.
  const ArWhitener whitener = ArWhitener::of(Eigen::Vector3d(0.5, -0.2, 0.1));
  const double corner = 40.0;
  const Eigen::Index first_row = 1;
  const std::vector<ident::Term> cover = ident::parse_terms({"1", "a_i", "a_p", "a_o", "a_i^2", "a_p^2", "a_i*a_o", "a_i^2*a_p"});
  const MountingRegressions regressions(m, data, "test", first_row, corner, whitener, cover);
  // 1; a_x a_y a_z; the six products of two, plain and through the high pass; the ten of three.
  EXPECT_EQ(regressions.monomial_columns(), 26u);

  // Asked for more than it covers: new monomials, terms that stay direct, an output-multiplied
  // term, a lag within the first row.
  const std::vector<ident::Term> terms = ident::parse_terms({"1", "a_i", "a_o^2", "a_i^2", "a_p*a_o", "T*a_i", "a_x", "abs(a_i)",
                                                             "sign(a_p)*a_i", "y*a_i", "a_i[k-1]", "T^2", "a_p^2"});
  for (const double angle : {0.0, 0.03, 1.1}) {
    const frames::Dcm m_cs = frames::frame_rotation(Eigen::Vector3d(0.3, -1.0, 0.7).normalized(), angle);
    const StackedRegression direct = whitened_regression(terms, m, m_cs, data, "test", first_row, corner, whitener);
    const StackedRegression combined = regressions.whitened(terms, m_cs);
    ASSERT_EQ(combined.labels, direct.labels);
    ASSERT_EQ(combined.phi.rows(), direct.phi.rows());
    ASSERT_EQ(combined.phi.cols(), direct.phi.cols());
    ASSERT_EQ(combined.cases.size(), direct.cases.size());
    for (std::size_t c = 0; c < direct.cases.size(); ++c) {
      EXPECT_EQ(combined.cases[c].begin, direct.cases[c].begin);
      EXPECT_EQ(combined.cases[c].rows, direct.cases[c].rows);
      EXPECT_EQ(combined.cases[c].first_sample, direct.cases[c].first_sample);
    }
    EXPECT_EQ(combined.y, direct.y);
    // A combination of monomials rounds differently from the product of the turned coordinates:
    // each column within a few rounding units of its own size.
    for (Eigen::Index j = 0; j < direct.phi.cols(); ++j) {
      const double scale = direct.phi.col(j).cwiseAbs().maxCoeff();
      EXPECT_LE((combined.phi.col(j) - direct.phi.col(j)).cwiseAbs().maxCoeff(), 1e-13 * scale)
          << direct.labels[std::size_t(j)] << " at " << angle << " rad";
    }
    EXPECT_EQ(combined.rational.columns, direct.rational.columns);
    EXPECT_EQ(combined.rational.factors, direct.rational.factors);
  }
  // The monomials asked for beyond the cover (T a_x, T a_y, T a_z, the three a[k-1], T^2) were
  // whitened once and kept.
  EXPECT_EQ(regressions.monomial_columns(), 33u);
  (void)regressions.whitened(terms, frames::Dcm::Identity());
  EXPECT_EQ(regressions.monomial_columns(), 33u);
}

// A stage's normal equations from the monomials' Gram and its residual from one pass over them:
// those of the rows whitened() builds, to rounding, with terms that stay direct (abs, sign) and
// monomials beyond the cover whitened on the way; none where a term needs the rows.
TEST(MountingRegressions, SumsAreTheNormalEquationsAndResidualsOfTheRows) {
  const dataset::Dataset data = two_case_mounting();
  const MountingCases m = mounting_cases(data, {0, 1}, PipelineOptions{}, std::nullopt);
  const ArWhitener whitener = ArWhitener::of(Eigen::Vector3d(0.5, -0.2, 0.1));
  const double corner = 40.0;
  const Eigen::Index first_row = 1;
  const MountingRegressions regressions(m, data, "test", first_row, corner, whitener, ident::parse_terms({"1", "a_i", "a_p", "a_i^2"}));
  const std::vector<ident::Term> terms =
      ident::parse_terms({"1", "a_i", "a_o^2", "a_i^2", "a_p*a_o", "abs(a_i)", "T*a_i", "sign(a_p)*a_i", "a_i[k-1]", "a_p"});
  for (const double angle : {0.0, 0.03, 1.1}) {
    const frames::Dcm m_cs = frames::frame_rotation(Eigen::Vector3d(0.3, -1.0, 0.7).normalized(), angle);
    const std::optional<RegressionSums> sums = regressions.sums(terms, m_cs);
    ASSERT_TRUE(sums.has_value());
    const StackedRegression rows = regressions.whitened(terms, m_cs);
    const ident::NormalEquations from_rows = ident::NormalEquations::from_rows(rows.phi, rows.y, rows.labels);
    ASSERT_EQ(sums->equations.labels(), rows.labels);
    EXPECT_EQ(sums->equations.samples(), rows.phi.rows());
    const Eigen::MatrixXd& a = sums->equations.augmented();
    const Eigen::MatrixXd& b = from_rows.augmented();
    ASSERT_EQ(a.rows(), b.rows());
    for (Eigen::Index i = 0; i < a.rows(); ++i)
      for (Eigen::Index j = 0; j < a.cols(); ++j)
        EXPECT_NEAR(a(i, j), b(i, j), 1e-12 * std::sqrt(b(i, i) * b(j, j))) << rows.labels.size() << " " << i << " " << j << " at " << angle;
    // The residual of a fit of some of the columns, in any order.
    const std::vector<Eigen::Index> columns{5, 0, 2, 7, 1, 9};
    Eigen::VectorXd theta(static_cast<Eigen::Index>(columns.size()));
    theta << 0.3, -1.2, 2.5e-3, 0.07, 0.99, -4e-4;
    Eigen::VectorXd expected = rows.y;
    for (std::size_t k = 0; k < columns.size(); ++k) expected -= theta(Eigen::Index(k)) * rows.phi.col(columns[k]);
    const Eigen::VectorXd residual = sums->residuals(columns, theta);
    ASSERT_EQ(residual.size(), expected.size());
    EXPECT_LE((residual - expected).cwiseAbs().maxCoeff(), 1e-12 * rows.y.cwiseAbs().maxCoeff()) << angle;
  }
  // An output-multiplied term's fit needs its rows.
  EXPECT_FALSE(regressions.sums(ident::parse_terms({"1", "a_i", "y*a_i"}), frames::Dcm::Identity()).has_value());
}

TEST(MountingRegressions, LagsBeyondTheFirstRowMoveTheRowsAndAreBuiltDirectly) {
  const dataset::Dataset data = two_case_mounting();
  const MountingCases m = mounting_cases(data, {0, 1}, PipelineOptions{}, std::nullopt);
  const ArWhitener whitener = ArWhitener::of(Eigen::Vector2d(0.4, 0.1));
  const MountingRegressions regressions(m, data, "test", 0, std::nullopt, whitener, ident::parse_terms({"1", "a_i"}));
  const std::vector<ident::Term> terms = ident::parse_terms({"1", "a_i", "a_p[k-2]"});
  const frames::Dcm m_cs = frames::frame_rotation(Eigen::Vector3d::UnitZ(), 0.2);
  const StackedRegression direct = whitened_regression(terms, m, m_cs, data, "test", 0, std::nullopt, whitener);
  const StackedRegression combined = regressions.whitened(terms, m_cs);
  EXPECT_EQ(combined.phi, direct.phi);
  EXPECT_EQ(combined.y, direct.y);
}

// mounting_cases reads the dataset's cases in place: each stack input turns the external
// variables into the nominal case frame and takes the known bias from the output. The same
// regression, inputs' Gram and excitation as from copies of the cases turned and offset.
TEST(MountingCases, ReadTheCasesInTheNominalFrameLessTheKnownBias) {
  dataset::Dataset data = two_case_mounting();
  for (dataset::CaseData& c : data.cases) c.w_e = Eigen::MatrixXd::Random(c.size(), 3);
  constexpr double kBias = 0.37;
  const MountingCases m = mounting_cases(data, {0, 1}, PipelineOptions{}, kBias);
  ASSERT_EQ(m.cases.size(), 2u);
  EXPECT_EQ(m.cases[1], &data.cases[1]);   // no copy
  std::vector<dataset::CaseData> turned = {data.cases[0], data.cases[1]};
  for (dataset::CaseData& c : turned) {
    c.a_e = c.a_e * c.m_ec.transpose();
    if (c.w_e) *c.w_e = *c.w_e * c.m_ec.transpose();
    c.m_ec = frames::Dcm::Identity();
    c.y.array() -= kBias;
  }
  const frames::Dcm m_cs = frames::frame_rotation(Eigen::Vector3d(0.3, -1.0, 0.7).normalized(), 0.05);
  const std::vector<StackInput> copies = {{0, &turned[0], m_cs, 1.0, {}}, {1, &turned[1], m_cs, 1.0, {}}};
  const std::vector<ident::Term> terms =
      ident::parse_terms({"1", "a_i", "a_p*a_o", "a_x", "a_y*a_z", "w_z", "w_i", "T*a_i", "y*a_i", "a_o[k-1]"});
  const StackedRegression in_place = stack_regressions(terms, stack_inputs(m, m_cs), data.t_ref, "test");
  const StackedRegression from_copies = stack_regressions(terms, copies, data.t_ref, "test");
  ASSERT_EQ(in_place.phi.rows(), from_copies.phi.rows());
  // The turn is applied in another order (M_C^S M_E^C at once): within a few rounding units.
  for (Eigen::Index j = 0; j < in_place.phi.cols(); ++j) {
    const double scale = from_copies.phi.col(j).cwiseAbs().maxCoeff();
    EXPECT_LE((in_place.phi.col(j) - from_copies.phi.col(j)).cwiseAbs().maxCoeff(), 1e-14 * scale) << in_place.labels[std::size_t(j)];
  }
  EXPECT_EQ(in_place.y, from_copies.y);
  ASSERT_EQ(in_place.rational.factors.cols(), 1);   // y*a_i's a_i
  EXPECT_LE((in_place.rational.factors - from_copies.rational.factors).cwiseAbs().maxCoeff(),
            1e-14 * from_copies.rational.factors.cwiseAbs().maxCoeff());
  for (std::size_t c = 0; c < turned.size(); ++c) {
    for (const dataset::SensorKind sensor : {dataset::SensorKind::Accelerometer, dataset::SensorKind::Gyroscope}) {
      const Eigen::Matrix4d expected = case_input_gram(turned[c], sensor);
      EXPECT_LE((case_input_gram(data.cases[c], sensor) - expected).cwiseAbs().maxCoeff(), 1e-12 * expected.cwiseAbs().maxCoeff());
    }
  }
  // The excitation rule judges the same products.
  std::vector<ident::Term> judged_in_place = ident::parse_terms({"a_i*a_p", "a_p*a_o", "a_x*a_y", "a_i^2", "a_p^2"});
  std::vector<ident::Term> judged_copies = judged_in_place;
  const std::vector<UndeterminedTerm> left_in_place = remove_unexcited_terms(judged_in_place, stack_inputs(m, frames::Dcm::Identity()), data.t_ref);
  const std::vector<UndeterminedTerm> left_copies = remove_unexcited_terms(judged_copies, std::span<const dataset::CaseData>(turned), data.t_ref);
  EXPECT_EQ(judged_in_place, judged_copies);
  EXPECT_EQ(left_in_place.size(), left_copies.size());
}

}  // namespace
}  // namespace inertia::procedure
