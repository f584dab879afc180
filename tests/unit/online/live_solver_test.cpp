// The live solver on sufficient statistics (online/live_solver.hpp) against least squares solved
// directly on the same rows: noiseless data gives back the coefficients it was made with, noisy
// data the QR solution with its residual, variance and sd; columns the data cannot tell apart are
// named undetermined, not guessed; algorithm 1 on a mounting finds the input axis it was made
// with, and a mounting whose inputs excite no axis of its own is held at the nominal frame.
#include "analyzer/online/live_solver.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include "analyzer/ident/normal_equations.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/selection.hpp"
#include "common/frames.hpp"

namespace inertia::online {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kPeriod = 1e-3;
constexpr double kTRef = 25.0;

/// Case-frame specific force, one row per sample.
using Inputs = Eigen::Matrix<double, Eigen::Dynamic, 3>;

/// Correlated axes with means (a table sweep with vibration): every monomial varies on its own.
Inputs random_inputs(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Inputs a(n, 3);
  for (Index k = 0; k < n; ++k) {
    const double u = g(rng), v = g(rng), w = g(rng);
    a.row(k) << 2.0 + 5.0 * u, -1.0 + 2.0 * u + 4.0 * v, 9.0 + 3.0 * w - 1.0 * v;
  }
  return a;
}

dataset::CaseData case_of(const Inputs& a) {
  dataset::CaseData c;
  c.name = "case";
  const Index n = a.rows();
  c.sample_period_s = kPeriod;
  c.t = VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * kPeriod);
  c.a_e = a;
  c.y = VectorXd::Zero(n);
  return c;
}

/// The model's columns in F_S = M_C^S times the case frame, built by the batch's regressor builder.
MatrixXd sensor_frame_columns(const std::vector<ident::Term>& terms, const Inputs& a, const Eigen::Matrix3d& m_cs) {
  const dataset::CaseData c = case_of(a);
  return ident::build_regression(terms, ident::signals_from_case(c, m_cs, kTRef)).phi;
}

/// A basis holding `model` and the external-frame sensitivities, static squares only.
struct Fixture {
  std::vector<ident::Term> model_terms;
  std::unique_ptr<LiveBasis> basis;
  std::vector<Index> model, sensitivities;

  explicit Fixture(const std::vector<std::string>& model_names) : model_terms(ident::parse_terms(model_names)) {
    std::vector<ident::Term> all = model_terms;
    for (const char* s : {"a_x", "a_y", "a_z"}) all.push_back(ident::parse_term(s));
    basis = std::make_unique<LiveBasis>(all, std::vector<ident::Term>{});
    for (const ident::Term& t : model_terms) model.push_back(basis->find(t));
    for (const char* s : {"a_x", "a_y", "a_z"}) sensitivities.push_back(basis->find(ident::parse_term(s)));
  }

  [[nodiscard]] LiveSolver solver() const {
    return LiveSolver(*basis, model, sensitivities, dataset::SensorKind::Accelerometer, CornerGrid(), true, SolverOptions{});
  }

  /// The statistics of rows `a` (case frame) with output y.
  [[nodiscard]] Information statistics(const Inputs& a, const VectorXd& y) const {
    dataset::CaseData c = case_of(a);
    c.y = y;
    MatrixXd b(a.rows(), basis->base_size());
    basis->evaluate(ident::signals_from_case(c, Eigen::Matrix3d::Identity(), kTRef), 0, b);
    Information info(basis->base_size(), 0, 0);
    info.add(b, {}, y);
    info.add_inputs(a);
    return info;
  }
};

/// The size of a coefficient that would carry the whole output on column j alone: the scale a
/// coefficient's rounding error is measured against.
VectorXd coefficient_scales(const MatrixXd& phi, const VectorXd& y) {
  VectorXd s(phi.cols());
  for (Index j = 0; j < phi.cols(); ++j) s(j) = y.norm() / phi.col(j).norm();
  return s;
}

const std::vector<std::string> kModel = {"1", "a_i", "a_p", "a_o", "a_i^2", "a_i*a_p"};

