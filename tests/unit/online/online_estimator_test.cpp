// The live estimator against the batch procedure and against known truth: on the same rows it
// gives the batch pipeline's answer (two mountings, algorithm 1 on each, the squares' high pass),
// chunking does not matter, the corner comes back when it is searched, and the convergence flag
// means what docs/live-estimates.md ("Converged") says.
#include "analyzer/online/online_estimator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <random>

#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/pipeline.hpp"
#include "analyzer/procedure/square_highpass.hpp"
#include "analyzer/procedure/turn_search.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;
constexpr double kG = 9.80665;
constexpr double kPeriod = 1e-3;

struct PlanCase {
  config::TestCase tc;
  dataset::CaseData data;
};

// The paper's complete static model with eq. 12's squares (high pass at `corner`).
const std::vector<std::string> kModel = {"1", "a_i", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o"};
Eigen::VectorXd truth_values() {
  Eigen::VectorXd v(8);
  // Table 1's sensor per (m/s^2)^n, mA: bias, K_i, K_jj (high-frequency gains), K_ij.
  v << 3.44e-3, 0.0877, 5.3e-6, 5.3e-6, 5.3e-6, 8.9e-6, 8.9e-6, 8.9e-6;
  return v;
}

config::TestCase test_case(const std::string& name, CaseKind kind, const frames::Dcm& m_ec, const std::string& mounting) {
  config::TestCase tc;
  tc.name = name;
  tc.kind = kind;
  tc.m_ec = m_ec;
  tc.mounting = mounting;
  return tc;
}

/// Gravity sweeping over the sphere (a table turning about changing axes).
dataset::CaseData table_rows(Index n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phase(0.0, 6.28);
  const double p1 = phase(rng), p2 = phase(rng);
  dataset::CaseData c;
  c.a_e.resize(n, 3);
  for (Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * kPeriod;
    const double th = 1.5 + 1.4 * std::sin(1.9 * t + p1), ph = 3.1 * t + p2;
    c.a_e.row(k) << kG * std::sin(th) * std::cos(ph), kG * std::sin(th) * std::sin(ph), kG * std::cos(th);
  }
  return c;
}

/// Gravity along z_E plus random vibration along x_E (sd 3 g).
dataset::CaseData shaker_rows(Index n, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> v(0.0, 3.0 * kG);
  dataset::CaseData c;
  c.a_e.resize(n, 3);
  for (Index k = 0; k < n; ++k) c.a_e.row(k) << v(rng), 0.0, kG;
  return c;
}

/// y of the model on the case's references with M_E^S = m_cs * m_ec, squares through s/(s + corner),
/// plus white noise.
void set_output(dataset::CaseData& c, const frames::Dcm& m_cs, const frames::Dcm& m_ec, double corner, double noise_sd,
                std::uint32_t seed, const Eigen::VectorXd& truth) {
  const Index n = c.a_e.rows();
  c.sample_period_s = kPeriod;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
  c.w_e = dataset::Matrix3Columns::Zero(n, 3);
  c.y = Eigen::VectorXd::Zero(n);
  const std::vector<ident::Term> terms = ident::parse_terms(kModel);
  const ident::SignalSet s = ident::signals_from_case(c, m_cs * m_ec, 25.0);
  const ident::Regression reg = ident::build_regression(terms, s);
  Eigen::MatrixXd phi = reg.phi;
  for (Index j = 2; j <= 4; ++j) procedure::highpass_in_place(phi.col(j), corner, kPeriod);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_sd);
  c.y = phi * truth;
  for (Index k = 0; k < n; ++k) c.y(k) += noise(rng);
}

struct Plan {
  std::vector<PlanCase> cases;
  frames::Dcm table_m_cs, shaker_m_cs;
};

/// A table mounting (one case) and a shaker fixture carrying three orientations (one mounting),
/// each with its own case misalignment, as the paper's Fig. 2 bench; `shaker_orientations` < 3
/// keeps the first ones (IA, then PA).
Plan two_mountings(double corner, double noise_sd, std::uint32_t seed, Index table_n = 6000, Index shaker_n = 3000,
                   const Eigen::VectorXd& truth = truth_values(), int shaker_orientations = 3) {
  Plan p;
  // Rotations about axes normal to the input axis: algorithm 1 sees all of them (a turn about n_i
  // itself is not observable from one axis and would leave a_p, a_o in another frame than truth's).
  p.table_m_cs = frames::frame_rotation(Eigen::Vector3d(0.0, 0.3, 1.0), deg_to_rad(2.0));
  p.shaker_m_cs = frames::frame_rotation(Eigen::Vector3d(0.0, 1.0, -0.6), deg_to_rad(1.5));
  PlanCase table{test_case("rotation-table", CaseKind::RotationTable, frames::Dcm::Identity(), ""), table_rows(table_n, seed)};
  set_output(table.data, p.table_m_cs, table.tc.m_ec, corner, noise_sd, seed + 1, truth);
  p.cases.push_back(std::move(table));
  const char* names[3] = {"shaker-ia", "shaker-pa", "shaker-oa"};
  const config::Orientation orientations[3] = {config::Orientation::IA, config::Orientation::PA, config::Orientation::OA};
  for (int o = 0; o < shaker_orientations; ++o) {
    const frames::Dcm m_ec = config::slot_orientation(orientations[o], deg_to_rad(25.0));
    PlanCase c{test_case(names[o], CaseKind::Shaker, m_ec, "shaker-fixture"), shaker_rows(shaker_n, seed + 10 + static_cast<std::uint32_t>(o))};
    set_output(c.data, p.shaker_m_cs, m_ec, corner, noise_sd, seed + 20 + static_cast<std::uint32_t>(o), truth);
    p.cases.push_back(std::move(c));
  }
  return p;
}

fusion::FusedChunk chunk_of(const PlanCase& c, std::size_t case_index, Index from, Index n, int segment = 0) {
  fusion::FusedChunk k;
  k.case_index = case_index;
  k.case_name = c.tc.name;
  k.kind = c.tc.kind;
  k.segment = segment;
  k.sample_period_s = kPeriod;
  k.first_row = from;
  k.t = c.data.t.segment(from, n);
  k.a_e = c.data.a_e.middleRows(from, n);
  k.w_e = c.data.w_e->middleRows(from, n);
  k.y = c.data.y.segment(from, n);
  k.phase.assign(static_cast<std::size_t>(n), 0);
  k.phase_names = {"run"};
  return k;
}

/// Feeds every case, one segment each, in chunks of random length.
void feed(OnlineEstimator& est, const Plan& p, std::uint32_t seed, std::size_t cases = 99) {
  std::mt19937 rng(seed);
  for (std::size_t i = 0; i < p.cases.size() && i < cases; ++i) {
    const PlanCase& c = p.cases[i];
    for (Index k = 0; k < c.data.y.size();) {
      const Index n = std::min<Index>(1 + static_cast<Index>(rng() % 900), c.data.y.size() - k);
      est.push(chunk_of(c, i, k, n), c.tc);
      k += n;
    }
    est.end_segment({i, c.tc.name, 0, c.data.y.size(), true});
  }
}

