// Compensation against truth: outputs simulated from known inputs by the model's own free run
// (procedure::simulate_model), then read backwards.
#include "analyzer/compensate/inverse_model.hpp"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <random>

#include "analyzer/compensate/joint_inverse.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/unit/unit_inverse.hpp"
#include "common/config/bench_config.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"

namespace inertia::compensate {
namespace {

using ident::SignalSet;
using ident::Variable;

model::ModelFile model_of(dataset::SensorKind kind, const std::vector<std::pair<std::string, double>>& terms) {
  model::ModelFile m;
  m.sensor = kind;
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  return m;
}

Eigen::VectorXd theta_of(const model::ModelFile& m) {
  Eigen::VectorXd theta(static_cast<Eigen::Index>(m.terms.size()));
  for (std::size_t j = 0; j < m.terms.size(); ++j) theta(static_cast<Eigen::Index>(j)) = m.terms[j].coefficient;
  return theta;
}

std::vector<ident::Term> terms_of(const model::ModelFile& m) {
  std::vector<ident::Term> t;
  for (const model::ModelTerm& mt : m.terms) t.push_back(mt.term);
  return t;
}

/// Smooth random inputs (a random walk through a one-pole low pass), settled (constant) over the
/// first `settled` samples as a record that starts at rest.
SignalSet smooth_inputs(Eigen::Index n, std::uint64_t seed, double amplitude, Eigen::Index settled = 4) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  SignalSet s(n, "test record");
  for (Variable v : {Variable::Ai, Variable::Ap, Variable::Ao, Variable::Wi, Variable::T}) {
    Eigen::VectorXd x(n);
    double state = amplitude * g(rng) * 0.3;
    for (Eigen::Index k = 0; k < n; ++k) {
      if (k >= settled) state = 0.98 * state + 0.2 * amplitude * g(rng) * 0.3;
      x(k) = state;
    }
    s.set(v, x);
  }
  return s;
}

/// The model's noise-free output on `s`; the free run's lags start from outputs 0 before its first
/// row, which the compensation then reads as measured.
Eigen::VectorXd output_of(const model::ModelFile& m, SignalSet& s, double period = 1e-3) {
  const auto terms = terms_of(m);
  const Eigen::Index first = ident::first_usable_row(terms);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(s.size());
  s.set(Variable::Y, y);
  const Eigen::VectorXd tail = procedure::simulate_model(terms, theta_of(m), s, first, m.square_highpass_rad_s, period);
  y.tail(tail.size()) = tail;
  s.set(Variable::Y, y);
  return y;
}

TEST(NewtonConverged, StopsWhereTheRootIsWithinTheToleranceAndNotBefore) {
  // Newton on g(x) = x^3 + x - 10 (root 2) from several starts, stopped by the rule: where it
  // stops, |x - root| is within the bound, and it took one evaluation fewer than a stop on a
  // step within the bound alone.
  const double root = 2.0, tolerance = InverseModel::kStepTolerance;
  for (const double start : {1.0, 3.0, 10.0, 0.5, 2.5}) {
    double x = start, previous = 0.0;
    bool stopped = false;
    int steps = 0, plain_steps = 0;
    for (; steps < 60 && !stopped; ++steps) {
      const double step = (x * x * x + x - 10.0) / (3.0 * x * x + 1.0);
      x -= step;
      const double scale = std::abs(x) + 1.0;
      stopped = newton_converged(std::abs(step), previous, tolerance * scale, std::sqrt(tolerance) * scale);
      previous = std::abs(step);
    }
    ASSERT_TRUE(stopped) << start;
    EXPECT_LE(std::abs(x - root), tolerance * (root + 1.0)) << start;
    double y = start;
    for (bool within = false; plain_steps < 60 && !within; ++plain_steps) {
      const double step = (y * y * y + y - 10.0) / (3.0 * y * y + 1.0);
      y -= step;
      within = std::abs(step) <= tolerance * (std::abs(y) + 1.0);
    }
    EXPECT_EQ(steps + 1, plain_steps) << start;
  }
  // The prediction is trusted only for a small, shrinking step, and needs a step before it.
  EXPECT_TRUE(newton_converged(1e-14, 0.0, 1e-13, 3e-7));     // within the bound
  EXPECT_FALSE(newton_converged(1e-9, 0.0, 1e-13, 3e-7));     // no step before: no prediction
  EXPECT_TRUE(newton_converged(1e-9, 1e-3, 1e-13, 3e-7));     // next about 1e-21
  EXPECT_FALSE(newton_converged(1e-6, 10.0, 1e-13, 3e-7));    // above the regime
  EXPECT_FALSE(newton_converged(1e-9, 1e-9, 1e-13, 3e-7));    // not shrinking
  EXPECT_FALSE(newton_converged(1e-7, 3e-5, 1e-13, 3e-7));    // next about 1.1e-12: above
}

TEST(InverseModel, RecoversTheInputOfANonlinearDynamicTemperatureModel) {
  // An accelerometer with bias, scale, second-order and odd-quadratic terms, cross-coupling, a
  // temperature bias and scale coefficient, one input lag and one output lag.
  const model::ModelFile m = model_of(dataset::SensorKind::Accelerometer,
                                      {{"1", 3.4e-3},
                                       {"a_i", 0.0877},
                                       {"a_i^2", 4e-5},
                                       {"a_i*abs(a_i)", -2e-5},
                                       {"a_i*a_p", 9e-6},
                                       {"a_p*a_o", 7e-6},
                                       {"T", 2e-5},
                                       {"a_i*T", 3e-6},
                                       {"a_i[k-1]", 0.004},
                                       {"y[k-1]", 0.3},
                                       {"e[k-1]", 0.5}});
  SignalSet s = smooth_inputs(4000, 11, 10.0);
  output_of(m, s);
  const InverseModel inverse(m);
  EXPECT_EQ(inverse.sensed(), Variable::Ai);
  EXPECT_FALSE(inverse.known_inputs().test(static_cast<std::size_t>(Variable::Ai)));
  const CompensatedSignal c = inverse.compensate(s, 1e-3);
  ASSERT_EQ(c.first_row, 1);
  const Eigen::VectorXd truth = s.get(Variable::Ai).tail(c.value.size());
  EXPECT_LT((c.value - truth).cwiseAbs().maxCoeff(), 1e-9 * truth.cwiseAbs().maxCoeff());
  EXPECT_EQ(c.not_converged, 0);
  EXPECT_LE(c.most_iterations, 6);
}

TEST(InverseModel, RecoversTheRateOfARationalGyroModel) {
  // Eq. 5's form: y (1 + c T + d w_i) = bias + S w_i + g-sensitivity.
  const model::ModelFile m = model_of(dataset::SensorKind::Gyroscope,
                                      {{"1", 0.02}, {"w_i", 1.5}, {"a_p", 0.004}, {"y*T", 1e-3}, {"y*w_i", 0.05}});
  SignalSet s = smooth_inputs(3000, 12, 2.0);
  output_of(m, s);
  const CompensatedSignal c = InverseModel(m).compensate(s, 1e-3);
  const Eigen::VectorXd truth = s.get(Variable::Wi).tail(c.value.size());
  EXPECT_LT((c.value - truth).cwiseAbs().maxCoeff(), 1e-11);
}

TEST(InverseModel, SolvesAModelLinearInItsInputAtOnceWithItsDynamicsAndKnownSquares) {
  // Linear in a_i (JointInverse's one solve, -b / a): a known square through the high pass, a
  // lagged output, temperature in a product and over y, and the bias and a_i, whose share of a
  // and b is summed once.
  model::ModelFile m = model_of(dataset::SensorKind::Accelerometer, {{"1", 2e-3},
                                                                     {"a_i", 0.09},
                                                                     {"a_p^2", -2e-4},
                                                                     {"a_i*T", 3e-5},
                                                                     {"a_o", 1e-4},
                                                                     {"y[k-1]", 0.25},
                                                                     {"a_i[k-1]", 0.01},
                                                                     {"y*T", 1e-3}});
  m.square_highpass_rad_s = 40.0;
  SignalSet s = smooth_inputs(4000, 17, 10.0);
  output_of(m, s, 1e-3);
  const InverseModel inverse(m);
  EXPECT_TRUE(inverse.as_joint().linear());
  const CompensatedSignal c = inverse.compensate(s, 1e-3);
  const Eigen::VectorXd truth = s.get(Variable::Ai).tail(c.value.size());
  EXPECT_LT((c.value - truth).cwiseAbs().maxCoeff(), 1e-11);
  EXPECT_EQ(c.most_iterations, 1);
  EXPECT_EQ(c.not_converged, 0);
}

TEST(InverseModel, FollowsTheSquaresThroughTheirHighPass) {
  model::ModelFile m = model_of(dataset::SensorKind::Accelerometer,
                                {{"1", 1e-3}, {"a_i", 0.09}, {"a_i^2", 3e-4}, {"a_p^2", -2e-4}, {"a_i^2[k-1]", 1e-4}});
  m.square_highpass_rad_s = 40.0;
  SignalSet s = smooth_inputs(5000, 13, 10.0);
  output_of(m, s, 1e-3);
  const CompensatedSignal c = InverseModel(m).compensate(s, 1e-3);
  const Eigen::VectorXd truth = s.get(Variable::Ai).tail(c.value.size());
  EXPECT_LT((c.value - truth).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_THROW((void)InverseModel(m).compensate(s, 0.0), std::invalid_argument);
}

TEST(InverseModel, CoefficientUncertaintyIsTheSpreadOfEstimatesUnderTheCovariance) {
  // The model's coefficients drawn from their covariance around the truth: each sample's spread
  // of estimates against its u_coefficients, at a few samples over 400 draws.
  model::ModelFile truth = model_of(dataset::SensorKind::Accelerometer,
                                    {{"1", 3e-3}, {"a_i", 0.088}, {"a_i^2", 5e-5}, {"a_i*a_p", 1e-5}, {"T", 4e-5}});
  SignalSet s = smooth_inputs(200, 14, 10.0);
  output_of(truth, s);
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(5, 5);
  Eigen::Vector<double, 5> sd;
  sd << 3e-5, 3e-6, 5e-7, 4e-7, 2e-6;
  const Eigen::MatrixXd correlation_root = (a * a.transpose() + 2.0 * Eigen::MatrixXd::Identity(5, 5)).llt().matrixL();
  Eigen::MatrixXd root = sd.asDiagonal() * correlation_root;
  model::ModelFile stated = truth;
  stated.covariance = root * root.transpose();
  const CompensatedSignal nominal = InverseModel(stated).compensate(s, 1e-3);
  std::mt19937_64 rng(15);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::vector<Eigen::Index> samples = {10, 80, 150};
  std::vector<double> sum(samples.size()), sum2(samples.size());
  const int draws = 400;
  for (int d = 0; d < draws; ++d) {
    Eigen::Vector<double, 5> z;
    for (int i = 0; i < 5; ++i) z(i) = g(rng);
    const Eigen::VectorXd delta = root * z;
    model::ModelFile drawn = truth;
    for (int i = 0; i < 5; ++i) drawn.terms[std::size_t(i)].coefficient += delta(i);
    const CompensatedSignal c = InverseModel(drawn).compensate(s, 1e-3);
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const double e = c.value(samples[i]) - nominal.value(samples[i]);
      sum[i] += e;
      sum2[i] += e * e;
    }
  }
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double spread = std::sqrt(sum2[i] / draws - std::pow(sum[i] / draws, 2));
    // The sample sd of 400 normal draws: relative sd 1/sqrt(800) = 3.5 %; 4 of them.
    EXPECT_NEAR(spread / nominal.u_coefficients(samples[i]), 1.0, 0.14) << samples[i];
  }
  EXPECT_TRUE(InverseModel(stated).has_covariance());
  EXPECT_FALSE(InverseModel(truth).has_covariance());
}