VectorXd truth() {
  VectorXd t(6);
  t << 3.44e-3, 0.0877, 2.0e-4, -1.5e-4, 5.3e-6, 8.9e-6;
  return t;
}

TEST(LiveSolver, NoiselessBatchGivesBackTheCoefficients) {
  const Fixture fx(kModel);
  const Inputs a = random_inputs(3000, 1);
  const Eigen::Matrix3d m_cs = frames::frame_rotation(Eigen::Vector3d(0.2, 0.5, 1.0).normalized(), 0.03);
  const MatrixXd phi = sensor_frame_columns(fx.model_terms, a, m_cs);
  const VectorXd y = phi * truth();
  const Information info = fx.statistics(a, y);
  const StatFit f = fx.solver().fit_batch({&info}, {m_cs});
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_TRUE(f.undetermined.empty());
  ASSERT_EQ(f.terms, fx.model);
  EXPECT_FALSE(f.corner_rad_s.has_value()) << "no grid: static squares";
  const VectorXd scale = coefficient_scales(phi, y);
  for (Index j = 0; j < 6; ++j) EXPECT_NEAR(f.theta(j), truth()(j), 1e-9 * scale(j)) << kModel[static_cast<std::size_t>(j)];
  EXPECT_LT(std::abs(f.rss), 1e-12 * y.squaredNorm());
  EXPECT_EQ(f.weight, 3000.0);
}

TEST(LiveSolver, NoisyBatchIsTheQrSolutionWithItsStatistics) {
  const Fixture fx(kModel);
  const Inputs a = random_inputs(3000, 2);
  const Eigen::Matrix3d m_cs = frames::frame_rotation(Eigen::Vector3d(-0.4, 1.0, 0.3).normalized(), 0.02);
  const MatrixXd phi = sensor_frame_columns(fx.model_terms, a, m_cs);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1e-3);
  VectorXd y = phi * truth();
  for (Index k = 0; k < y.size(); ++k) y(k) += noise(rng);
  const Information info = fx.statistics(a, y);
  const StatFit f = fx.solver().fit_batch({&info}, {m_cs});
  ASSERT_TRUE(f.ok) << f.why;
  ASSERT_EQ(f.terms, fx.model);
  // Ordinary least squares on the rows: theta, rss, s^2 = rss / (n - p), sd^2 = s^2 (Phi'Phi)^-1.
  const VectorXd theta = phi.colPivHouseholderQr().solve(y);
  const double rss = (y - phi * theta).squaredNorm();
  const double s2 = rss / (3000.0 - 6.0);
  const VectorXd sd = (s2 * (phi.transpose() * phi).inverse().diagonal()).cwiseSqrt();
  const VectorXd scale = coefficient_scales(phi, y);
  for (Index j = 0; j < 6; ++j) {
    EXPECT_NEAR(f.theta(j), theta(j), 1e-9 * scale(j)) << kModel[static_cast<std::size_t>(j)];
    EXPECT_NEAR(f.sd(j), sd(j), 1e-6 * sd(j)) << kModel[static_cast<std::size_t>(j)];
  }
  // The statistics' rss is y'y - 2 theta'Phi'y + theta'Phi'Phi theta: its rounding is a few eps y'y.
  EXPECT_NEAR(f.rss, rss, 1e-12 * y.squaredNorm());
  EXPECT_NEAR(f.s2, s2, 1e-6 * s2);
}

