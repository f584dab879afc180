// The live estimator against known truth: chunked feeding equals one batch, lagged and high-passed
// terms continue across chunks exactly, the misalignment comes back within its noise, and the
// convergence flag means what it says.
#include "analyzer/online/online_estimator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/uls_batch.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;

constexpr double kG = 9.80665;

/// A shaker-like case: random specific force (sd 3 g per axis) at 10 kHz.
dataset::CaseData random_case(Index n, std::uint32_t seed, const frames::Dcm& m_ec = frames::Dcm::Identity()) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 3.0 * kG);
  dataset::CaseData c;
  c.name = "shaker";
  c.kind = CaseKind::Shaker;
  c.m_ec = m_ec;
  c.sample_period_s = 1e-4;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-4);
  c.a_e.resize(n, 3);
  for (Index k = 0; k < n; ++k) c.a_e.row(k) << normal(rng), normal(rng), normal(rng);
  c.y = Eigen::VectorXd::Zero(n);
  return c;
}

/// y = sum coefficient * term evaluated on the case with M_E^S = m_es, plus white noise.
void set_output(dataset::CaseData& c, const std::vector<ident::Term>& terms, const Eigen::VectorXd& theta,
                const Eigen::Matrix3d& m_es, double noise_sd, std::uint32_t seed) {
  const ident::SignalSet s = ident::signals_from_case(c, m_es, 25.0);
  const ident::Regression reg = ident::build_regression(terms, s);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_sd);
  c.y.setZero();
  for (Index r = 0; r < reg.phi.rows(); ++r) c.y(reg.first_row + r) = reg.phi.row(r).dot(theta) + noise(rng);
}

dataset::CaseData rows(const dataset::CaseData& c, Index from, Index count) {
  dataset::CaseData out = c;
  out.t = c.t.segment(from, count);
  out.a_e = c.a_e.middleRows(from, count);
  out.y = c.y.segment(from, count);
  return out;
}

OnlineOptions batch_like() {
  OnlineOptions o;
  o.uls.forgetting = 1.0;
  o.uls.initial_covariance = 1e6;   // prior weight 1e-6 against 1e4 samples of unit-RMS columns
  return o;
}

model::ModelFile model_of(const std::vector<std::string>& terms) {
  model::ModelFile m;
  for (const std::string& t : terms) m.terms.push_back({ident::parse_term(t), 0.0, std::nullopt});
  return m;
}

TEST(OnlineEstimator, ChunkedFeedEqualsOneBatchLeastSquares) {
  dataset::CaseData c = random_case(20000, 1);
  const std::vector<ident::Term> truth_terms = OnlineEstimator::default_terms(dataset::SensorKind::Accelerometer);
  Eigen::VectorXd theta(8);
  theta << 3.4e-3, 0.0877, 6e-6, 6e-6, 6e-6, 1e-4, 1e-4, 1e-4;
  set_output(c, truth_terms, theta, Eigen::Matrix3d::Identity(), 1e-3, 2);

  OnlineEstimator est(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, batch_like());
  std::mt19937 rng(3);
  for (Index k = 0; k < c.y.size();) {
    const Index n = std::min<Index>(1 + static_cast<Index>(rng() % 700), c.y.size() - k);
    est.push(rows(c, k, n), true);
    k += n;
  }
  const OnlineSnapshot s = est.snapshot();
  ASSERT_EQ(s.terms.size(), 10u);   // the default model + a_p, a_o
  EXPECT_EQ(s.terms[8], "a_p");
  EXPECT_EQ(s.samples_used, 20000);

  // The same least squares in one batch.
  const ident::SignalSet sig = ident::signals_from_case(c, Eigen::Matrix3d::Identity(), 25.0);
  const ident::Regression reg = ident::build_regression(est.terms(), sig);
  const Eigen::VectorXd batch = reg.phi.colPivHouseholderQr().solve(reg.y);
  for (Index j = 0; j < batch.size(); ++j) {
    EXPECT_NEAR(s.values(j), batch(j), 1e-6 * std::abs(batch(j)) + 1e-3 * s.std_devs(j)) << s.terms[static_cast<std::size_t>(j)];
  }
  // And it is the truth within the noise.
  for (Index j = 0; j < 8; ++j) EXPECT_NEAR(s.values(j), theta(j), 4.0 * s.std_devs(j)) << s.terms[static_cast<std::size_t>(j)];
  EXPECT_NEAR(std::sqrt(s.residual_variance), 1e-3, 3e-5);   // sd of a sample variance over 2e4: 0.5%
}