model::ModelFile model_file(const std::vector<std::string>& terms, std::optional<double> corner) {
  model::ModelFile m;
  for (const std::string& t : terms) m.terms.push_back({ident::parse_term(t), 0.0, std::nullopt});
  m.square_highpass_rad_s = corner;
  return m;
}

OnlineOptions white_noise() {
  OnlineOptions o;
  o.noise_window_s = 0.0;
  o.nominal_sample_period_s = kPeriod;
  return o;
}

dataset::Dataset as_dataset(const Plan& p) {
  dataset::Dataset d;
  d.sensor = dataset::SensorKind::Accelerometer;
  d.t_ref = 25.0;
  for (const PlanCase& c : p.cases) {
    dataset::CaseData cd = c.data;
    cd.name = c.tc.name;
    cd.kind = c.tc.kind;
    cd.m_ec = c.tc.m_ec;
    cd.mounting = c.tc.mounting;
    d.cases.push_back(std::move(cd));
  }
  return d;
}

/// The batch pipeline as the live estimator runs it: the fixed model and corner, white noise.
procedure::PipelineOptions fixed_model_pipeline() {
  procedure::PipelineOptions po;
  po.misalignment.select = false;
  po.misalignment.fixed_terms = {"a_x", "a_y", "a_z", "1", "a_i^2", "a_p^2", "a_o^2", "a_i*a_p", "a_i*a_o", "a_p*a_o"};
  po.batch.select = false;
  po.batch.fixed_terms = kModel;
  po.whitening_max_order = 0;
  po.max_refinements = 50;
  po.square_highpass_min_rad_s = 500.0;   // the model's corner
  po.square_highpass_max_rad_s = 500.0;
  return po;
}

/// The live estimate's terms against the batch's: values within `within` of the batch's sd; and
/// the sd. Both include what the mountings' misalignment uncertainty moves, by two first-order
/// routes: the live one propagates each mounting's angle covariance through the coefficients
/// (delta method, angle and coefficient errors taken as independent); the batch fits the angles'
/// derivative columns jointly with the terms (procedure/post_selection_inference.hpp, SearchedColumns), so
/// the rows both use count once. The joint route is the larger: on this plan the live sd are 0.89
/// to 0.99 of the batch's (measured 2026-11-26). Asserted: never above the batch's but for its
/// white level, an estimate from a case's 3000 rows (1/sqrt(3000) in variance, half that in sd;
/// three of it here), and not below 0.85 of it (the measured difference of the two methods with a
/// margin: a bound on a method, not on noise).
void expect_the_batchs_terms(const OnlineSnapshot& live, const procedure::PipelineResult& batch, double within) {
  ASSERT_EQ(batch.fit.labels.size(), kModel.size());
  for (std::size_t j = 0; j < kModel.size(); ++j) {
    const auto jj = static_cast<Index>(j);
    const auto b = static_cast<Index>(std::find(batch.fit.labels.begin(), batch.fit.labels.end(), kModel[j]) - batch.fit.labels.begin());
    EXPECT_NEAR(live.values(jj), batch.fit.theta(b), within * batch.fit.std_dev(b)) << kModel[j];
    const double ratio = live.std_devs(jj) / batch.fit.std_dev(b);
    EXPECT_LE(ratio, 1.0 + 1.5 / std::sqrt(3000.0)) << kModel[j];
    EXPECT_GE(ratio, 0.85) << kModel[j];
  }
}

TEST(OnlineEstimator, EqualsTheBatchPipelineOnTheSameRows) {
  // The exact route of the issue: sufficient statistics per mounting, algorithm 1 re-derived from
  // them, give the batch procedure's answer on the same samples (fixed model and corner, white
  // noise, so the two run the same estimator; only the arithmetic differs).
  // The mountings' twists about n_i are held at algorithm 1's frame in both here (the next test
  // finds them in both).
  const Plan p = two_mountings(500.0, 1e-3, 11);
  OnlineOptions options = white_noise();
  options.solver.relative_twist = false;
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, options);
  feed(est, p, 3);
  const OnlineSnapshot live = est.snapshot();

  procedure::PipelineOptions po = fixed_model_pipeline();
  po.batch_relative_twist = false;
  const procedure::PipelineResult batch = procedure::run_pipeline(as_dataset(p), po, "test");
  ASSERT_EQ(batch.square_corner_rad_s.value_or(0.0), 500.0);
  ASSERT_EQ(batch.mountings.size(), 2u);
  ASSERT_EQ(live.mountings.size(), 2u);
  for (std::size_t m = 0; m < 2; ++m) {
    SCOPED_TRACE(live.mountings[m].name);
    EXPECT_EQ(live.mountings[m].name, batch.mountings[m].mounting);
    EXPECT_LT(frames::angle_between(live.mountings[m].m_cs, batch.mountings[m].m_cs), 1e-12);
  }
  ASSERT_EQ(batch.fit.labels.size(), kModel.size());
  EXPECT_EQ(live.samples_used, 6000 + 3 * 3000);
  expect_the_batchs_terms(live, batch, 1e-6);
  // And the truth within the noise: coefficients and each mounting's misalignment.
  const Eigen::VectorXd truth = truth_values();
  for (Index j = 0; j < truth.size(); ++j) EXPECT_NEAR(live.values(j), truth(j), 4.0 * live.std_devs(j)) << kModel[static_cast<std::size_t>(j)];
  const frames::Dcm truths[2] = {p.table_m_cs, p.shaker_m_cs};
  for (std::size_t m = 0; m < 2; ++m) {
    const MountingEstimate& e = live.mountings[m];
    ASSERT_TRUE(e.determined);
    EXPECT_TRUE(std::isnan(e.angles_rad(0))) << "a single axis does not see its own turn";
    // The input axis: algorithm 1 fixes n_i; its tilt from truth against the angles' sd.
    const double tilt = frames::axis_angle_between(e.m_cs.row(0).transpose(), truths[m].row(0).transpose());
    EXPECT_LT(tilt, 4.0 * e.angles_sd_rad.tail<2>().norm()) << e.name;
    EXPECT_GT(e.angles_sd_rad(1), 0.0);
  }
}