TEST(InverseModel, NoiseUncertaintyIsTheSpreadUnderTheStatedWhiteNoise) {
  model::ModelFile m = model_of(dataset::SensorKind::Accelerometer, {{"1", 3e-3}, {"a_i", 0.088}, {"a_i^2", 5e-4}});
  m.white_sd = 1e-4;
  SignalSet s = smooth_inputs(20000, 16, 10.0);
  Eigen::VectorXd y = output_of(m, s);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> g(0.0, *m.white_sd);
  for (Eigen::Index k = 0; k < y.size(); ++k) y(k) += g(rng);
  s.set(Variable::Y, y);
  const CompensatedSignal c = InverseModel(m).compensate(s, 1e-3);
  const Eigen::VectorXd z = (c.value - s.get(Variable::Ai)).array() / c.u_noise.array();
  // 20000 standardized errors: their sd within 4 of its own sd (1/sqrt(40000)) of 1.
  const double sd = std::sqrt(z.squaredNorm() / static_cast<double>(z.size()));
  EXPECT_NEAR(sd, 1.0, 4.0 / std::sqrt(40000.0));
}

TEST(InverseModel, FlagsInputsOutsideTheCharacterizedRangeAndSamplesWithoutARoot) {
  model::ModelFile m = model_of(dataset::SensorKind::Accelerometer, {{"1", 0.0}, {"a_i", 1.0}, {"T", 0.1}});
  m.range[Variable::Ai] = {-1.0, 1.0};
  m.range[Variable::T] = {-10.0, 10.0};
  SignalSet s(5, "flags");
  Eigen::VectorXd y(5), t(5);
  y << 0.5, 1.015, 1.025, 0.0, 0.0;   // a_i: 0.5, 1.015 (inside the 1 % margin), 1.025, 0, 0
  t << 0.0, 0.0, 0.0, 10.1, 10.3;     // T: the last one beyond 10 + 0.2
  s.set(Variable::Y, y + 0.1 * t);
  s.set(Variable::T, t);
  const CompensatedSignal c = InverseModel(m).compensate(s, 1e-3);
  EXPECT_EQ(c.flag, (std::vector<SampleFlag>{SampleFlag::Ok, SampleFlag::Ok, SampleFlag::OutsideRange, SampleFlag::Ok,
                                             SampleFlag::OutsideRange}));
  EXPECT_EQ(c.outside_range, 2);
  EXPECT_NEAR(c.value(2), 1.025, 1e-12);   // flagged, still the model's answer

  // y = a_i^2 has no root for y < 0: NaN, flagged, counted; the next sample starts afresh.
  const model::ModelFile square = model_of(dataset::SensorKind::Accelerometer, {{"a_i", 0.0}, {"a_i^2", 1.0}});
  SignalSet q(3, "square");
  Eigen::VectorXd yq(3);
  yq << 4.0, -1.0, 9.0;
  q.set(Variable::Y, yq);
  const CompensatedSignal r = InverseModel(square).compensate(q, 1e-3);
  EXPECT_EQ(r.flag[1], SampleFlag::NotConverged);
  EXPECT_TRUE(std::isnan(r.value(1)));
  EXPECT_EQ(r.not_converged, 1);
  EXPECT_NEAR(std::abs(r.value(2)), 3.0, 1e-12);
}