TEST(LiveSolver, ACollinearColumnIsNamedNotGuessed) {
  // a_o is gravity alone (constant): it is the bias's column times 9.80665. The bias takes
  // b + k_o g; a_o has no value of its own.
  const Fixture fx({"1", "a_i", "a_p", "a_o"});
  Inputs a = random_inputs(2000, 4);
  a.col(2).setConstant(9.80665);
  const VectorXd k = (VectorXd(4) << 3.44e-3, 0.0877, 2.0e-4, -1.5e-4).finished();
  const MatrixXd phi = sensor_frame_columns(fx.model_terms, a, Eigen::Matrix3d::Identity());
  const VectorXd y = phi * k;
  const Information info = fx.statistics(a, y);
  const StatFit f = fx.solver().fit_batch({&info}, {Eigen::Matrix3d::Identity()});
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_EQ(f.undetermined, std::vector<Index>(1, fx.model[3]));
  EXPECT_FALSE(f.value(fx.model[3]).has_value());
  ASSERT_TRUE(f.value(fx.model[0]).has_value());
  EXPECT_NEAR(*f.value(fx.model[0]), k(0) + k(3) * 9.80665, 1e-12);
  EXPECT_NEAR(*f.value(fx.model[1]), k(1), 1e-12);
  EXPECT_NEAR(*f.value(fx.model[2]), k(2), 1e-12);

  // a_p = 2 a_i on every row: a_i (the scale factor, ranked first) carries k_i + 2 k_p.
  Inputs b = random_inputs(2000, 5);
  b.col(1) = 2.0 * b.col(0);
  const MatrixXd phi_b = sensor_frame_columns(fx.model_terms, b, Eigen::Matrix3d::Identity());
  const VectorXd y_b = phi_b * k;
  const Information info_b = fx.statistics(b, y_b);
  const StatFit g = fx.solver().fit_batch({&info_b}, {Eigen::Matrix3d::Identity()});
  ASSERT_TRUE(g.ok) << g.why;
  EXPECT_EQ(g.undetermined, std::vector<Index>(1, fx.model[2]));
  EXPECT_FALSE(g.value(fx.model[2]).has_value());
  EXPECT_NEAR(*g.value(fx.model[1]), k(1) + 2.0 * k(2), 1e-12);
  EXPECT_NEAR(*g.value(fx.model[3]), k(3), 1e-12);
  EXPECT_NEAR(*g.value(fx.model[0]), k(0), 1e-11);
}

TEST(LiveSolver, BatchOverTwoMountingsIsOneSolveOnTheStackedRows) {
  // Each mounting's rows turned by its own M_C^S, one model over both.
  const Fixture fx(kModel);
  const Inputs a1 = random_inputs(1500, 6), a2 = random_inputs(1200, 7);
  const Eigen::Matrix3d m1 = frames::frame_rotation(Eigen::Vector3d(0.0, 0.3, 1.0).normalized(), 0.035);
  const Eigen::Matrix3d m2 = frames::frame_rotation(Eigen::Vector3d(0.0, 1.0, -0.6).normalized(), 0.026);
  MatrixXd phi(2700, 6);
  phi << sensor_frame_columns(fx.model_terms, a1, m1), sensor_frame_columns(fx.model_terms, a2, m2);
  std::mt19937_64 rng(8);
  std::normal_distribution<double> noise(0.0, 1e-3);
  VectorXd y = phi * truth();
  for (Index k = 0; k < y.size(); ++k) y(k) += noise(rng);
  const Information i1 = fx.statistics(a1, y.head(1500));
  const Information i2 = fx.statistics(a2, y.tail(1200));
  const StatFit f = fx.solver().fit_batch({&i1, &i2}, {m1, m2});
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_EQ(f.weight, 2700.0);
  const VectorXd theta = phi.colPivHouseholderQr().solve(y);
  const VectorXd scale = coefficient_scales(phi, y);
  for (Index j = 0; j < 6; ++j) EXPECT_NEAR(f.theta(j), theta(j), 1e-9 * scale(j)) << kModel[static_cast<std::size_t>(j)];
}