/// How far the live and the batch searches for a mounting's turn may end apart, in the turn's sd,
/// derived from the searches and the problem (not from what one machine printed). Both take the
/// batch's Gauss-Newton steps (procedure::search_turns) on the same whitened rows, the batch from
/// the rows and live from the statistics' sums (LiveSolver::turn_derivative_gram):
/// - each stops once its steps are at most procedure::kTurnConvergence of the sd;
/// - live's J~'r is a difference of sums of the size |D| |y| (D'y less D'X theta, p products
///   each), so its rounding is at most p eps |D| |y|. A turn moves a term of degree at most two by
///   at most twice its size per radian, so |D| <= 2 |y| for a prediction of the output's size: an
///   error of 2 p eps y'y;
/// - the information J~'J~ = s^2 / sd^2 turns that into a shift of 2 p eps y'y sd / s^2.
/// The rounding itself differs between CPUs' libm paths and builds; this bound does not.
/// `live_searches`: how many of the two searches are the live one (1: live against batch, 2: two
/// live runs).
double turn_search_agreement_in_sd(const Plan& p, double twist_sd, double noise_sd, int live_searches = 1) {
  double yy = 0.0;
  for (const PlanCase& c : p.cases) yy += c.data.y.squaredNorm();
  const double rounding = 2.0 * static_cast<double>(kModel.size()) * std::numeric_limits<double>::epsilon() * yy;
  const double rounding_shift_in_sd = rounding * twist_sd / (noise_sd * noise_sd);
  return 2.0 * procedure::kTurnConvergence + live_searches * rounding_shift_in_sd;
}

TEST(OnlineEstimator, FindsTheBatchsTwistAgainstTheReferenceMounting) {
  // PipelineOptions::batch_relative_twist: the shaker mounting turned about n_i against the table
  // to one set of cross terms for both, by Gauss-Newton on the batch's rows; live, by the same
  // steps from its statistics (LiveSolver::relative_turns). The two searches end apart
  // by at most turn_search_agreement_in_sd; a coefficient moves with the three angles searched,
  // each of whose sd-sized shift moves it by at most its own sd (the batch's sd carry the angles'
  // uncertainty), so the terms agree within three times that in their sd.
  constexpr double kNoiseSd = 1e-3;
  const Plan p = two_mountings(500.0, kNoiseSd, 11);
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
  feed(est, p, 3);
  const OnlineSnapshot live = est.snapshot();
  const procedure::PipelineResult batch = procedure::run_pipeline(as_dataset(p), fixed_model_pipeline(), "test");
  ASSERT_EQ(batch.mountings.size(), 2u);
  ASSERT_EQ(live.mountings.size(), 2u);
  const procedure::MountingResult& shaker = batch.mountings[1];
  ASSERT_EQ(shaker.twist_reference, batch.mountings[0].mounting);
  ASSERT_GT(shaker.angles_sd(0), 0.0) << "the twist was held";
  const double within = turn_search_agreement_in_sd(p, shaker.angles_sd(0), kNoiseSd);
  // The bound must still say something: far below the sd, so a search that stopped early or
  // found another minimum fails.
  ASSERT_LT(within, 0.01);
  std::cout << "live and batch searches may end " << within << " sd apart\n";
  EXPECT_NEAR(live.mountings[1].angles_rad(0), shaker.angles(0), within * shaker.angles_sd(0));
  EXPECT_LT(frames::angle_between(live.mountings[1].m_cs, shaker.m_cs), within * shaker.angles_sd.norm());
  EXPECT_TRUE(std::isnan(live.mountings[0].angles_rad(0))) << "the reference's twist is the convention";
  expect_the_batchs_terms(live, batch, 3.0 * within);   // the twist's uncertainty in the sd by the two routes
}

/// The shaker fixture with `orientations` of IA, PA (two_mountings, seed 11) under a 2 deg mounting
/// tolerance: live and the batch on the same rows.
struct WeakFixture {
  static constexpr double kNoiseSd = 1e-3;
  static inline const double kTolerance = deg_to_rad(2.0);
  Plan plan;
  OnlineSnapshot live;
  procedure::PipelineResult batch;
};
WeakFixture weak_fixture(int orientations) {
  WeakFixture f;
  f.plan = two_mountings(500.0, WeakFixture::kNoiseSd, 11, 6000, 3000, truth_values(), orientations);
  OnlineOptions options = white_noise();
  options.solver.mounting_tolerance_rad = WeakFixture::kTolerance;
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, options);
  feed(est, f.plan, 3);
  f.live = est.snapshot();
  procedure::PipelineOptions po = fixed_model_pipeline();
  po.mounting_tolerance_rad = WeakFixture::kTolerance;
  f.batch = procedure::run_pipeline(as_dataset(f.plan), po, "test");
  return f;
}

TEST(OnlineEstimator, FindsTheBatchsTwistWhereTheFixtureDeterminesItWeakly) {
  // Two orientations on the fixture (IA, PA): the twist is determined weakly, and the residual sum
  // is not convex on the way to it. Gauss-Newton's J~'J~ is positive in every step, on the rows and
  // on the statistics alike, so live lands where the batch does.
  // The tolerance is 2 deg: the twist's sd with the tilts free is about 0.5 deg here.
  const WeakFixture f = weak_fixture(2);
  const Plan& p = f.plan;
  const OnlineSnapshot& live = f.live;
  const procedure::PipelineResult& batch = f.batch;
  ASSERT_EQ(live.mountings.size(), 2u);
  const procedure::MountingResult& shaker = batch.mountings[1];
  ASSERT_GT(shaker.angles_sd(0), 0.0) << "the batch held the twist";
  ASSERT_GT(live.mountings[1].angles_sd_rad(0), 0.0) << "live held the twist, or its sd is not positive";
  const double within = turn_search_agreement_in_sd(p, shaker.angles_sd(0), WeakFixture::kNoiseSd);
  EXPECT_NEAR(live.mountings[1].angles_rad(0), shaker.angles(0), within * shaker.angles_sd(0));
}