TEST(InverseModel, RefusesModelsThatDoNotTellTheInput) {
  EXPECT_THROW(InverseModel(model_of(dataset::SensorKind::Accelerometer, {{"1", 1.0}, {"a_p", 1.0}})), InputError);
  EXPECT_THROW(InverseModel(model_of(dataset::SensorKind::Accelerometer, {{"a_i[k-1]", 1.0}})), InputError);
  EXPECT_THROW(InverseModel(model_of(dataset::SensorKind::Gyroscope, {{"a_i", 1.0}})), InputError);
  const model::ModelFile m = model_of(dataset::SensorKind::Accelerometer, {{"a_i", 1.0}, {"a_i*T", 0.1}});
  SignalSet s(3, "case 'x'");
  s.set(Variable::Y, Eigen::VectorXd::Zero(3));
  try {
    (void)InverseModel(m).compensate(s, 1e-3);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'T' (temp), which case 'x' lacks"), std::string::npos) << e.what();
  }
}


// A unit's six outputs read backwards together (unit/unit_inverse.hpp, compensate/joint_inverse.hpp).
// Each member sees the unit-frame inputs through its own turned frame, v_S = M_C^S T_j v_U.
struct UnitRecord {
  unit::UnitModel unit;
  std::vector<SignalSet> records;   // one per member, in its sensor frame
  Eigen::MatrixXd truth;            // a_x, a_y, a_z, w_x, w_y, w_z in the unit frame, per sample
};