// Algorithm 2 on the statistics (LiveSolver::select) against the batch's selection on the same
// rows (ident::select_model on the rows, ranked by the same rule, the sensitivities and the bias
// kept): the same model on every seed. a_i*a_p is made zero: at the 1 % family-wise level it is
// left out in at least 18 of 20 seeds (the binomial's expectation is 19.8).
TEST(LiveSolver, SelectsTheModelTheBatchSelectsOnTheSameRows) {
  const Fixture fx(kModel);
  VectorXd theta = truth();
  theta(5) = 0.0;
  constexpr int kSeeds = 20;
  int left_out = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    const Inputs a = random_inputs(3000, 100 + static_cast<std::uint64_t>(seed));
    const Eigen::Matrix3d m_cs = frames::frame_rotation(Eigen::Vector3d(0.2, 0.5, 1.0).normalized(), 0.03);
    const MatrixXd phi = sensor_frame_columns(fx.model_terms, a, m_cs);
    std::mt19937_64 rng(200 + static_cast<std::uint64_t>(seed));
    std::normal_distribution<double> noise(0.0, 1e-3);
    VectorXd y = phi * theta;
    for (Index k = 0; k < y.size(); ++k) y(k) += noise(rng);
    const Information info = fx.statistics(a, y);
    const LiveSolver solver = fx.solver();
    const StatFit batch = solver.fit_batch({&info}, {m_cs});
    ASSERT_TRUE(batch.ok) << batch.why;
    std::vector<Index> live = solver.select(batch, {&info}, {m_cs});
    std::sort(live.begin(), live.end());

    const ident::NormalEquations rows = ident::NormalEquations::from_rows(phi, y, kModel);
    const std::vector<Index> ranking = ident::rank_identifiable(rows, dataset::SensorKind::Accelerometer).order;
    ident::SelectionProblem problem(phi, y, kModel, ident::OutputMultiplied(), ranking);
    problem.kept = ident::sensitivities_then_bias(kModel, dataset::SensorKind::Accelerometer);
    std::vector<Index> offline = ident::select_model(problem, ident::SelectionOptions{}).best_model().columns;
    std::vector<Index> offline_terms;
    for (const Index c : offline) offline_terms.push_back(fx.model[static_cast<std::size_t>(c)]);
    std::sort(offline_terms.begin(), offline_terms.end());
    EXPECT_EQ(live, offline_terms) << "seed " << seed;
    left_out += std::find(live.begin(), live.end(), fx.model[5]) == live.end() ? 1 : 0;
  }
  EXPECT_GE(left_out, kSeeds - 2);
}

// The case scatter with the noise's colour (add_case_scatter's run_noise) against the sandwich
// (X'X)^-1 X'RX (X'X)^-1 computed on the rows. Static poses (every column constant within its
// run, so X = Z M' and the runs' means are all of X) and a residual of zero mean in every run (no
// offsets to find), under R = s^2 I + c 1 1' (a noise common to the case's runs): the same
// covariance to rounding. White runs' covariance (C = s^2 N) changes nothing.
TEST(LiveSolver, TheCaseScattersColouredNoiseIsTheSandwichOnTheRows) {
  const Fixture fx({"1", "a_i"});
  const std::vector<Eigen::Vector3d> poses = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {-1.0, 0.0, 0.0},
                                              {0.6, 0.8, 0.0}, {0.0, 0.0, 1.0}, {-0.6, 0.0, -0.8}};
  constexpr Index kRows = 200;
  constexpr double kSigma = 1e-3, kCommon = 4e-8;
  const Eigen::Matrix3d m_cs = Eigen::Matrix3d::Identity();
  Information info(fx.basis->base_size(), 0, 0);
  MatrixXd x(kRows * static_cast<Index>(poses.size()), 2);
  for (std::size_t g = 0; g < poses.size(); ++g) {
    Inputs a(kRows, 3);
    for (Index k = 0; k < kRows; ++k) a.row(k) = 9.80665 * poses[g].transpose();
    VectorXd y(kRows);
    for (Index k = 0; k < kRows; ++k) y(k) = 3.44e-3 + 0.0877 * a(k, 0) + (k % 2 == 0 ? kSigma : -kSigma);
    dataset::CaseData c = case_of(a);
    c.y = y;
    MatrixXd b(kRows, fx.basis->base_size());
    fx.basis->evaluate(ident::signals_from_case(c, Eigen::Matrix3d::Identity(), kTRef), 0, b);
    info.start_run();
    info.add(b, {}, y);
    info.add_inputs(a);
    x.middleRows(static_cast<Index>(g) * kRows, kRows) << VectorXd::Ones(kRows), a.col(0);
  }
  const LiveSolver solver = fx.solver();
  StatFit white = solver.fit_batch({&info}, {m_cs});
  ASSERT_TRUE(white.ok) << white.why;
  StatFit coloured = white;
  const MatrixXd classical = white.covariance;
  const double s2 = white.s2;
  const VectorXd n = VectorXd::Constant(static_cast<Index>(poses.size()), static_cast<double>(kRows));

  const std::vector<MatrixXd> white_runs{MatrixXd(n.asDiagonal())};   // per unit variance
  solver.add_case_scatter(white, {&info}, {m_cs}, 1.0, 0, &white_runs);
  EXPECT_LT((white.covariance - classical).norm(), 1e-12 * classical.norm());

  const std::vector<MatrixXd> common_runs{MatrixXd(MatrixXd(n.asDiagonal()) + kCommon / s2 * n * n.transpose())};
  const CaseScatter scatter = solver.add_case_scatter(coloured, {&info}, {m_cs}, 1.0, 0, &common_runs);
  EXPECT_EQ(scatter.tau2, 0.0) << "no offsets beyond the noise";
  const MatrixXd xtx_inverse = (x.transpose() * x).inverse();
  const VectorXd column_sums = x.colwise().sum().transpose();
  const MatrixXd meat = s2 * x.transpose() * x + kCommon * column_sums * column_sums.transpose();
  const MatrixXd sandwich = xtx_inverse * meat * xtx_inverse;
  for (Index i = 0; i < 2; ++i)
    for (Index j = 0; j < 2; ++j)
      EXPECT_NEAR(coloured.covariance(i, j), sandwich(i, j), 1e-9 * std::sqrt(sandwich(i, i) * sandwich(j, j))) << i << "," << j;
  EXPECT_GT(coloured.sd(0), 3.0 * std::sqrt(classical(0, 0))) << "the common noise dominates the bias's sd";
}