TEST(OnlineEstimator, HoldsTheTwistWhereAHeldTiltLeavesItNoSingleLeastResidual) {
  // One orientation on the fixture (IA): its tilt about p is not excited, and stays at the nominal
  // frame 1.3 deg from its truth. At the nominal frame the twist looks determined (sd 0.15 deg live),
  // but the residual the held tilt leaves has no single least value near it: Gauss-Newton's steps
  // go 9 deg one way, then 14 and 16 the other, and still move two thirds of the live sd after 12
  // steps, at 13 deg, where the batch's sd (under the residual's fitted spectrum) is 11 deg. The
  // two mountings' true frames differ about n_i by a few hundredths of a degree (the product of
  // their 2 and 1.5 deg tilts). Both hold the twist at the nominal frame, and the batch says why.
  const WeakFixture f = weak_fixture(1);
  const OnlineSnapshot& live = f.live;
  const procedure::PipelineResult& batch = f.batch;
  const double tolerance = WeakFixture::kTolerance;
  ASSERT_EQ(live.mountings.size(), 2u);
  const procedure::MountingResult& shaker = batch.mountings[1];
  EXPECT_EQ(shaker.angles(0), 0.0) << "the batch's twist is at the nominal frame";
  EXPECT_EQ(shaker.angles_sd(0), 0.0) << "the batch's twist is held";
  EXPECT_TRUE(std::any_of(batch.notes.begin(), batch.notes.end(), [](const std::string& n) {
    return n.find("twist about n_i of mounting 'shaker-fixture'") != std::string::npos && n.find("held at the nominal frame") != std::string::npos;
  })) << "the batch says why";
  EXPECT_TRUE(std::isnan(live.mountings[1].angles_rad(0))) << "live holds the twist: " << live.mountings[1].angles_rad(0);
  EXPECT_NE(live.mountings[1].note.find("search for the twist about n_i of mounting 'shaker-fixture' against 'rotation-table' did not settle"),
            std::string::npos)
      << "live says why: " << live.mountings[1].note;
  EXPECT_EQ(live.mountings[1].angles_sd_rad(1), tolerance) << "the tilt about p held";
  // The terms carry what the held angles move (the tolerance) in their sd: each within 3 sd.
  const Eigen::VectorXd truth = truth_values();
  for (Index j = 0; j < truth.size(); ++j) {
    const auto at = std::find(live.terms.begin(), live.terms.end(), kModel[static_cast<std::size_t>(j)]);
    ASSERT_NE(at, live.terms.end());
    const auto k = at - live.terms.begin();
    EXPECT_NEAR(live.values(k), truth(j), 3.0 * live.std_devs(k)) << "live " << kModel[static_cast<std::size_t>(j)];
    const auto b = std::find(batch.fit.labels.begin(), batch.fit.labels.end(), kModel[static_cast<std::size_t>(j)]);
    ASSERT_NE(b, batch.fit.labels.end());
    const auto i = b - batch.fit.labels.begin();
    EXPECT_NEAR(batch.fit.theta(i), truth(j), 3.0 * batch.fit.std_dev(i)) << "batch " << kModel[static_cast<std::size_t>(j)];
  }
}

TEST(OnlineEstimator, ChunkingDoesNotMatter) {
  // The statistics are the same however the samples arrive, to rounding: with the mountings'
  // frames fixed by algorithm 1 the estimates agree to 1e-6 of their sd; the twist's search reads
  // sums the rounding reaches, so there two live searches end apart by at most
  // turn_search_agreement_in_sd (the previous test says why), the terms three times that.
  constexpr double kNoiseSd = 1e-3;
  const Plan p = two_mountings(500.0, kNoiseSd, 21, 3000, 2000);
  for (const bool twist : {false, true}) {
    SCOPED_TRACE(twist ? "twist searched" : "twist held");
    OnlineOptions options = white_noise();
    options.solver.relative_twist = twist;
    OnlineEstimator a(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, options);
    OnlineEstimator b(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, options);
    feed(a, p, 1);
    feed(b, p, 2);
    const OnlineSnapshot sa = a.snapshot(), sb = b.snapshot();
    ASSERT_EQ(sa.samples_used, sb.samples_used);
    ASSERT_EQ(sa.mountings.size(), 2u);
    const double within =
        twist ? 3.0 * turn_search_agreement_in_sd(p, sa.mountings[1].angles_sd_rad(0), kNoiseSd, 2) : 1e-6;
    if (twist) {
      ASSERT_LT(within, 0.03);
    }
    for (Index j = 0; j < sa.values.size(); ++j)
      EXPECT_NEAR(sa.values(j), sb.values(j), 1e-12 * std::abs(sa.values(j)) + within * sa.std_devs(j));
  }
}

TEST(OnlineEstimator, TheSquaresCornerIsFoundBetweenTheGridsNodes) {
  // 500 rad/s lies between nodes of the grid (1 .. 0.9 Nyquist, six a decade); the live search
  // finds it on the interpolated columns as the batch finds it on filtered data.
  const Plan p = two_mountings(500.0, 1e-4, 31);
  OnlineEstimator est(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, white_noise());
  feed(est, p, 4);
  const OnlineSnapshot s = est.snapshot();
  ASSERT_TRUE(s.corner_rad_s.has_value());
  EXPECT_NEAR(*s.corner_rad_s, 500.0, 0.02 * 500.0);
  const Eigen::VectorXd truth = truth_values();
  for (Index j = 0; j < truth.size(); ++j) {
    // Interpolation costs at most 1.1e-3 of the squares' response: a bound on top of the noise.
    EXPECT_NEAR(s.values(j), truth(j), 4.0 * s.std_devs(j) + 3e-3 * std::abs(truth(j))) << s.terms[static_cast<std::size_t>(j)];
  }
}

TEST(OnlineEstimator, TheDefaultModelLeavesOutATermTheDataShowsInsignificantAModelFileKeepsIt) {
  // A sensor without cross-coupling between p and o: the default terms are a search, and the term
  // leaves as the batch's inference takes it out (ident::term_leaving); a model file's terms are
  // fitted as given.
  Eigen::VectorXd truth = truth_values();
  truth(7) = 0.0;   // a_p*a_o
  const Plan p = two_mountings(500.0, 1e-4, 31, 6000, 3000, truth);
  OnlineEstimator searched(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, white_noise());
  feed(searched, p, 4);
  const OnlineSnapshot s = searched.snapshot();
  EXPECT_EQ(s.insignificant, std::vector<std::string>{"a_p*a_o"}) << s.convergence;
  EXPECT_TRUE(std::isnan(s.values(7)));
  EXPECT_NE(s.convergence.find("not significant: a_p*a_o"), std::string::npos) << s.convergence;
  for (Index j = 0; j < 7; ++j)
    EXPECT_NEAR(s.values(j), truth(j), 4.0 * s.std_devs(j) + 3e-3 * std::abs(truth(j))) << s.terms[static_cast<std::size_t>(j)];
  OnlineEstimator given(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
  feed(given, p, 4);
  const OnlineSnapshot g = given.snapshot();
  EXPECT_TRUE(g.insignificant.empty());
  ASSERT_TRUE(std::isfinite(g.values(7)));
  EXPECT_NEAR(g.values(7), 0.0, 4.0 * g.std_devs(7));
}

TEST(OnlineEstimator, AHeldTiltsSecondOrderShiftIsInAStaticPosesScaleFactorSd) {
  // Two static poses, the input axis up and down: no pose excites a tilt, so both are held within
  // the mounting tolerance, and the scale factor read as K cos(tilt) is uncertain by
  // K (1 - cos(tolerance)) per held tilt, the batch's one-sided refit (procedure::held_angle_response).
  // A symmetric difference gives 0 there, and the sd would be the noise's alone.
  const double k = 0.0877, bias = 3e-3, noise_sd = 1e-5;
  const Index n = 4000;
  std::vector<PlanCase> poses;
  for (int pose = 0; pose < 2; ++pose) {
    dataset::CaseData c;
    c.sample_period_s = kPeriod;
    c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
    c.a_e = dataset::Matrix3Columns::Zero(n, 3);
    c.a_e.col(0).setConstant(pose == 0 ? kG : -kG);
    c.w_e = dataset::Matrix3Columns::Zero(n, 3);
    std::mt19937_64 rng(77 + static_cast<std::uint64_t>(pose));
    std::normal_distribution<double> noise(0.0, noise_sd);
    c.y.resize(n);
    for (Index r = 0; r < n; ++r) c.y(r) = bias + k * c.a_e(r, 0) + noise(rng);
    poses.push_back({test_case(pose == 0 ? "up" : "down", CaseKind::Static, frames::Dcm::Identity(), "poses"), c});
  }
  model::ModelFile m = model_file({"1", "a_i"}, std::nullopt);
  OnlineEstimator est(dataset::SensorKind::Accelerometer, m, 25.0, white_noise());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    est.push(chunk_of(poses[i], i, 0, n), poses[i].tc);
    est.end_segment({i, poses[i].tc.name, 0, n, true});
  }
  const OnlineSnapshot s = est.snapshot();
  ASSERT_TRUE(std::isfinite(s.values(1))) << s.convergence;
  const double held = std::sqrt(2.0) * k * (1.0 - std::cos(SolverOptions{}.mounting_tolerance_rad));
  const double noise_alone = noise_sd / (kG * std::sqrt(2.0 * static_cast<double>(n)));
  ASSERT_LT(noise_alone, 1e-3 * held);
  EXPECT_NEAR(s.std_devs(1), held, 1e-3 * held);
  EXPECT_NEAR(s.values(1), k, 4.0 * noise_alone);
}

