// A unit's triad against known truth: the members' case frames turned to their unit axes, a
// [[unit]]'s reading and its refusals, and the triad's sensitivity matrix, imucal's K, R, b and
// the non-orthogonality with their uncertainties, on models whose axes are known exactly.
#include "analyzer/unit/triad_frame.hpp"
#include "analyzer/unit/kalibr_intrinsics.hpp"
#include "analyzer/unit/unit_covariance.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "analyzer/commands/unit.hpp"
#include "common/config/bench_config.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "common/units.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia::unit {
namespace {

namespace fs = std::filesystem;

TEST(UnitAxisFrame, PutsIraOnTheAxisByACyclicTurn) {
  EXPECT_TRUE(config::unit_axis_frame(-1).isIdentity());
  EXPECT_TRUE(config::unit_axis_frame(0).isIdentity());
  for (int axis = 0; axis < 3; ++axis) {
    const frames::Dcm t = config::unit_axis_frame(axis);
    EXPECT_NEAR(t.determinant(), 1.0, 1e-15);
    EXPECT_TRUE(t.row(0).isApprox(Eigen::RowVector3d::Unit(axis))) << "IRA along the unit axis";
    EXPECT_TRUE(t.row(1).isApprox(Eigen::RowVector3d::Unit((axis + 1) % 3))) << "XRA along the next";
  }
  config::TestCase tc;
  tc.m_ec << 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0;   // unit x up
  config::SensorUnderTest y_member;
  y_member.unit_axis = 1;
  // The y member's IRA is the unit's y: the second row of the unit's frame.
  EXPECT_TRUE(config::nominal_m_ec(tc, y_member).row(0).isApprox(tc.m_ec.row(1)));
}

fs::path write(const fs::path& file, const std::string& text) {
  std::ofstream(file) << text;
  return file;
}

std::string imu_bench(const std::string& unit_table) {
  std::ifstream in(fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-imu-tumble.toml");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t from = text.find("\n[[unit]]") + 1, to = text.find("\n[[sensor]]") + 1;
  return text.replace(from, to - from, unit_table);
}

TEST(UnitConfig, MembersGetTheirAxisSerialAndPartAndBadUnitsAreRefused) {
  const config::BenchConfig bench = config::load_bench_config(fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-imu-tumble.toml");
  ASSERT_EQ(bench.units.size(), 1u);
  for (int axis = 0; axis < 3; ++axis) {
    const config::SensorUnderTest& s = bench.sensors[static_cast<std::size_t>(axis)];
    EXPECT_EQ(s.unit, "imu1");
    EXPECT_EQ(s.unit_axis, axis);
    EXPECT_EQ(s.serial, "IMU-0001");
    EXPECT_EQ(s.part, "MEMS-IMU-SIM");
  }
  const testing::TempDir dir("inertia-unit");
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"[[unit]]\nname = \"u\"\naccelerometers = [\"ax\", \"ay\"]\n\n", "three sensor names"},
      {"[[unit]]\nname = \"u\"\naccelerometers = [\"ax\", \"ay\", \"nosuch\"]\n\n", "no [[sensor]] named 'nosuch'"},
      {"[[unit]]\nname = \"u\"\ngyroscopes = [\"ax\", \"\", \"\"]\n\n", "sensor 'ax' is a accelerometer"},
      {"[[unit]]\nname = \"u\"\naccelerometers = [\"ax\", \"ay\", \"az\"]\n\n[[unit]]\nname = \"v\"\naccelerometers = [\"ax\", \"\", \"\"]\n\n",
       "already in unit 'u'"},
      {"[[unit]]\nname = \"u\"\n\n", "needs accelerometers or gyroscopes"},
  };
  for (const auto& [table, message] : bad) {
    try {
      config::load_bench_config(write(dir.path / "bench.toml", imu_bench(table)));
      ADD_FAILURE() << table;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

/// An accelerometer of the unit along `axis`: y = b + k a_i in a sensor frame tilted from its case
/// by `about_p`, `about_o` (with sd `angle_sd`), coefficients with sd `coefficient_sd`.
model::ModelFile member(int axis, double b, double k, double about_p, double about_o, double angle_sd, double coefficient_sd) {
  model::ModelFile m;
  m.name = std::string("a") + static_cast<char>('x' + axis);
  m.unit = "imu";
  m.unit_axis = axis;
  m.output_unit = "g";
  m.terms = {{ident::parse_term("1"), b, coefficient_sd}, {ident::parse_term("a_i"), k, coefficient_sd}};
  const Eigen::Vector3d v(0.0, about_p, about_o);
  m.m_cs = frames::frame_rotation(v.normalized(), v.norm());
  m.misalignment = model::ModelFile::Misalignment{about_p, about_o, angle_sd, angle_sd};
  return m;
}

TEST(TriadFrame, AxesScaleBiasAndNonOrthogonalityOfKnownMembers) {
  const double k = 1.0 / 9.80665;
  const std::vector<model::ModelFile> members = {member(0, 1e-3, k, 2e-3, -1e-3, 1e-4, 1e-7), member(1, -2e-3, 1.01 * k, -1e-3, 3e-3, 1e-4, 1e-7),
                                                 member(2, 3e-3, 0.99 * k, 0.5e-3, 1e-3, 1e-4, 1e-7)};
  const TriadFrame f = triad_frame(members);
  for (int a = 0; a < 3; ++a) {
    const model::ModelFile& m = members[static_cast<std::size_t>(a)];
    // The input axis in the unit frame: the sensor's i in case coordinates, turned back to the unit.
    const Eigen::Vector3d n = config::unit_axis_frame(a).transpose() * m.m_cs.row(0).transpose();
    EXPECT_TRUE(f.misalignment.row(a).transpose().isApprox(n, 1e-12)) << a;
    EXPECT_NEAR(f.scale(a), m.terms[1].coefficient, 1e-15);
    EXPECT_NEAR(f.bias(a), m.terms[0].coefficient, 1e-15);
    EXPECT_NEAR(f.bias_sd(a), 1e-7, 1e-12);
    EXPECT_NEAR(f.scale_sd(a), 1e-7, 1e-12);   // a turn changes the direction, not |s|
  }
  EXPECT_TRUE(f.sensitivity.isApprox(f.scale.asDiagonal() * f.misalignment, 1e-14)) << "S = K R";
  // Non-orthogonality: asin of the axes' dot product; to first order the sum of the two tilts
  // towards each other. Its sd: each axis moves by angle_sd in the two directions across it, and
  // the pair's dot product sees one of them from each: sqrt(2) angle_sd.
  for (std::size_t p = 0; p < 3; ++p) {
    const Eigen::Vector3d a = f.misalignment.row(static_cast<Eigen::Index>(p)).transpose();
    const Eigen::Vector3d b = f.misalignment.row(static_cast<Eigen::Index>((p + 1) % 3)).transpose();
    EXPECT_NEAR(f.non_orthogonality[p], std::asin(a.dot(b)), 1e-15);
    EXPECT_NEAR(f.non_orthogonality_sd[p], std::sqrt(2.0) * 1e-4, 2e-6) << kAxisPairs[p];
    // No dof stated: many, and the normal's 1.96.
    EXPECT_TRUE(std::isinf(f.non_orthogonality_dof[p]));
    EXPECT_NEAR(f.non_orthogonality_half_width[p], 1.959964 * f.non_orthogonality_sd[p], 1e-9);
  }
}

TEST(TriadFrame, TheNonOrthogonalitysIntervalIsStudentsTOnTheMembersAngleDof) {
  // Two members' angle parts alike (sd 1e-4, 3 dof each), the coefficients' part nil:
  // Welch-Satterthwaite gives (2 v)^2 / (2 v^2 / 3) = 6 dof, and t_0.975(6) = 2.446912.
  const double k = 1.0 / 9.80665;
  std::vector<model::ModelFile> members = {member(0, 1e-3, k, 0.0, 0.0, 1e-4, 0.0), member(1, -2e-3, k, 0.0, 0.0, 1e-4, 0.0),
                                           member(2, 3e-3, k, 0.0, 0.0, 1e-4, 0.0)};
  for (model::ModelFile& m : members) m.misalignment->dof = 3.0;
  const TriadFrame f = triad_frame(members);
  for (std::size_t p = 0; p < 3; ++p) {
    EXPECT_NEAR(f.non_orthogonality_dof[p], 6.0, 1e-9) << kAxisPairs[p];
    EXPECT_NEAR(f.non_orthogonality_half_width[p] / f.non_orthogonality_sd[p], 2.446912, 1e-6) << kAxisPairs[p];
  }
  // The dof round-trips through the model file.
  const model::ModelFile back = model::parse_model(model::format_model(members[0]), "member.toml");
  ASSERT_TRUE(back.misalignment.has_value());
  EXPECT_EQ(back.misalignment->dof, 3.0);
}

/// A gyroscope of the unit along `axis`: y = b + k w_i + g_i a_i + g_p a_p (a g-sensitivity).
model::ModelFile gyro_member(int axis, double k, double g_i, double g_p, double about_p) {
  model::ModelFile m;
  m.sensor = dataset::SensorKind::Gyroscope;
  m.name = std::string("g") + static_cast<char>('x' + axis);
  m.unit = "imu";
  m.unit_axis = axis;
  m.output_unit = "rad/s";
  m.terms = {{ident::parse_term("1"), 1e-5, 1e-7}, {ident::parse_term("w_i"), k, 1e-6}, {ident::parse_term("a_i"), g_i, 1e-7},
             {ident::parse_term("a_p"), g_p, 1e-7}};
  m.m_cs = frames::frame_rotation(Eigen::Vector3d::UnitY(), about_p);
  return m;
}

TEST(TriadFrame, TheGyroscopesGSensitivityIsTheirResponseToSpecificForceInTheUnitFrame) {
  const std::vector<model::ModelFile> members = {gyro_member(0, 1.0, 2e-4, -1e-4, 1e-3), gyro_member(1, 1.01, 3e-4, 0.0, -2e-3),
                                                 gyro_member(2, 0.99, -1e-4, 5e-5, 0.0)};
  const TriadFrame f = triad_frame(members);
  EXPECT_EQ(f.kind, dataset::SensorKind::Gyroscope);
  for (int a = 0; a < 3; ++a) {
    const model::ModelFile& m = members[static_cast<std::size_t>(a)];
    // dy / da_S = (g_i, g_p, 0), turned to the case by M_C^S' and to the unit by T'.
    const Eigen::Vector3d expected =
        config::unit_axis_frame(a).transpose() * m.m_cs.transpose() * Eigen::Vector3d(m.terms[2].coefficient, m.terms[3].coefficient, 0.0);
    EXPECT_TRUE(f.g_sensitivity.row(a).transpose().isApprox(expected, 1e-12)) << a << ": " << f.g_sensitivity.row(a);
    EXPECT_NEAR(f.scale(a), m.terms[1].coefficient, 1e-15);
  }
}

fs::path write_model_file(const fs::path& dir, const model::ModelFile& m) {
  const fs::path file = dir / (m.name + ".toml");
  model::write_model(file, m);
  return file;
}

TEST(UnitCommand, WritesTheTriadAndImucalsCalibrationFile) {
  const testing::TempDir dir("inertia-unit");
  const double k = 1.0 / 9.80665;
  std::vector<fs::path> files;
  for (int a = 0; a < 3; ++a) files.push_back(write_model_file(dir.path, member(a, 1e-3 * (a + 1), k, 1e-3, -1e-3, 1e-4, 1e-7)));
  std::ostringstream out;
  ASSERT_EQ(commands::run_unit(files, dir.path / "unit", out), 0) << out.str();
  std::ifstream in(dir.path / "unit" / "imucal.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  // imucal's FerrarisCalibrationInfo, format 2.0.0: every field it reads, 3x3 matrices and 3-vectors.
  EXPECT_EQ(j["cal_type"], "Ferraris");
  EXPECT_EQ(j["_format_version"], "2.0.0");
  EXPECT_EQ(j["acc_unit"], "m/s^2");
  EXPECT_EQ(j["from_acc_unit"], "g");
  ASSERT_EQ(j["K_a"].size(), 3u);
  EXPECT_DOUBLE_EQ(j["K_a"][1][1].get<double>(), k);
  EXPECT_EQ(j["K_a"][0][1].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(j["b_a"][2].get<double>(), 3e-3);
  EXPECT_NEAR(j["R_a"][0][0].get<double>(), 1.0, 1e-5);
  for (const char* key : {"K_g", "R_g", "K_ga", "b_g", "gyr_unit"}) EXPECT_TRUE(j[key].is_null()) << key;
  EXPECT_NE(j["comment"].get<std::string>().find("gyroscope triad was not characterized"), std::string::npos);
  std::ifstream toml(dir.path / "unit" / "unit.toml");
  const std::string text((std::istreambuf_iterator<char>(toml)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("[accelerometer]"), std::string::npos);
  EXPECT_NE(text.find("[accelerometer.non_orthogonality]"), std::string::npos);
  EXPECT_NE(text.find("model = \"member-"), std::string::npos);
  std::ifstream kalibr(dir.path / "unit" / "kalibr.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(kalibr)), std::istreambuf_iterator<char>());
  EXPECT_NE(yaml.find("model: scale-misalignment"), std::string::npos);
  EXPECT_NE(yaml.find("  accelerometers:\n    M: [["), std::string::npos) << yaml;
  files.pop_back();
  std::ostringstream refused;
  EXPECT_THROW((void)commands::run_unit(files, dir.path / "two", refused), InputError);
  EXPECT_FALSE(fs::exists(dir.path / "two"));
}

TEST(TriadFrame, RefusesMembersThatAreNotOneTriad) {
  const double k = 0.1;
  const auto refused = [](std::vector<model::ModelFile> m, const char* message) {
    try {
      (void)triad_frame(m);
      ADD_FAILURE() << message;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  refused({member(0, 0, k, 0, 0, 0, 0), member(1, 0, k, 0, 0, 0, 0)}, "three models");
  refused({member(0, 0, k, 0, 0, 0, 0), member(0, 0, k, 0, 0, 0, 0), member(2, 0, k, 0, 0, 0, 0)}, "two models along unit axis x");
  model::ModelFile other = member(2, 0, k, 0, 0, 0, 0);
  other.unit = "imu2";
  refused({member(0, 0, k, 0, 0, 0, 0), member(1, 0, k, 0, 0, 0, 0), other}, "of unit 'imu2'");
  model::ModelFile lone = member(2, 0, k, 0, 0, 0, 0);
  lone.unit.clear();
  lone.unit_axis = -1;
  refused({member(0, 0, k, 0, 0, 0, 0), member(1, 0, k, 0, 0, 0, 0), lone}, "states no unit");
}


TEST(KalibrIntrinsics, LowerTriangularScaleTimesARotationGivesTheTriadsSensitivity) {
  TriadFrame acc, gyro;
  acc.kind = dataset::SensorKind::Accelerometer;
  acc.output_unit = "g";
  acc.sensitivity = (Eigen::Matrix3d() << 0.1021, 0.0003, -0.0004, -0.0002, 0.0998, 0.0005, 0.0006, 0.0001, 0.1017).finished();
  gyro.kind = dataset::SensorKind::Gyroscope;
  gyro.output_unit = "deg/s";
  gyro.sensitivity = frames::frame_rotation(Eigen::Vector3d(1.0, 2.0, 3.0), 0.01) * 57.3 * Eigen::Matrix3d::Identity() +
                     (Eigen::Matrix3d() << 0.2, 0.01, 0.0, 0.03, -0.1, 0.02, 0.0, 0.01, 0.05).finished();
  gyro.g_sensitivity = (Eigen::Matrix3d() << 0.01, -0.002, 0.003, 0.001, 0.02, 0.0, -0.004, 0.0, 0.015).finished();
  const KalibrIntrinsics k = kalibr_intrinsics(acc, gyro);
  ASSERT_TRUE(k.m_accel && k.m_gyro && k.a_gyro) << k.note;
  EXPECT_TRUE(k.note.empty());
  for (const Eigen::Matrix3d& m : {*k.m_accel, *k.m_gyro}) {
    EXPECT_EQ(m(0, 1), 0.0);
    EXPECT_EQ(m(0, 2), 0.0);
    EXPECT_EQ(m(1, 2), 0.0);
    for (int d = 0; d < 3; ++d) EXPECT_GT(m(d, d), 0.0);
  }
  for (const Eigen::Matrix3d& c : {k.c_imu_unit, k.c_gyro_i}) {
    EXPECT_TRUE((c * c.transpose()).isIdentity(1e-12));
    EXPECT_NEAR(c.determinant(), 1.0, 1e-12);
  }
  // Outputs in SI: g times 9.80665, deg/s times pi/180.
  EXPECT_TRUE((*k.m_accel * k.c_imu_unit).isApprox(acc.sensitivity * 9.80665, 1e-12));
  EXPECT_TRUE((*k.m_gyro * k.c_gyro_i * k.c_imu_unit).isApprox(gyro.sensitivity * kPi / 180.0, 1e-12));
  EXPECT_TRUE((*k.a_gyro * k.c_gyro_i * k.c_imu_unit).isApprox(gyro.g_sensitivity * kPi / 180.0, 1e-12));

  TriadFrame volts = acc;
  volts.output_unit = "V";
  const KalibrIntrinsics v = kalibr_intrinsics(volts, std::nullopt);
  EXPECT_FALSE(v.m_accel);
  EXPECT_NE(v.note.find("'V', which is no unit of the sensed quantity"), std::string::npos) << v.note;
  TriadFrame mirrored = acc;
  mirrored.sensitivity.row(2) *= -1.0;   // a left-handed triad: no rotation reaches it
  EXPECT_FALSE(kalibr_intrinsics(mirrored, std::nullopt).m_accel);
}


/// A random covariance of size n with standard deviations near `sd` and correlations up to about
/// 0.5.
Eigen::MatrixXd random_covariance(Eigen::Index n, double sd, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) a(i, j) = (i == j ? 1.0 : 0.3) * normal(rng);
  return sd * sd * (a * a.transpose() / static_cast<double>(n) + 0.5 * Eigen::MatrixXd::Identity(n, n));
}

TEST(UnitCovariance, TheDeltaMethodMatchesTheSpreadOfTheParametersOverDrawnSensitivities) {
  // A unit whose members' sensitivities and g-sensitivities have known covariances: each parameter's
  // covariance by the delta method against the sample covariance of the same parameter computed
  // from 4000 draws of the members. An sd estimated from N draws scatters by sd / sqrt(2N) (1.1 %
  // here): 5 % is 4.5 of those; a correlation scatters by at most 1 / sqrt(N) (0.016): 0.06.
  std::mt19937_64 rng(7);
  Triads triads;
  TriadFrame acc, gyro;
  acc.kind = dataset::SensorKind::Accelerometer;
  acc.output_unit = "g";
  acc.sensitivity = (Eigen::Matrix3d() << 0.1021, 0.0003, -0.0004, -0.0002, 0.0998, 0.0005, 0.0006, 0.0001, 0.1017).finished();
  gyro.kind = dataset::SensorKind::Gyroscope;
  gyro.output_unit = "deg/s";
  gyro.sensitivity = frames::frame_rotation(Eigen::Vector3d(1.0, 2.0, 3.0), 0.01) * 57.3 * Eigen::Matrix3d::Identity();
  gyro.g_sensitivity = (Eigen::Matrix3d() << 0.01, -0.002, 0.003, 0.001, 0.02, 0.0, -0.004, 0.0, 0.015).finished();
  for (std::size_t k = 0; k < 3; ++k) {
    acc.axes[k].covariance = random_covariance(3, 2e-5, rng);
    acc.axes[k].joint_covariance.topLeftCorner(3, 3) = acc.axes[k].covariance;
    gyro.axes[k].joint_covariance = random_covariance(6, 2e-2, rng);
    gyro.axes[k].joint_covariance.bottomRightCorner(3, 3) *= 1e-4;   // g-sensitivity sd near 2e-4
    gyro.axes[k].joint_covariance.topRightCorner(3, 3) *= 1e-2;
    gyro.axes[k].joint_covariance.bottomLeftCorner(3, 3) *= 1e-2;
    gyro.axes[k].covariance = gyro.axes[k].joint_covariance.topLeftCorner(3, 3);
  }
  acc.bias = Eigen::Vector3d(1e-3, -2e-3, 3e-3);
  acc.bias_sd = Eigen::Vector3d(1e-5, 2e-5, 3e-5);
  gyro.bias = Eigen::Vector3d::Zero();
  gyro.bias_sd = Eigen::Vector3d::Constant(1e-4);
  triads.accelerometer = acc;
  triads.gyroscope = gyro;
  const std::vector<UnitParameter> parameters = unit_parameters(triads);
  std::vector<std::string> names;
  for (const UnitParameter& p : parameters) names.push_back(p.name);
  EXPECT_EQ(names, (std::vector<std::string>{"K_a", "R_a", "K_g", "R_g", "K_ga", "M_a", "C", "M_g", "A", "C_gyro_i", "b_a", "b_g"}));

  // The parameters of one draw, in the same order and layout (rotations as rotation vectors from
  // the undrawn ones), without the biases.
  const KalibrIntrinsics at = kalibr_intrinsics(acc, gyro);
  const auto flat = [&](const TriadFrame& a, const TriadFrame& g) {
    std::vector<double> v;
    const auto matrix = [&v](const Eigen::Matrix3d& m) {
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) v.push_back(m(r, c));
    };
    const auto rotation = [&v](const Eigen::Matrix3d& turned, const Eigen::Matrix3d& from) {
      const Eigen::AngleAxisd aa(Eigen::Matrix3d(turned * from.transpose()));
      for (int k = 0; k < 3; ++k) v.push_back(aa.angle() * aa.axis()(k));
    };
    for (const TriadFrame* f : {&a, &g}) {
      Eigen::Matrix3d k = Eigen::Matrix3d::Zero(), r;
      for (int row = 0; row < 3; ++row) {
        k(row, row) = f->sensitivity.row(row).norm();
        r.row(row) = f->sensitivity.row(row) / k(row, row);
      }
      matrix(k);
      matrix(r);
    }
    matrix(g.g_sensitivity);
    const KalibrIntrinsics d = kalibr_intrinsics(a, g);
    matrix(*d.m_accel);
    rotation(d.c_imu_unit, at.c_imu_unit);
    matrix(*d.m_gyro);
    matrix(*d.a_gyro);
    rotation(d.c_gyro_i, at.c_gyro_i);
    return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size())).eval();
  };
  const Eigen::VectorXd center = flat(acc, gyro);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto draw = [&](const Eigen::MatrixXd& covariance) {
    Eigen::VectorXd z(covariance.rows());
    for (Eigen::Index k = 0; k < z.size(); ++k) z(k) = normal(rng);
    return Eigen::VectorXd(covariance.llt().matrixL() * z);
  };
  constexpr int kDraws = 4000;
  Eigen::MatrixXd samples(kDraws, center.size());
  for (int n = 0; n < kDraws; ++n) {
    TriadFrame a = acc, g = gyro;
    for (Eigen::Index k = 0; k < 3; ++k) {
      a.sensitivity.row(k) += draw(acc.axes[static_cast<std::size_t>(k)].covariance).transpose();
      const Eigen::VectorXd d = draw(gyro.axes[static_cast<std::size_t>(k)].joint_covariance);
      g.sensitivity.row(k) += d.head(3).transpose();
      g.g_sensitivity.row(k) += d.tail(3).transpose();
    }
    samples.row(n) = (flat(a, g) - center).transpose();
  }
  const Eigen::MatrixXd centered = samples.rowwise() - samples.colwise().mean();
  const Eigen::MatrixXd sample_covariance = centered.transpose() * centered / (kDraws - 1.0);

  Eigen::Index offset = 0;
  int compared = 0;
  for (const UnitParameter& p : parameters) {
    if (p.name == "b_a" || p.name == "b_g") continue;
    const Eigen::Index size = p.covariance.rows();
    const Eigen::MatrixXd drawn = sample_covariance.block(offset, offset, size, size);
    for (Eigen::Index i = 0; i < size; ++i) {
      const double delta_sd = std::sqrt(p.covariance(i, i)), drawn_sd = std::sqrt(drawn(i, i));
      if (delta_sd == 0.0) {
        EXPECT_LT(drawn_sd, 1e-15) << p.name << " element " << i;
        continue;
      }
      EXPECT_NEAR(delta_sd / drawn_sd, 1.0, 0.05) << p.name << " element " << i;
      for (Eigen::Index j = 0; j < i; ++j) {
        if (p.covariance(j, j) == 0.0) continue;
        const double delta_r = p.covariance(i, j) / (delta_sd * std::sqrt(p.covariance(j, j)));
        const double drawn_r = drawn(i, j) / (drawn_sd * std::sqrt(drawn(j, j)));
        EXPECT_NEAR(delta_r, drawn_r, 0.06) << p.name << " elements " << i << ", " << j;
      }
      ++compared;
    }
    offset += size;
  }
  EXPECT_EQ(offset, center.size());
  // The elements that vary: K's diagonals (3 + 3), R (9 + 9), K_ga (9), M's lower triangles
  // (6 + 6), A (9), the two rotations (3 + 3).
  EXPECT_EQ(compared, 60);
  // The biases' covariance is the diagonal of their sd squared; K's diagonal is the triad's K sd.
  EXPECT_TRUE(parameters[10].covariance.isApprox(Eigen::Vector3d(1e-10, 4e-10, 9e-10).asDiagonal().toDenseMatrix()));
}
}  // namespace
}  // namespace inertia::unit