// The turn parameters' covariance (turn_covariance) against the variable-projection sandwich on
// the rows: with A = [X J], J the fitted prediction's derivatives by the shaker mounting's twist and
// tilts, its block of (A'A)^-1 A'RA (A'A)^-1 under R = s^2 I + c 1 1' per case (a noise common to
// a case's runs). The noise is made orthogonal to the columns and to the runs' indicators, so the
// residual's run sums are zero (no offsets to find) and the fit is the truth: the same covariance
// to rounding. The common noise is what a turn read from the cases' means meets (here the tilt
// about p), and the white information (J~'J~ / s^2) does not count it.
TEST(LiveSolver, ATurnsCovarianceIsTheSandwichTheCoefficientsGetOnTheRows) {
  const Fixture fx({"1", "a_i", "a_p", "a_o", "a_i*a_p"});
  const VectorXd k = (VectorXd(5) << 3.44e-3, 0.0877, 2.0e-3, -1.5e-3, 5.0e-4).finished();
  const std::vector<Eigen::Matrix3d> m_cs = {frames::frame_rotation(Eigen::Vector3d(0.0, 0.3, 1.0).normalized(), 0.02),
                                             frames::frame_rotation(Eigen::Vector3d(1.0, 0.1, 0.2).normalized(), -0.4)};
  constexpr Index kRuns = 3, kRows = 400;
  constexpr double kSigma = 1e-3, kCommon = 4e-8, kStep = 1e-4;
  const std::vector<procedure::TurnParameter> parameters = {{1, 0}, {1, 1}, {1, 2}};
  const auto q = static_cast<Index>(parameters.size());
  const auto p = k.size();
  std::vector<Information> infos;
  std::vector<MatrixXd> x(2), j(2);
  std::vector<VectorXd> e(2);
  for (std::size_t c = 0; c < 2; ++c) {
    const Index n = kRuns * kRows;
    Inputs a(n, 3);
    for (Index r = 0; r < kRuns; ++r) a.middleRows(r * kRows, kRows) = random_inputs(kRows, 20 + 10 * c + static_cast<std::uint64_t>(r));
    x[c] = sensor_frame_columns(fx.model_terms, a, m_cs[c]);
    // The prediction's derivatives by the turns, as turned() moves the frame.
    j[c] = MatrixXd::Zero(n, q);
    for (Index i = 0; i < q; ++i) {
      if (parameters[static_cast<std::size_t>(i)].mounting != c) continue;
      Eigen::Vector3d turn = Eigen::Vector3d::Zero();
      turn(parameters[static_cast<std::size_t>(i)].axis) = kStep;
      j[c].col(i) = (sensor_frame_columns(fx.model_terms, a, procedure::turned(m_cs[c], turn)) -
                     sensor_frame_columns(fx.model_terms, a, procedure::turned(m_cs[c], -turn))) * k / (2.0 * kStep);
    }
    // Noise orthogonal to the columns (so X'e = 0 and the fit is the truth) and to each run's
    // constant (so the residual's run sums are zero).
    MatrixXd span(n, p + kRuns);
    span.leftCols(p) = x[c];
    span.rightCols(kRuns).setZero();
    for (Index r = 0; r < kRuns; ++r) span.block(r * kRows, p + r, kRows, 1).setOnes();
    std::mt19937_64 rng(7 + c);
    std::normal_distribution<double> g(0.0, kSigma);
    VectorXd noise(n);
    for (Index i = 0; i < n; ++i) noise(i) = g(rng);
    e[c] = noise - span * span.colPivHouseholderQr().solve(noise);
    const VectorXd y = x[c] * k + e[c];
    Information info(fx.basis->base_size(), 0, 0);
    for (Index r = 0; r < kRuns; ++r) {
      dataset::CaseData rows = case_of(a.middleRows(r * kRows, kRows));
      rows.y = y.segment(r * kRows, kRows);
      MatrixXd b(kRows, fx.basis->base_size());
      fx.basis->evaluate(ident::signals_from_case(rows, Eigen::Matrix3d::Identity(), kTRef), 0, b);
      info.start_run();
      info.add(b, {}, rows.y);
      info.add_inputs(a.middleRows(r * kRows, kRows));
    }
    infos.push_back(std::move(info));
  }
  const LiveSolver solver = fx.solver();
  const StatFit at = solver.fit_batch_at({&infos[0], &infos[1]}, m_cs, std::nullopt);
  ASSERT_TRUE(at.ok) << at.why;
  ASSERT_LT((at.theta - k).cwiseAbs().maxCoeff(), 1e-9) << "the noise is orthogonal to the columns";
  const double s2 = at.s2;
  const VectorXd n = VectorXd::Constant(kRuns, static_cast<double>(kRows));
  CaseClusters clusters;
  clusters.infos = {&infos[0], &infos[1]};
  clusters.mountings = {0, 1};
  clusters.run_noise.assign(2, MatrixXd(MatrixXd(n.asDiagonal()) + kCommon / s2 * n * n.transpose()));
  const std::optional<MatrixXd> covariance = solver.turn_covariance(at, parameters, clusters, m_cs, kStep);
  ASSERT_TRUE(covariance.has_value());

  const Index rows = 2 * kRuns * kRows;
  MatrixXd design(rows, p + q);
  design << x[0], j[0], x[1], j[1];
  const MatrixXd inverse = (design.transpose() * design).inverse();
  MatrixXd meat = s2 * design.transpose() * design;
  for (std::size_t c = 0; c < 2; ++c) {
    const VectorXd sums = design.middleRows(static_cast<Index>(c) * kRuns * kRows, kRuns * kRows).colwise().sum().transpose();
    meat += kCommon * sums * sums.transpose();
  }
  const MatrixXd sandwich = (inverse * meat * inverse).bottomRightCorner(q, q);
  for (Index a = 0; a < q; ++a)
    for (Index b = 0; b < q; ++b)
      EXPECT_NEAR((*covariance)(a, b), sandwich(a, b), 1e-7 * std::sqrt(sandwich(a, a) * sandwich(b, b))) << a << "," << b;
  const MatrixXd white = s2 * inverse.bottomRightCorner(q, q);
  EXPECT_GT(sandwich(1, 1), 4.0 * white(1, 1)) << "the common noise dominates a tilt's variance";
}