TEST(OnlineEstimator, NotDeterminedYetIsSaidNotGuessed) {
  // The table alone: the squares cannot be told from the bias (a_i^2 + a_p^2 + a_o^2 = g^2).
  const Plan p = two_mountings(500.0, 1e-3, 41, 4000, 2000);
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
  feed(est, p, 5, 1);
  const OnlineSnapshot s = est.snapshot();
  EXPECT_FALSE(s.undetermined.empty());
  EXPECT_FALSE(s.converged);
  for (const std::string& t : s.undetermined) {
    const auto j = static_cast<Index>(std::find(s.terms.begin(), s.terms.end(), t) - s.terms.begin());
    EXPECT_TRUE(std::isnan(s.values(j))) << t;
  }
  // Nothing yet at all: every term undetermined, no exception.
  OnlineEstimator empty(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, white_noise());
  EXPECT_EQ(empty.snapshot().undetermined.size(), kModel.size());
}

TEST(OnlineEstimator, AShakerPlanThatAlignsNoMountingHoldsTheAnglesAndFitsTheFrameFreeTermsAsTheBatch) {
  // config/sim-shaker.toml's shape: the three orientations, each remounted (no shared label), no
  // table. In each, the vibration along x_E moves IRA and XRA together and gravity is constant, so
  // no tilt has excitation of its own (procedure/excitation.hpp): every angle is held at the
  // nominal frame, the sensor frame's p and o axes are known in no case, and only the terms that
  // hold in any frame near it are fitted, as the batch does (procedure::frame_free).
  Plan p = two_mountings(500.0, 1e-3, 61, 4000, 3000);
  p.cases.erase(p.cases.begin());
  for (PlanCase& c : p.cases) c.tc.mounting.clear();
  OnlineOptions options = white_noise();
  for (const PlanCase& c : p.cases) options.plan.push_back({c.tc.name, c.tc.mounting, c.tc.kind});
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, options);
  feed(est, p, 7);
  const OnlineSnapshot live = est.snapshot();
  ASSERT_EQ(live.mountings.size(), 3u);
  for (const MountingEstimate& m : live.mountings) {
    SCOPED_TRACE(m.name);
    EXPECT_FALSE(m.determined);
    EXPECT_NE(m.note.find("held at the nominal case frame"), std::string::npos) << m.note;
    EXPECT_NEAR(m.angles_sd_rad(1), deg_to_rad(1.0), 1e-15) << "the mounting tolerance";
    EXPECT_NEAR(m.angles_sd_rad(2), deg_to_rad(1.0), 1e-15);
    EXPECT_LT(frames::angle_between(m.m_cs, frames::Dcm::Identity()), 1e-15);
  }
  // The frame-free terms are estimated, the rest said to be beyond this plan, and that does not
  // hold the convergence flag back.
  const std::vector<std::string> frame_free = {"1", "a_i"};
  for (std::size_t j = 0; j < kModel.size(); ++j) {
    const bool free = std::find(frame_free.begin(), frame_free.end(), kModel[j]) != frame_free.end();
    EXPECT_EQ(std::isfinite(live.values(static_cast<Index>(j))), free) << kModel[j];
    EXPECT_EQ(std::find(live.plan_undetermined.begin(), live.plan_undetermined.end(), kModel[j]) != live.plan_undetermined.end(),
              !free)
        << kModel[j];
  }
  EXPECT_NE(live.convergence.find("no mounting is aligned"), std::string::npos) << live.convergence;
  EXPECT_TRUE(live.converged) << live.convergence;

  // The batch pipeline on the same rows with the same two terms: the same frames (held), the same
  // values. The sd carry the held angles by the two routes of expect_the_batchs_terms.
  procedure::PipelineOptions po = fixed_model_pipeline();
  po.batch.fixed_terms = frame_free;
  const procedure::PipelineResult batch = procedure::run_pipeline(as_dataset(p), po, "test");
  ASSERT_EQ(batch.mountings.size(), 3u);
  for (const procedure::MountingResult& m : batch.mountings) EXPECT_FALSE(m.aligned) << m.mounting;
  for (std::size_t j = 0; j < frame_free.size(); ++j) {
    const auto b = static_cast<Index>(std::find(batch.fit.labels.begin(), batch.fit.labels.end(), frame_free[j]) -
                                      batch.fit.labels.begin());
    ASSERT_LT(b, static_cast<Index>(batch.fit.labels.size())) << frame_free[j];
    const auto l = static_cast<Index>(std::find(kModel.begin(), kModel.end(), frame_free[j]) - kModel.begin());
    EXPECT_NEAR(live.values(l), batch.fit.theta(b), 1e-6 * batch.fit.std_dev(b)) << frame_free[j];
    // The held angles reach the sd by two routes: the batch refits at the tolerance and counts the
    // offsets between phases; the live turns each mounting by its tolerance and counts the
    // offsets between cases. Measured 2026-11-27: live/batch 0.81 for the bias, 0.99 for a_i. A
    // bound on the methods' difference, with a margin, not on noise.
    const double ratio = live.std_devs(l) / batch.fit.std_dev(b);
    EXPECT_GT(ratio, 0.75) << frame_free[j];
    EXPECT_LT(ratio, 1.05) << frame_free[j];
  }
  // And the truth, within the sd the held angles widen (each mounting is turned 1.5 deg).
  EXPECT_NEAR(live.values(1), truth_values()(1), 3.0 * live.std_devs(1));
}