UnitRecord unit_record(Eigen::Index n, const std::vector<std::pair<std::string, double>>& accelerometer,
                       const std::vector<std::pair<std::string, double>>& gyroscope, double noise_sd, std::uint64_t seed,
                       bool constant_input) {
  UnitRecord r;
  r.unit.unit = "imu";
  const SignalSet first = smooth_inputs(n, seed, 10.0), second = smooth_inputs(n, seed + 1, 2.0);
  r.truth.resize(n, 6);
  r.truth.col(0) = first.get(Variable::Ai);
  r.truth.col(1) = first.get(Variable::Ap);
  r.truth.col(2) = first.get(Variable::Ao);
  r.truth.col(3) = second.get(Variable::Ai);
  r.truth.col(4) = second.get(Variable::Ap);
  r.truth.col(5) = second.get(Variable::Ao);
  if (constant_input) r.truth = r.truth.row(0).replicate(n, 1);
  std::mt19937_64 rng(seed + 2);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int member = 0; member < 6; ++member) {
    const bool gyro = member >= 3;
    model::ModelFile m = model_of(gyro ? dataset::SensorKind::Gyroscope : dataset::SensorKind::Accelerometer, gyro ? gyroscope : accelerometer);
    m.name = fmt::format("{}{}", gyro ? 'g' : 'a', static_cast<char>('x' + member % 3));
    m.unit = "imu";
    m.unit_axis = member % 3;
    m.output_sd = noise_sd;
    // Each member a few mrad off its nominal axis, differently.
    m.m_cs = frames::frame_rotation(Eigen::Vector3d(1.0, -2.0 + member, 0.5 * member), 3e-3 * (member + 1));
    const Eigen::Matrix3d to_sensor = m.m_cs * config::unit_axis_frame(m.unit_axis);
    SignalSet s(n, m.name);
    const Eigen::MatrixXd a = r.truth.leftCols(3) * to_sensor.transpose(), w = r.truth.rightCols(3) * to_sensor.transpose();
    s.set(Variable::Ai, a.col(0));
    s.set(Variable::Ap, a.col(1));
    s.set(Variable::Ao, a.col(2));
    s.set(Variable::Wi, w.col(0));
    s.set(Variable::Wp, w.col(1));
    s.set(Variable::Wo, w.col(2));
    s.set(Variable::T, first.get(Variable::T));
    Eigen::VectorXd y = output_of(m, s);
    for (Eigen::Index k = 0; k < n; ++k) y(k) += noise_sd * g(rng);
    s.set(Variable::Y, y);
    r.unit.members.push_back(std::move(m));
    r.records.push_back(std::move(s));
  }
  return r;
}