/// A table mounting of y = b + k a_i + k2 a_i^2, a_i = n_i . a, with n_i tilted 0.035 rad from
/// (0, 0.3, 1): its model, inputs, true frame and coefficients, and its statistics.
struct TableMounting {
  Fixture fx{{"1", "a_i", "a_i^2"}};
  Inputs a = random_inputs(3000, 9);
  Eigen::Matrix3d m_true = frames::frame_rotation(Eigen::Vector3d(0.0, 0.3, 1.0).normalized(), 0.035);
  VectorXd k = (VectorXd(3) << 3.44e-3, 0.0877, 5.3e-4).finished();
  VectorXd y = sensor_frame_columns(fx.model_terms, a, m_true) * k;
  MountingStatistics m;
  TableMounting() {
    m.name = "table";
    m.info = fx.statistics(a, y);
    m.kind.shaker_only = false;
  }
};

TEST(LiveSolver, MountingFindsTheInputAxisItWasMadeWith) {
  // y = b + k a_i + k2 a_i^2 with a_i = n_i . a: algorithm 1 on the sensitivities k n_i of a_x a_y
  // a_z, to the fixed point, gives n_i; the F_S fit gives b and k2.
  const TableMounting table;
  const Fixture& fx = table.fx;
  const Eigen::Matrix3d& m_true = table.m_true;
  const VectorXd& k = table.k;
  MountingStatistics m = table.m;
  const MountingFit fit = fx.solver().fit_mounting(m, std::nullopt);
  ASSERT_TRUE(fit.determined) << fit.note;
  const Eigen::Vector3d n_i = m_true.row(0).transpose();
  EXPECT_LT((fit.m_cs.row(0).transpose() - n_i).norm(), 1e-9);
  for (std::size_t c = 0; c < 3; ++c) {
    ASSERT_TRUE(fit.fit.value(fx.sensitivities[c]).has_value());
    EXPECT_NEAR(*fit.fit.value(fx.sensitivities[c]), k(1) * n_i(static_cast<Index>(c)), 1e-10);
  }
  ASSERT_TRUE(fit.fit.value(fx.model[2]).has_value());
  EXPECT_NEAR(*fit.fit.value(fx.model[2]), k(2), 1e-11);
  ASSERT_TRUE(fit.bias.has_value());
  EXPECT_NEAR(*fit.bias, k(0), 1e-10);
}

