// A sensor-frame term's column equals the combination of its case-frame monomials' columns
// (analyzer/ident/frame_expansion.hpp), for any frame: the property the live estimator's
// sufficient statistics rest on.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "analyzer/ident/frame_expansion.hpp"
#include "analyzer/ident/regressors.hpp"
#include "common/frames.hpp"

namespace inertia::ident {
namespace {

dataset::CaseData random_case(std::mt19937_64& rng, Eigen::Index n) {
  std::normal_distribution<double> g(0.0, 5.0);
  dataset::CaseData c;
  c.name = "random";
  c.a_e.resize(n, 3);
  c.w_e = dataset::Matrix3Columns(n, 3);
  c.temp = Eigen::VectorXd(n);
  c.y.resize(n);
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-3);
  c.sample_period_s = 1e-3;
  for (Eigen::Index k = 0; k < n; ++k) {
    for (int j = 0; j < 3; ++j) {
      c.a_e(k, j) = g(rng);
      (*c.w_e)(k, j) = g(rng);
    }
    (*c.temp)(k) = 25.0 + g(rng);
    c.y(k) = g(rng);
  }
  return c;
}

TEST(FrameExpansion, ColumnsEqualTheirMonomialCombination) {
  std::mt19937_64 rng(7);
  const dataset::CaseData c = random_case(rng, 50);
  const frames::Dcm m = frames::frame_rotation(Eigen::Vector3d(0.3, -0.5, 0.8).normalized(), 0.4);
  // Rows of a_e are the other frame's coordinates; the sensor-frame signals are m a.
  const SignalSet s = signals_from_case(c, m, 25.0, "test");
  for (const char* text : {"1", "a_i", "a_p^2", "a_i*a_o", "a_i^2*a_p", "a_o^2[k-1]", "a_i*T", "y*w_i", "w_p*a_o",
                           "y[k-1]", "T^2", "a_p[k-2]*a_i", "a_x", "a_i^3"}) {
    const Term term = parse_term(text);
    ASSERT_TRUE(expandable(term)) << text;
    const std::vector<FrameMonomial> expansion = expand_in_frame(term, m);
    std::vector<Term> monomials;
    for (const FrameMonomial& e : expansion) {
      monomials.push_back(e.monomial);
      for (const Factor& f : e.monomial.factors()) {
        EXPECT_TRUE(f.variable >= Variable::Ax && f.variable != Variable::Wi && f.variable != Variable::Wp &&
                    f.variable != Variable::Wo)
            << text << " -> " << e.monomial.to_string();
      }
    }
    const Eigen::Index first = 2;
    Eigen::MatrixXd direct(c.size() - first, 1), basis(c.size() - first, static_cast<Eigen::Index>(monomials.size()));
    fill_regressors(std::vector<Term>{term}, s, first, direct);
    fill_regressors(monomials, s, first, basis);
    Eigen::VectorXd w(static_cast<Eigen::Index>(expansion.size()));
    for (std::size_t j = 0; j < expansion.size(); ++j) w(static_cast<Eigen::Index>(j)) = expansion[j].coefficient;
    const Eigen::VectorXd combined = basis * w;
    EXPECT_LE((combined - direct.col(0)).norm(), 1e-12 * direct.norm()) << text;
  }
}

TEST(FrameExpansion, MonomialListDoesNotDependOnTheFrame) {
  // a_i*a_p in the identity frame has a single nonzero coefficient (a_x*a_y), but every monomial a
  // rotation can give weight to is listed, so statistics kept in this basis serve any frame.
  const Term t = parse_term("a_i*a_p");
  const auto at_identity = expand_in_frame(t, Eigen::Matrix3d::Identity());
  const auto turned = expand_in_frame(t, frames::frame_rotation(Eigen::Vector3d::UnitZ(), 0.1));
  ASSERT_EQ(at_identity.size(), 6u);   // a_x^2, a_x*a_y, a_x*a_z, a_y^2, a_y*a_z, a_z^2
  ASSERT_EQ(turned.size(), at_identity.size());
  int nonzero = 0;
  for (std::size_t j = 0; j < at_identity.size(); ++j) {
    EXPECT_EQ(at_identity[j].monomial, turned[j].monomial);
    nonzero += at_identity[j].coefficient != 0.0 ? 1 : 0;
  }
  EXPECT_EQ(nonzero, 1);
  EXPECT_EQ(expand_in_frame(parse_term("1"), Eigen::Matrix3d::Identity()).size(), 1u);
}

TEST(FrameExpansion, AbsAndSignOfSensorAxesDoNotExpand) {
  for (const char* text : {"abs(a_i)", "sign(a_i)", "a_i*abs(a_i)", "w_i*abs(w_i)"}) {
    EXPECT_FALSE(expandable(parse_term(text))) << text;
    EXPECT_THROW((void)expand_in_frame(parse_term(text), Eigen::Matrix3d::Identity()), std::invalid_argument);
  }
  EXPECT_TRUE(expandable(parse_term("abs(a_x)*T")));   // already in the other frame
}

}  // namespace
}  // namespace inertia::ident