TEST(OnlineEstimator, ATumblesPlacementScatterIsNotNamedAsCrossTerms) {
  // config/sim-tumble.toml's shape: six static poses of a linear sensor, each placed 3 mrad (per
  // axis) off its nominal pose. In a pose every term is constant, so the cross terms can fit the
  // poses' placement offsets; with four terms and the mounting's two tilts at the level of six
  // poses' means, no pose is left to tell them apart. The live estimate leaves out the weakest
  // such terms while none is left over or its t fails Student's test on what is (as the batch
  // does), and counts those levels in the offsets' degrees of freedom. Before, a_i*a_p and a_i*a_o
  // came out at t of 400 on sim-tumble's log; here all three cross terms leave in 10 of 10 seeds.
  const std::vector<std::string> model = {"1", "a_i", "a_i*a_p", "a_i*a_o", "a_p*a_o"};
  const frames::Dcm poses[6] = {
      (frames::Dcm() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished(), (frames::Dcm() << 0, 0, -1, 0, 1, 0, 1, 0, 0).finished(),
      (frames::Dcm() << 1, 0, 0, 0, 0, 1, 0, -1, 0).finished(), (frames::Dcm() << 0, 1, 0, 0, 0, -1, -1, 0, 0).finished(),
      (frames::Dcm() << 0, -1, 0, 1, 0, 0, 0, 0, 1).finished(), (frames::Dcm() << 1, 0, 0, 0, -1, 0, 0, 0, -1).finished()};
  const frames::Dcm m_cs = frames::frame_rotation(Eigen::Vector3d(0.0, 1.0, 1.0), deg_to_rad(0.05));
  int named = 0;
  constexpr int kSeeds = 10;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
    std::normal_distribution<double> placement(0.0, 3e-3), noise(0.0, 1e-3);
    Plan p;
    OnlineOptions options = white_noise();
    for (int k = 0; k < 6; ++k) {
      PlanCase c{test_case("pose-" + std::to_string(k), CaseKind::Static, poses[k], ""), {}};
      const Index n = 2000;
      c.data.sample_period_s = kPeriod;
      c.data.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
      c.data.a_e = dataset::Matrix3Columns::Zero(n, 3);
      c.data.a_e.col(2).setConstant(kG);
      c.data.w_e = dataset::Matrix3Columns::Zero(n, 3);
      // The pose as placed: off its nominal by a small random rotation.
      const frames::Dcm placed =
          poses[k] * frames::frame_rotation(Eigen::Vector3d(placement(rng), placement(rng), placement(rng)).normalized(),
                                            std::sqrt(3.0) * 3e-3);
      const Eigen::Vector3d a = m_cs * placed * Eigen::Vector3d(0.0, 0.0, kG);
      c.data.y = Eigen::VectorXd::Constant(n, 3.44e-3 + 0.0877 * a(0));
      for (Index r = 0; r < n; ++r) c.data.y(r) += noise(rng);
      options.plan.push_back({c.tc.name, "", CaseKind::Static});
      p.cases.push_back(std::move(c));
    }
    OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(model, std::nullopt), 25.0, options);
    feed(est, p, static_cast<std::uint32_t>(seed));
    const OnlineSnapshot s = est.snapshot();
    ASSERT_EQ(s.mountings.size(), 1u) << "the unlabelled poses share one mounting, as the batch infers";
    bool any = false;
    for (std::size_t j = 2; j < model.size(); ++j) {
      const double t = s.values(static_cast<Index>(j)) / s.std_devs(static_cast<Index>(j));
      if (std::isfinite(t) && std::abs(t) > 3.0) any = true;
    }
    EXPECT_FALSE(s.confounded.empty()) << "seed " << seed << ": " << s.convergence;
    EXPECT_NEAR(s.values(1), 0.0877, 4.0 * s.std_devs(1)) << "seed " << seed;
    named += any ? 1 : 0;
  }
  // The t-test's 3 sd: a cross term named in 1 of 10 seeds is already a 1 % tail.
  EXPECT_LE(named, 1) << "seeds with a cross term at |t| > 3";
}

TEST(OnlineEstimator, ConvergedNeverWhileOneMoreCaseWouldMoveACoefficientByThreeSd) {
  // The definition in docs/live-estimates.md ("Converged"), tested as stated: over a plan of
  // repeated orientations, whenever the flag is set after a case, the next case moves every
  // coefficient by less than 3 of its sd.
  int converged_count = 0;
  for (std::uint32_t seed = 1; seed <= 4; ++seed) {
    Plan p = two_mountings(500.0, 1e-3, 100 * seed, 4000, 2000);
    const Plan again = two_mountings(500.0, 1e-3, 100 * seed + 50, 4000, 2000);
    for (std::size_t i = 1; i < again.cases.size(); ++i) {
      PlanCase c = again.cases[i];
      c.tc.name += "-2";
      p.cases.push_back(std::move(c));
    }
    OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
    std::optional<OnlineSnapshot> before;
    for (std::size_t i = 0; i < p.cases.size(); ++i) {
      const PlanCase& c = p.cases[i];
      est.push(chunk_of(c, i, 0, c.data.y.size()), c.tc);
      est.end_segment({i, c.tc.name, 0, c.data.y.size(), true});
      const OnlineSnapshot now = est.snapshot();
      if (before && before->converged) {
        ++converged_count;
        for (Index j = 0; j < now.values.size(); ++j)
          EXPECT_LT(std::abs(now.values(j) - before->values(j)), 3.0 * before->std_devs(j))
              << "seed " << seed << ", after case " << c.tc.name << ": " << now.terms[static_cast<std::size_t>(j)];
      }
      before = now;
    }
    EXPECT_TRUE(before->converged) << before->convergence;
  }
  EXPECT_GT(converged_count, 0) << "the test must see the flag set";

  // A sensor that changes between cases (scale factor +1 %) is never called converged.
  Plan p = two_mountings(500.0, 1e-3, 7, 4000, 2000);
  p.cases[3].data.y *= 1.01;
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
  feed(est, p, 6);
  const OnlineSnapshot s = est.snapshot();
  EXPECT_FALSE(s.converged) << s.convergence;
}

/// Feeds one case in chunks whose rows carry `phases` plan phases of equal length, every phase
/// labelled alike (one cluster of the case scatter, as consecutive phases of one kind are).
void feed_phased(OnlineEstimator& est, const PlanCase& c, std::size_t case_index, int phases) {
  const Index n = c.data.y.size();
  for (Index k = 0; k < n;) {
    const Index m = std::min<Index>(700, n - k);
    fusion::FusedChunk chunk = chunk_of(c, case_index, k, m);
    for (Index r = 0; r < m; ++r) chunk.plan_phase.push_back(static_cast<std::int32_t>((k + r) * phases / n));
    est.push(chunk, c.tc);
    k += m;
  }
  est.end_segment({case_index, c.tc.name, 0, n, true});
}