TEST(LiveSolver, AMountingsAnglesCarryItsCasesPlacementsAsTheBatchDoes) {
  // The mounting of MountingFindsTheInputAxisItWasMadeWith as two cases of several runs each,
  // placed within 0.2 mrad: the angles' covariance gains the placements' (procedure/placement.hpp),
  // carried through algorithm 1 as the fit's own is (misalignment_angles is linear in it).
  const TableMounting table;
  const Fixture& fx = table.fx;
  const Inputs& a = table.a;
  MountingStatistics m = table.m;
  const MountingFit without = fx.solver().fit_mounting(m, std::nullopt);
  for (const Index half : {Index{0}, Index{1500}}) {
    Eigen::MatrixXd r(1500, 4);
    r.leftCols(3) = a.middleRows(half, 1500);
    r.col(3).setOnes();
    m.placements.push_back({r.transpose() * r, 2e-4});
  }
  const MountingFit with = fx.solver().fit_mounting(m, std::nullopt);
  ASSERT_TRUE(with.determined) << with.note;
  Eigen::Vector3d theta;
  for (std::size_t c = 0; c < 3; ++c) theta(static_cast<Index>(c)) = *with.fit.value(fx.sensitivities[c]);
  const Eigen::Matrix3d added =
      procedure::misalignment_angles(theta, procedure::placement_covariance(theta, m.placements, true)).covariance;
  EXPECT_GT(added(1, 1), without.angles_covariance(1, 1)) << "the placements dominate a noiseless fit";
  EXPECT_TRUE(with.angles_covariance.isApprox(without.angles_covariance + added, 1e-9))
      << with.angles_covariance << "\n" << without.angles_covariance + added;
}