TEST(OnlineEstimator, LaggedAndHighPassedTermsContinueAcrossChunks) {
  dataset::CaseData c = random_case(6000, 4);
  model::ModelFile m = model_of({"1", "a_i", "a_i[k-1]", "a_i^2", "a_p^2"});
  m.square_highpass_rad_s = 500.0;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (Index k = 0; k < c.y.size(); ++k) c.y(k) = normal(rng);
  OnlineEstimator whole(dataset::SensorKind::Accelerometer, m, 25.0, batch_like());
  whole.push(c, false);
  OnlineEstimator chunked(dataset::SensorKind::Accelerometer, m, 25.0, batch_like());
  for (Index k = 0; k < c.y.size(); k += 250) chunked.push(rows(c, k, 250), k > 0);
  const OnlineSnapshot a = whole.snapshot(), b = chunked.snapshot();
  EXPECT_EQ(a.samples_used, 5999);   // the first sample only fills a_i[k-1]'s history
  EXPECT_EQ(b.samples_used, a.samples_used);
  for (Index j = 0; j < a.values.size(); ++j) EXPECT_NEAR(b.values(j), a.values(j), 1e-9 * (1.0 + std::abs(a.values(j))));

  // A gap (continues_previous = false) restarts the lag history: one more sample is lost.
  OnlineEstimator gapped(dataset::SensorKind::Accelerometer, m, 25.0, batch_like());
  gapped.push(rows(c, 0, 3000), false);
  gapped.push(rows(c, 3000, 3000), false);
  EXPECT_EQ(gapped.snapshot().samples_used, 5998);
}

TEST(OnlineEstimator, HighPassInBlocksEqualsTheWholeSignal) {
  Eigen::VectorXd x = Eigen::VectorXd::Random(1000), whole = x;
  procedure::highpass_in_place(whole, 500.0, 1e-4);
  procedure::HighpassState state;
  for (Index k = 0; k < x.size(); k += 137) {
    const Index n = std::min<Index>(137, x.size() - k);
    procedure::highpass_in_place(x.segment(k, n), 500.0, 1e-4, state);
  }
  EXPECT_LT((x - whole).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(OnlineEstimator, MisalignmentOfTheSensitiveAxisComesBackWithinItsNoise) {
  // The sensor's true axis is turned by theta_p = 1.2 mrad about p and theta_o = -0.8 mrad about
  // o from the model's M_C^S (identity); the case is mounted at 25 deg about z.
  const frames::Dcm m_ec = frames::Dcm(Eigen::AngleAxisd(deg_to_rad(25.0), Eigen::Vector3d::UnitZ()).toRotationMatrix().transpose());
  dataset::CaseData c = random_case(40000, 6, m_ec);
  const double theta_p = 1.2e-3, theta_o = -0.8e-3;
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(theta_o, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(theta_p, Eigen::Vector3d::UnitY())).toRotationMatrix().transpose();
  const std::vector<ident::Term> truth_terms = {ident::parse_term("1"), ident::parse_term("a_i")};
  set_output(c, truth_terms, Eigen::Vector2d(2e-3, 0.0877), tilt * m_ec, 1e-4, 7);

  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_of({"1", "a_i"}), 25.0, batch_like());
  est.push(c, false);
  const OnlineSnapshot s = est.snapshot();
  // sd of an angle = sd of the cross term / K.
  const double sd_p = s.std_devs(3) / s.values(1), sd_o = s.std_devs(2) / s.values(1);
  EXPECT_NEAR(s.misalignment_rad(1), theta_p, 4.0 * sd_p + 1e-6);   // + second-order small-angle terms
  EXPECT_NEAR(s.misalignment_rad(2), theta_o, 4.0 * sd_o + 1e-6);
  EXPECT_EQ(s.misalignment_rad(0), 0.0);
  EXPECT_LT(sd_p, 2e-5);   // the test must be able to fail: 1e-4 noise over 4e4 samples of 3 g
}

TEST(OnlineEstimator, ConvergedOnlyOnceTheEstimateHasSettled) {
  dataset::CaseData c = random_case(20000, 8);
  set_output(c, {ident::parse_term("1"), ident::parse_term("a_i")}, Eigen::Vector2d(2e-3, 0.0877),
             Eigen::Matrix3d::Identity(), 1e-3, 9);
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_of({"1", "a_i"}), 25.0, OnlineOptions{});
  est.push(rows(c, 0, 100), false);
  EXPECT_FALSE(est.snapshot().converged);   // too few samples per term (4 terms x 100)
  est.push(rows(c, 100, 5000), true);
  EXPECT_FALSE(est.snapshot().converged);   // first snapshot with enough samples: nothing to compare with yet
  est.push(rows(c, 5100, 5000), true);
  EXPECT_TRUE(est.snapshot().converged);
  EXPECT_TRUE(est.snapshot().converged);   // no new samples: the verdict stands
  // The sensor changes (scale factor +1%): the estimate moves by many standard deviations.
  dataset::CaseData changed = rows(c, 10100, 9900);
  set_output(changed, {ident::parse_term("1"), ident::parse_term("a_i")}, Eigen::Vector2d(2e-3, 0.0886),
             Eigen::Matrix3d::Identity(), 1e-3, 10);
  est.push(changed, true);
  EXPECT_FALSE(est.snapshot().converged);
  EXPECT_FALSE(est.snapshot().converged);   // and waiting does not make it converge
}

TEST(OnlineEstimator, RejectsWhatTheLiveStreamCannotEstimate) {
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, model_of({"1", "a_i^2"}), 25.0, {}), InputError);
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, model_of({"1", "a_i", "e[k-1]"}), 25.0, {}),
               InputError);
  model::ModelFile gyro = model_of({"1", "w_i"});
  gyro.sensor = dataset::SensorKind::Gyroscope;
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, gyro, 25.0, {}), InputError);
  // A chunk without temperature for a model that needs it names the column.
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_of({"1", "a_i", "T"}), 25.0, {});
  try {
    est.push(random_case(100, 1), false);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("temp"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace inertia::online