TEST(JointInverse, RecoversASixOutputUnitsSpecificForceAndRateTogether) {
  // Accelerometers: second order, cross-coupling, a rate-squared term, temperature, an input and
  // an output lag. Gyroscopes: eq. 5's rational form with g-sensitivity to all three axes.
  const UnitRecord r = unit_record(3000,
                                   {{"1", 3.4e-3},
                                    {"a_i", 0.0877},
                                    {"a_p", 2e-4},
                                    {"a_i^2", 4e-5},
                                    {"a_i*a_p", 9e-6},
                                    {"w_i^2", 1e-4},
                                    {"T", 2e-5},
                                    {"a_i[k-1]", 0.004},
                                    {"y[k-1]", 0.3}},
                                   {{"1", 0.02}, {"w_i", 1.5}, {"a_i", 0.004}, {"a_p", -0.002}, {"a_o", 0.001}, {"y*T", 1e-3}}, 0.0, 21,
                                   false);
  const unit::UnitInverse inverse(r.unit);
  ASSERT_EQ(inverse.unknowns().size(), 6U);
  std::vector<const SignalSet*> records;
  for (const SignalSet& s : r.records) records.push_back(&s);
  const JointCompensation c = inverse.joint().compensate(records, 1e-3);
  ASSERT_EQ(c.first_row, 1);
  const Eigen::MatrixXd truth = r.truth.bottomRows(c.value.rows());
  for (Eigen::Index j = 0; j < 6; ++j)
    EXPECT_LT((c.value.col(j) - truth.col(j)).cwiseAbs().maxCoeff(), 1e-9 * truth.col(j).cwiseAbs().maxCoeff()) << j;
  EXPECT_EQ(c.not_converged, 0);
  EXPECT_LE(c.most_iterations, 6);
}

TEST(JointInverse, NoiseUncertaintyIsTheSpreadOfTheJointSolution) {
  // Linear members with cross-axis terms and white output noise, a constant input: the spread of
  // each solved axis against its u_noise (J^-1 diag(s^2) J^-T). 4000 samples: the sd's own
  // relative sd is 1.1 %, the bound 5 %.
  const UnitRecord r = unit_record(4000, {{"1", 1e-3}, {"a_i", 0.09}, {"a_p", 0.02}, {"a_o", -0.03}},
                                   {{"1", 0.01}, {"w_i", 1.2}, {"w_p", 0.3}, {"a_i", 0.05}}, 2e-3, 31, true);
  const unit::UnitInverse inverse(r.unit);
  std::vector<const SignalSet*> records;
  for (const SignalSet& s : r.records) records.push_back(&s);
  const JointCompensation c = inverse.joint().compensate(records, 1e-3);
  for (Eigen::Index j = 0; j < 6; ++j) {
    const Eigen::VectorXd x = c.value.col(j);
    const double mean = x.mean();
    const double sd = std::sqrt((x.array() - mean).square().sum() / static_cast<double>(x.size() - 1));
    EXPECT_NEAR(sd / c.u_noise(0, j), 1.0, 0.05) << j << ": spread " << sd << ", u_noise " << c.u_noise(0, j);
    EXPECT_NEAR(mean, r.truth(0, j), 4.0 * sd / std::sqrt(static_cast<double>(x.size()))) << j;
  }
}