TEST(LiveSolver, AMountingsAnglesCarryTheBiasItWasHandedAsMovingTheBiasMovesThem) {
  // The mounting of MountingFindsTheInputAxisItWasMadeWith as a shaker mounting that takes its
  // bias from another (noiseless rows: the angles' own variance is rounding). The bias it was
  // handed, with sd s, adds to the angles' covariance what moving the bias by s moves them by
  // (central difference; the fit is linear in the output, algorithm 1's fixed point nearly so).
  const TableMounting table;
  const Fixture& fx = table.fx;
  MountingStatistics m = table.m;
  m.kind.shaker_only = true;
  const double bias = table.k(0), sd = 2e-3;
  const LiveSolver solver = fx.solver();
  const MountingFit without = solver.fit_mounting(m, bias, 0.0);
  const MountingFit with = solver.fit_mounting(m, bias, sd);
  const MountingFit up = solver.fit_mounting(m, bias + sd, 0.0);
  const MountingFit down = solver.fit_mounting(m, bias - sd, 0.0);
  for (const MountingFit* f : {&without, &with, &up, &down}) ASSERT_TRUE(f->determined) << f->note;
  ASSERT_NE(without.note.find("left out (IEEE 1293 12.3.5.7): 1"), std::string::npos) << "the bias is taken: " << without.note;
  const Eigen::Vector2d moved = 0.5 * (up.angles.tail<2>() - down.angles.tail<2>());
  const Eigen::Matrix2d added = with.angles_covariance.bottomRightCorner<2, 2>() - without.angles_covariance.bottomRightCorner<2, 2>();
  const Eigen::Matrix2d want = moved * moved.transpose();
  const double own = without.angles_covariance.bottomRightCorner<2, 2>().trace();
  ASSERT_GT(want.trace(), 100.0 * own) << "the bias dominates";
  EXPECT_LT((added - want).norm(), 1e-2 * want.norm()) << added << "\n" << want;
}

TEST(LiveSolver, AMountingWithoutExcitationIsHeldAtTheNominalFrame) {
  // One static pose: gravity along IRA and the references' noise (1e-4 g). With the bias estimated
  // nothing varies on its own (procedure::axis_excitation): M_C^S stays the warm start and both
  // tilts carry the mounting tolerance.
  const Fixture fx({"1", "a_i"});
  std::mt19937_64 rng(10);
  std::normal_distribution<double> noise(0.0, 1e-4 * 9.80665);
  Inputs a(2000, 3);
  for (Index k = 0; k < a.rows(); ++k) a.row(k) << 9.80665 + noise(rng), noise(rng), noise(rng);
  const VectorXd y = sensor_frame_columns(fx.model_terms, a, Eigen::Matrix3d::Identity()) * Eigen::Vector2d(1e-3, 0.0877);
  MountingStatistics m;
  m.name = "pose";
  m.info = fx.statistics(a, y);
  m.kind.shaker_only = false;
  m.m_cs = frames::frame_rotation(Eigen::Vector3d::UnitZ(), 0.01);
  const SolverOptions defaults;
  const MountingFit fit = fx.solver().fit_mounting(m, std::nullopt);
  EXPECT_FALSE(fit.determined);
  EXPECT_EQ(fit.m_cs, m.m_cs);
  EXPECT_FALSE(fit.note.empty());
  EXPECT_DOUBLE_EQ(fit.angles_sd(1), defaults.mounting_tolerance_rad);
  EXPECT_DOUBLE_EQ(fit.angles_sd(2), defaults.mounting_tolerance_rad);
  EXPECT_TRUE(std::isnan(fit.angles(0))) << "the turn about n_i is not observable";
}

TEST(LiveSolver, NoSamplesNoFit) {
  const Fixture fx(kModel);
  const Information empty(fx.basis->base_size(), 0, 0);
  const StatFit f = fx.solver().fit_batch({&empty}, {Eigen::Matrix3d::Identity()});
  EXPECT_FALSE(f.ok);
  EXPECT_FALSE(f.why.empty());
}

}  // namespace
}  // namespace inertia::online
