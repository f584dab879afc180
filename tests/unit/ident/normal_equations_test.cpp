// The normal equations and the identifiability rules on them (analyzer/ident/normal_equations.hpp):
// statistics from rows equal those accumulated block by block and ULS's own from data; the
// ranking forces the sensor's sensitivities, then the bias; the fit lets go the named column
// ranked last, never a sensitivity.
#include "analyzer/ident/normal_equations.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "ident_test_data.hpp"

namespace inertia::ident {
namespace {

using dataset::SensorKind;

TEST(NormalEquations, SensitivitiesAreTheSensorsOwn) {
  EXPECT_TRUE(is_sensitivity_label("a_i", SensorKind::Accelerometer));
  EXPECT_TRUE(is_sensitivity_label("a_y", SensorKind::Accelerometer));
  EXPECT_FALSE(is_sensitivity_label("w_i", SensorKind::Accelerometer));
  EXPECT_TRUE(is_sensitivity_label("w_z", SensorKind::Gyroscope));
  EXPECT_FALSE(is_sensitivity_label("a_i", SensorKind::Gyroscope)) << "a gyroscope's a_i is a g-sensitivity";
  EXPECT_FALSE(is_sensitivity_label("a_i^2", SensorKind::Accelerometer));
  const std::vector<std::string> labels{"a_p", "1", "w_i", "a_i", "y*w_i"};
  EXPECT_EQ(sensitivities_then_bias(labels, SensorKind::Gyroscope), (std::vector<Index>{2, 1}));
  EXPECT_EQ(sensitivities_then_bias(labels, SensorKind::Accelerometer), (std::vector<Index>{3, 1}));
}

// The same statistics whether the rows are at hand (offline) or only their sums (live): the
// rational example's numerator and output-multiplied columns, summed in blocks of uneven length.
TEST(NormalEquations, StatisticsFromSumsEqualThoseFromRows) {
  const testing::RationalExample ex = testing::rational_example(11, 3000, 0.05);
  const OutputMultiplied rational{ex.output_multiplied, ex.factors};
  const NormalEquations rows = NormalEquations::from_rows(ex.phi, ex.y, ex.labels, rational);

  const Index p = ex.phi.cols();
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(p + 1, p + 1);
  Eigen::MatrixXd factor_gram = Eigen::MatrixXd::Zero(2, 2);
  Eigen::VectorXd factor_sum = Eigen::VectorXd::Zero(2);
  for (Index begin = 0, length = 7; begin < ex.phi.rows(); begin += length, length = length * 2 + 1) {
    const Index n = std::min(length, ex.phi.rows() - begin);
    Eigen::MatrixXd block(n, p + 1);
    block << ex.phi.middleRows(begin, n), ex.y.segment(begin, n);
    augmented += block.transpose() * block;
    factor_gram += ex.factors.middleRows(begin, n).transpose() * ex.factors.middleRows(begin, n);
    factor_sum += ex.factors.middleRows(begin, n).colwise().sum().transpose();
  }
  const NormalEquations sums(augmented, ex.phi.rows(), ex.labels, ex.output_multiplied, factor_gram, factor_sum);

  const std::vector<Index> subset{0, 2, 3, 4};
  const UlsStatistics a = rows.statistics(subset);
  const UlsStatistics b = sums.statistics(subset);
  Eigen::MatrixXd phi(ex.phi.rows(), 4);
  for (Index j = 0; j < 4; ++j) phi.col(j) = ex.phi.col(subset[static_cast<std::size_t>(j)]);
  const std::vector<Index> den{2, 3};
  const UlsStatistics c = UlsStatistics::from_data(phi, ex.y, den, ex.factors);
  for (const UlsStatistics* s : {&b, &c}) {
    EXPECT_LT((a.gram - s->gram).norm(), 1e-12 * a.gram.norm());
    EXPECT_LT((a.cross - s->cross).norm(), 1e-12 * a.cross.norm());
    EXPECT_NEAR(a.yy, s->yy, 1e-12 * a.yy);
    EXPECT_EQ(a.denominator, s->denominator);
    EXPECT_LT((a.den_gram - s->den_gram).norm(), 1e-12 * a.den_gram.norm());
    EXPECT_LT((a.den_sum - s->den_sum).norm(), 1e-12 * a.den_sum.norm());
  }
  // ULS on the statistics is ULS on the rows.
  const std::vector<std::string> names{"y[k-1]", "u[k-1]", "y*y[k-1]^2", "y*y[k-2]^2"};
  const UlsSolution from_sums = solve_uls(b, names, UlsOptions{});
  const UlsResult from_rows = uls_batch(ex.phi, ex.y, ex.labels, rational, UlsOptions{}, subset);
  EXPECT_LT((from_sums.theta - from_rows.theta).norm(), 1e-9 * from_rows.theta.norm());
}

TEST(NormalEquations, ShapesAreChecked) {
  EXPECT_THROW(NormalEquations(Eigen::MatrixXd::Identity(3, 3), 10, {"1"}), std::invalid_argument);
  EXPECT_THROW(NormalEquations(Eigen::MatrixXd::Identity(3, 3), 10, {"1", "y*T"}, {1}), std::invalid_argument);
  EXPECT_THROW(NormalEquations(Eigen::MatrixXd::Identity(3, 3), 10, {"1", "y*T"}, {2}, Eigen::MatrixXd::Ones(1, 1),
                               Eigen::VectorXd::Ones(1)),
               std::invalid_argument);
}

/// Rotation-table poses: a_i^2 + a_p^2 + a_o^2 = g^2, so the squares and the bias are dependent.
struct Poses {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
  std::vector<std::string> labels{"a_p^2", "a_o^2", "1", "a_i^2", "a_i", "a_p"};
};

Poses rotation_table_poses(Index n, double bias, double scale, double k2, double noise_sd) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * std::numbers::pi);
  std::normal_distribution<double> noise(0.0, noise_sd);
  constexpr double g = 9.80665;
  Poses out;
  out.phi.resize(n, 6);
  out.y.resize(n);
  for (Index k = 0; k < n; ++k) {
    const double t = angle(rng), s = angle(rng);
    const double ai = g * std::cos(t), ap = g * std::sin(t) * std::cos(s), ao = g * std::sin(t) * std::sin(s);
    out.phi.row(k) << ap * ap, ao * ao, 1.0, ai * ai, ai, ap;
    out.y(k) = bias + scale * ai + k2 * ai * ai + noise(rng);
  }
  return out;
}