TEST(OnlineEstimator, APlanWithNoCaseToSpareIsCheckedByItsPhases) {
  // Two poses, input axis up and down (config/sim-thermal.toml's plan): without either, the bias
  // and the scale factor are one number, so leaving a case out tests nothing. The poses' plan
  // phases stand in for replicates.
  const auto pose = [](const std::string& name, double g, std::uint32_t seed) {
    dataset::CaseData c;
    const Index n = 8000;
    c.a_e = dataset::Matrix3Columns::Zero(n, 3);
    c.a_e.col(0).setConstant(g * kG);
    c.w_e = dataset::Matrix3Columns::Zero(n, 3);
    c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
    c.sample_period_s = kPeriod;
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, 1e-3);
    c.y.resize(n);
    for (Index k = 0; k < n; ++k) c.y(k) = 3.44e-3 + 0.0877 * g * kG + noise(rng);
    return PlanCase{test_case(name, CaseKind::Static, frames::Dcm::Identity(), "poses"), c};
  };
  const PlanCase up = pose("up", 1.0, 3), down = pose("down", -1.0, 4);
  for (const int phases : {4, 1}) {
    SCOPED_TRACE(std::to_string(phases) + " phase(s) per pose");
    OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file({"1", "a_i"}, std::nullopt), 25.0, white_noise());
    feed_phased(est, up, 0, phases);
    feed_phased(est, down, 1, phases);
    const OnlineSnapshot s = est.snapshot();
    ASSERT_TRUE(s.undetermined.empty()) << s.convergence;
    EXPECT_NEAR(s.values(1), 0.0877, 4.0 * s.std_devs(1));
    // With one phase a pose, nothing checks the estimate: never converged.
    EXPECT_EQ(s.converged, phases > 1) << s.convergence;
    EXPECT_NE(s.convergence.find(phases > 1 ? "without phase" : "one phase to check it by"), std::string::npos)
        << s.convergence;
  }
}

/// A gyroscope with eq. 5's rate nonlinearity on a rate table: y (1 + c w_i) = K w_i + b + v, w_i
/// along x_E (the nominal frame's input axis), twelve rate phases; v white (pole 0) or AR(1).
constexpr double kGyroBias = 2e-6, kGyroScale = 1.0005, kGyroNonlinearity = 1e-4;
PlanCase rate_phases(std::uint32_t seed, double pole, int phases = 12, Index n = 24000, Index dwell = 0) {
  dataset::CaseData c;
  c.a_e = dataset::Matrix3Columns::Zero(n, 3);
  c.a_e.col(2).setConstant(kG);
  c.w_e = dataset::Matrix3Columns::Zero(n, 3);
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
  c.sample_period_s = kPeriod;
  c.y.resize(n);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-4);
  double v = 0.0;
  for (Index k = 0; k < n; ++k) {
    const Index phase = k * phases / n;
    // A dwell reads the earth's rate (here all of it along the input axis).
    const double rate = k < dwell ? 7.292e-5 : (phase % 2 == 0 ? 1.0 : -1.0) * 0.3 * static_cast<double>(1 + phase % 6);
    if (phase % 3 != 1) c.w_e.value()(k, phase % 3 == 2 ? 1 : 2) = (phase % 3 == 2 ? 0.2 : 0.1) * rate;   // tilts seen on their own
    c.w_e.value()(k, 0) = rate;
    v = pole * v + noise(rng);
    c.y(k) = (kGyroScale * rate + kGyroBias + v) / (1.0 + kGyroNonlinearity * rate);
  }
  return PlanCase{test_case("rates", CaseKind::RotationTable, frames::Dcm::Identity(), ""), c};
}

/// The live estimate of {1, w_i, y*w_i} on `table`, its rows labelled in `phases` clusters.
OnlineSnapshot gyro_estimate(const PlanCase& table, int phases, const OnlineOptions& options) {
  model::ModelFile m = model_file({"1", "w_i", "y*w_i"}, std::nullopt);
  m.sensor = dataset::SensorKind::Gyroscope;
  OnlineEstimator est(dataset::SensorKind::Gyroscope, m, 25.0, options);
  const Index n = table.data.y.size();
  for (Index from = 0; from < n; from += 1000) {
    fusion::FusedChunk chunk = chunk_of(table, 0, from, 1000);
    for (Index r = 0; r < 1000; ++r) chunk.phase[static_cast<std::size_t>(r)] = static_cast<std::uint16_t>((from + r) * phases / n);
    chunk.phase_names = std::vector<std::string>(static_cast<std::size_t>(phases), "rotation");
    est.push(chunk, table.tc);
  }
  est.end_segment({0, "rates", 0, n, true});
  return est.snapshot();
}

TEST(OnlineEstimator, AnOutputMultipliedTermsPhasesCarryNoScatterTheNoiseDoesNot) {
  // ULS negates an output-multiplied coefficient in the prediction (uls_batch.hpp). The phases'
  // offsets, read with that sign, are noise, so the sd with the phases as clusters are those
  // without (one cluster, no scatter), and cover the truth.
  const PlanCase table = rate_phases(5, 0.0);
  const OnlineSnapshot with_phases = gyro_estimate(table, 12, white_noise());
  const OnlineSnapshot one_cluster = gyro_estimate(table, 1, white_noise());
  const Eigen::Vector3d truth(kGyroBias, kGyroScale, kGyroNonlinearity);
  for (Index j = 0; j < 3; ++j) {
    SCOPED_TRACE(with_phases.terms[static_cast<std::size_t>(j)]);
    ASSERT_TRUE(std::isfinite(with_phases.values(j)));
    // The sd over 12 phases' scatter: its own estimate's spread is ~1/sqrt(2 * 11) = 21 %, so 1.7
    // is three of it.
    EXPECT_LT(with_phases.std_devs(j), 1.7 * one_cluster.std_devs(j));
    EXPECT_NEAR(with_phases.values(j), truth(j), 4.0 * with_phases.std_devs(j));
  }
}

TEST(OnlineEstimator, AnOutputMultipliedTermWaitsForItsFactorToMove) {
  // In a dwell, y*w_i is the output times a constant: fitted, it explains the output by itself
  // (and the noise model, fitted on those rows, would find white noise). It is not determined
  // until the rate moves; then it is, and the noise model fitted in the dwell has the AR(1)'s
  // long-run power (19 in theory).
  const PlanCase table = rate_phases(9, 0.9, 12, 24000, 2000);
  model::ModelFile m = model_file({"1", "w_i", "y*w_i"}, std::nullopt);
  m.sensor = dataset::SensorKind::Gyroscope;
  OnlineOptions options;
  options.nominal_sample_period_s = kPeriod;
  options.structure_table = false;
  OnlineEstimator est(dataset::SensorKind::Gyroscope, m, 25.0, options);
  for (Index from = 0; from < 24000; from += 1000) {
    est.push(chunk_of(table, 0, from, 1000), table.tc);
    if (from + 1000 == 2000) {
      const OnlineSnapshot dwell = est.snapshot();
      EXPECT_FALSE(std::isfinite(dwell.values(2))) << dwell.values(2);
      EXPECT_NE(std::find(dwell.undetermined.begin(), dwell.undetermined.end(), "y*w_i"), dwell.undetermined.end());
      EXPECT_FALSE(dwell.converged);
    }
  }
  est.end_segment({0, "rates", 0, 24000, true});
  const OnlineSnapshot s = est.snapshot();
  EXPECT_NEAR(s.values(2), kGyroNonlinearity, 4.0 * s.std_devs(2));
  EXPECT_GT(s.long_run_variance_factor, 10.0);
}