TEST(JointInverse, ALinearUnitsSampleIsTheSameWhicheverSamplesItIsSolvedBeside) {
  // The affine path solves a few samples side by side (affine_samples.hpp): each record's first
  // few samples alone (fewer than a register holds, and a partial last group) give the same
  // bits as the same samples in the whole record. Members with a lagged temperature term and a
  // y*T denominator, so that b varies and reads a lag.
  const UnitRecord r = unit_record(1001, {{"1", 1e-3}, {"a_i", 0.09}, {"a_p", 0.02}, {"a_o", -0.03}, {"T[k-1]", 2e-5}},
                                   {{"1", 0.01}, {"w_i", 1.2}, {"w_p", 0.3}, {"a_i", 0.05}, {"y*T", 1e-3}}, 1e-3, 41, false);
  const unit::UnitInverse inverse(r.unit);
  ASSERT_TRUE(inverse.joint().linear());
  std::vector<const SignalSet*> whole;
  for (const SignalSet& s : r.records) whole.push_back(&s);
  const JointCompensation all = inverse.joint().compensate(whole, 1e-3);
  ASSERT_EQ(all.first_row, 1);
  for (const Eigen::Index samples : {2, 3, 4, 6, 7}) {
    std::vector<SignalSet> heads;
    for (const SignalSet& s : r.records) {
      SignalSet head(samples, s.origin());
      for (const Variable v : {Variable::Y, Variable::Ai, Variable::Ap, Variable::Ao, Variable::Wi, Variable::Wp, Variable::Wo, Variable::T})
        head.set(v, s.get(v).head(samples));
      heads.push_back(std::move(head));
    }
    std::vector<const SignalSet*> pointers;
    for (const SignalSet& s : heads) pointers.push_back(&s);
    const JointCompensation part = inverse.joint().compensate(pointers, 1e-3);
    ASSERT_EQ(part.value.rows(), samples - 1);
    for (Eigen::Index row = 0; row < part.value.rows(); ++row) {
      for (Eigen::Index j = 0; j < 6; ++j) {
        EXPECT_EQ(part.value(row, j), all.value(row, j)) << samples << " samples, row " << row << ", unknown " << j;
        EXPECT_EQ(part.u_coefficients(row, j), all.u_coefficients(row, j)) << samples << " samples, row " << row;
        EXPECT_EQ(part.u_noise(row, j), all.u_noise(row, j)) << samples << " samples, row " << row;
      }
    }
  }
}

TEST(JointInverse, RefusesASystemThatIsNotSquareAndRecordsOfDifferentLengths) {
  const model::ModelFile m = model_of(dataset::SensorKind::Accelerometer, {{"1", 1e-3}, {"a_i", 0.09}});
  const InverseModel inverse(m);
  const Eigen::RowVectorXd one = Eigen::RowVectorXd::Ones(1);
  EXPECT_THROW(JointInverse({{&inverse, {{Variable::Ai, one}}}, {&inverse, {{Variable::Ai, one}}}}, {}), std::invalid_argument);
  EXPECT_THROW(JointInverse({{&inverse, {{Variable::Ai, Eigen::RowVectorXd::Ones(3)}}}}, {}), std::invalid_argument);
  EXPECT_THROW(JointInverse({{&inverse, {{Variable::Ap, one}}}}, {}), std::invalid_argument);   // no unknown at the current sample
  const UnitRecord r = unit_record(50, {{"1", 1e-3}, {"a_i", 0.09}}, {{"1", 0.01}, {"w_i", 1.2}}, 0.0, 41, false);
  const unit::UnitInverse unit_inverse(r.unit);
  std::vector<SignalSet> records = r.records;
  records[4] = SignalSet(40, "short record");
  records[4].set(Variable::Y, Eigen::VectorXd::Zero(40));
  std::vector<const SignalSet*> pointers;
  for (const SignalSet& s : records) pointers.push_back(&s);
  EXPECT_THROW((void)unit_inverse.joint().compensate(pointers, 1e-3), InputError);
}

}  // namespace
}  // namespace inertia::compensate