TEST(NormalEquations, RankingForcesTheSensitivitiesThenTheBiasAndNamesTheDependent) {
  const Poses poses = rotation_table_poses(500, 0.02, 1.01, 1e-3, 1e-3);
  const NormalEquations equations = NormalEquations::from_rows(poses.phi, poses.y, poses.labels);
  const IdentifiableRanking accelerometer = rank_identifiable(equations, SensorKind::Accelerometer);
  ASSERT_GE(accelerometer.order.size(), 3U);
  EXPECT_EQ(accelerometer.order[0], 4) << "a_i first";
  EXPECT_EQ(accelerometer.order[1], 2) << "then the bias";
  EXPECT_EQ(accelerometer.order[2], 3) << "then the largest ERR: a_i^2, the term in the output";
  // Of the three squares and the bias one is dependent on the others: the last the ERR reaches.
  ASSERT_EQ(accelerometer.dependent.size(), 1U);
  EXPECT_TRUE(accelerometer.dependent[0] == 0 || accelerometer.dependent[0] == 1);
  EXPECT_EQ(accelerometer.order.size() + accelerometer.dependent.size(), 6U);
  // Read as a gyroscope's g-sensitivities, a_i is ranked by its ERR behind the forced bias.
  const IdentifiableRanking gyro = rank_identifiable(equations, SensorKind::Gyroscope);
  EXPECT_EQ(gyro.order[0], 2);
  EXPECT_EQ(gyro.order[1], 4) << "a_i carries most of the output";
  // Nuisance columns follow the forced ones.
  const std::vector<Index> nuisance{5};
  const IdentifiableRanking with_nuisance = rank_identifiable(equations, SensorKind::Accelerometer, ErrOptions(), nuisance);
  EXPECT_EQ(with_nuisance.order[2], 5);
}

/// 20000 rows of w_i, 1, T, T[k-1] and the output; `temperature(k, draw)` and
/// `output(w, t, previous, draw)` take their noise from `draw`, temperature first on each row.
/// Before the first row T[k-1] is `first_previous` (NaN: the row's own T).
template <class Temperature, class Output>
IdentifiableRanking rank_temperature_rows(std::uint64_t seed, double first_previous, Temperature temperature, Output output) {
  const std::vector<std::string> labels{"w_i", "1", "T", "T[k-1]"};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const auto draw = [&] { return normal(rng); };
  const Index n = 20000;
  Eigen::MatrixXd phi(n, 4);
  Eigen::VectorXd y(n);
  double previous = first_previous;
  for (Index k = 0; k < n; ++k) {
    const double t = temperature(double(k) / double(n), draw);
    const double w = std::sin(1e-3 * double(k));
    if (std::isnan(previous)) previous = t;
    phi.row(k) << w, 1.0, t, previous;
    y(k) = output(w, t, previous, draw);
    previous = t;
  }
  return rank_identifiable(NormalEquations::from_rows(phi, y, labels), SensorKind::Gyroscope);
}