TEST(OnlineEstimator, AWhiteModelsSdCarryTheNoisesLongRunPower) {
  // Output-multiplied terms keep the rows white (ULS's correction is derived for white equation
  // errors); the noise model fitted on the first 2 s scales the variances by the residual's
  // long-run power instead. With AR(1) noise of pole 0.9 that is 19 times (4.4 in sd): z over
  // seeds and terms is standard normal when the sd are honest.
  OnlineOptions options;
  options.nominal_sample_period_s = kPeriod;
  std::vector<double> z;
  double factor = 0.0;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const OnlineSnapshot s = gyro_estimate(rate_phases(300 + seed, 0.9), 12, options);
    factor += s.long_run_variance_factor / 20.0;
    const Eigen::Vector3d truth(kGyroBias, kGyroScale, kGyroNonlinearity);
    for (Index j = 0; j < 3; ++j) z.push_back((s.values(j) - truth(j)) / s.std_devs(j));
  }
  double sum = 0.0, sum2 = 0.0;
  for (double v : z) {
    sum += v;
    sum2 += v * v;
  }
  const double n = static_cast<double>(z.size());
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  // 60 values: the sample sd's own sd is ~0.09; the bounds are 3.3 and 3.9 of it.
  EXPECT_GT(sd, 0.7) << "sd of z over seeds";
  EXPECT_LT(sd, 1.35) << "sd of z over seeds";
  // 1 / (1 - 0.9)^2 / (1 / (1 - 0.81)) = 19, fitted on 2000 rows of each seed.
  EXPECT_NEAR(factor, 19.0, 4.0);
}

TEST(OnlineEstimator, AStreamShorterThanItsNoiseWindowHasTheModelFittedAtItsEnd) {
  // The window is longer than the stream: the rows stay on white noise while they come, and the
  // end of the stream fits the noise model on every one of them (AR(1) of pole 0.9: a long-run
  // power of 19 times the innovation's over the white fit's, as in the test above).
  OnlineOptions options;
  options.nominal_sample_period_s = kPeriod;
  options.noise_window_s = 1e9;
  const PlanCase table = rate_phases(77, 0.9);
  model::ModelFile m = model_file({"1", "w_i", "y*w_i"}, std::nullopt);
  m.sensor = dataset::SensorKind::Gyroscope;
  OnlineEstimator est(dataset::SensorKind::Gyroscope, m, 25.0, options);
  const Index n = table.data.y.size();
  for (Index from = 0; from < n; from += 1000) est.push(chunk_of(table, 0, from, 1000), table.tc);
  est.end_segment({0, "rates", 0, n, true});
  const OnlineSnapshot before = est.snapshot();
  EXPECT_FALSE(before.noise_model_fitted);
  EXPECT_EQ(before.long_run_variance_factor, 1.0);
  est.end_of_stream();
  const OnlineSnapshot after = est.snapshot();
  EXPECT_TRUE(after.noise_model_fitted);
  EXPECT_NEAR(after.long_run_variance_factor, 19.0, 4.0);
  const Eigen::Vector3d truth(kGyroBias, kGyroScale, kGyroNonlinearity);
  for (Index j = 0; j < 3; ++j) {
    EXPECT_EQ(after.values(j), before.values(j)) << "scaled variances, the same rows";
    // The sd are the white fit's scaled by the factor's root (to 1e-6 relative; a small part of the
    // covariance is not scaled).
    EXPECT_NEAR(after.std_devs(j) / before.std_devs(j) / std::sqrt(after.long_run_variance_factor), 1.0, 1e-6);
    EXPECT_NEAR(after.values(j), truth(j), 4.0 * after.std_devs(j));
  }
  // Once fitted, the end of the stream fits nothing again.
  est.end_of_stream();
  EXPECT_EQ(est.snapshot().long_run_variance_factor, after.long_run_variance_factor);
}

TEST(OnlineEstimator, StandardDeviationsCoverTheTruthOverSeeds) {
  // The sd include what each mounting's misalignment uncertainty does to the batch: z = (estimate
  // - truth) / sd over seeds and terms is standard normal when they are honest.
  std::vector<double> z;
  for (std::uint32_t seed = 1; seed <= 12; ++seed) {
    const Plan p = two_mountings(500.0, 1e-3, 1000 + 37 * seed, 4000, 2000);
    OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file(kModel, 500.0), 25.0, white_noise());
    feed(est, p, seed);
    const OnlineSnapshot s = est.snapshot();
    const Eigen::VectorXd truth = truth_values();
    for (Index j = 0; j < truth.size(); ++j) z.push_back((s.values(j) - truth(j)) / s.std_devs(j));
  }
  double sum = 0.0, sum2 = 0.0, worst = 0.0;
  for (double v : z) {
    sum += v;
    sum2 += v * v;
    worst = std::max(worst, std::abs(v));
  }
  const double n = static_cast<double>(z.size());
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  // 96 values: the sd of a unit normal's sample sd is ~0.07; 4.5 is beyond any of 96 draws but 1 in 3e4.
  EXPECT_GT(sd, 0.75) << "sd of z over seeds";
  EXPECT_LT(sd, 1.3) << "sd of z over seeds";
  EXPECT_LT(worst, 4.5);
}

TEST(OnlineEstimator, RejectsWhatTheLiveStreamCannotEstimate) {
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, model_file({"1", "a_i^2"}, std::nullopt), 25.0, {}),
               InputError);
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, model_file({"1", "a_i", "e[k-1]"}, std::nullopt), 25.0, {}),
               InputError);
  model::ModelFile gyro = model_file({"1", "w_i"}, std::nullopt);
  gyro.sensor = dataset::SensorKind::Gyroscope;
  EXPECT_THROW(OnlineEstimator(dataset::SensorKind::Accelerometer, gyro, 25.0, {}), InputError);
  // Rows without temperature for a model that needs it name the case and the column.
  OnlineEstimator est(dataset::SensorKind::Accelerometer, model_file({"1", "a_i", "T"}, std::nullopt), 25.0, {});
  const Plan p = two_mountings(500.0, 1e-3, 1, 100, 100);
  try {
    est.push(chunk_of(p.cases[0], 0, 0, 50), p.cases[0].tc);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("temperature"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("rotation-table"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace inertia::online