/// A gyro's output with a temperature term on T(k) (the simulator's c_t1), temperature read with
/// 0.02 degC noise per sample while it drifts slowly: T and T[k-1] explain the output alike. Over
/// 30 seeds the ranking takes T and names T[k-1] as not told apart from it, whatever the noise
/// favours; with a temperature that moves fast enough for its lag to show, the lag it depends on
/// is ranked.
TEST(NormalEquations, ALaggedTermRanksOnlyForWhatItExplainsBeyondItsUnlaggedForm) {
  for (int seed = 0; seed < 30; ++seed) {
    const IdentifiableRanking ranking = rank_temperature_rows(
        static_cast<std::uint64_t>(700 + seed), std::nan(""),
        [](double x, auto& draw) { return 10.0 * std::sin(2.0 * std::numbers::pi * x) + 0.02 * draw(); },
        [](double w, double t, double, auto& draw) { return 1.0005 * w + 2e-6 + 1e-6 * t + 1e-5 * draw(); });
    EXPECT_NE(std::find(ranking.order.begin(), ranking.order.end(), 2), ranking.order.end()) << seed;
    EXPECT_EQ(ranking.dependent, std::vector<Index>{3}) << seed;
  }
  // Temperature noise of 2 degC per sample and the output on T[k-1]: the lag is what the data say.
  const IdentifiableRanking ranking = rank_temperature_rows(
      9, 0.0, [](double, auto& draw) { return 2.0 * draw(); },
      [](double w, double, double previous, auto& draw) { return 1.0005 * w + 1e-5 * previous + 1e-5 * draw(); });
  ASSERT_GE(ranking.order.size(), 3U);
  EXPECT_EQ(ranking.order[2], 3) << "T[k-1], the term in the output, before T";
}

TEST(NormalEquations, TheFitLetsGoTheNamedColumnRankedLastNeverASensitivity) {
  const Poses poses = rotation_table_poses(500, 0.02, 1.01, 1e-3, 1e-3);
  const NormalEquations equations = NormalEquations::from_rows(poses.phi, poses.y, poses.labels);
  const auto solve = [&](std::span<const Index> columns) {
    return uls_batch(poses.phi, poses.y, poses.labels, OutputMultiplied(), UlsOptions(), columns);
  };
  // Every column, in an order that puts a_p^2 last among the four dependent ones.
  std::vector<Index> ranked{4, 2, 3, 5, 1, 0};
  std::vector<Index> left;
  const UlsResult fit = fit_identifiable(ranked, equations.labels(), SensorKind::Accelerometer, left, solve);
  EXPECT_EQ(left, (std::vector<Index>{0}));
  EXPECT_EQ(ranked, (std::vector<Index>{4, 2, 3, 5, 1}));
  ASSERT_EQ(fit.labels.size(), 5U);
  // Ascending columns 1 2 3 4 5: a_o^2 1 a_i^2 a_i a_p. With a_p^2 gone a_o^2 stands for
  // g^2 - a_i^2 - a_p^2 in the rest, so the scale factor is the one term read directly.
  EXPECT_NEAR(fit.theta(3), 1.01, 4.0 * fit.std_dev(3));

  // A dependence among sensitivities alone is not resolved by letting one go: it is rethrown.
  Eigen::MatrixXd twins(poses.phi.rows(), 2);
  twins << poses.phi.col(4), poses.phi.col(4);
  const std::vector<std::string> twin_labels{"a_x", "a_y"};
  std::vector<Index> both{0, 1};
  std::vector<Index> none;
  EXPECT_THROW((void)fit_identifiable(both, twin_labels, SensorKind::Accelerometer, none,
                                      [&](std::span<const Index> columns) {
                                        return uls_batch(twins, poses.y, twin_labels, OutputMultiplied(), UlsOptions(), columns);
                                      }),
               IdentifiabilityError);
  EXPECT_TRUE(none.empty());
  // Read as a gyroscope's, the same two are g-sensitivities and the later one leaves.
  const std::vector<std::string> g_labels{"w_i", "a_i"};
  std::vector<Index> pair{0, 1};
  const UlsResult one = fit_identifiable(pair, g_labels, SensorKind::Gyroscope, none, [&](std::span<const Index> columns) {
    return uls_batch(twins, poses.y, g_labels, OutputMultiplied(), UlsOptions(), columns);
  });
  EXPECT_EQ(none, (std::vector<Index>{1}));
  EXPECT_EQ(one.labels, (std::vector<std::string>{"w_i"}));
}

}  // namespace
}  // namespace inertia::ident
