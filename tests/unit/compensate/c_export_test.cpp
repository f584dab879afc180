// The generated C compiles as C99 with warnings as errors and gives InverseModel's answers on its
// test vectors: a model with every kind of term the inversion handles (nonlinear, absolute value,
// temperature, input and output lags, the squares' high pass, an output-multiplied term); and a
// unit's six outputs solved together (generate_joint_c) gives JointInverse's.
#include "analyzer/compensate/c_export.hpp"

#include <gtest/gtest.h>
#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/unit/unit_inverse.hpp"
#include "common/config/bench_config.hpp"
#include "common/frames.hpp"
#include "common/input_error.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia::compensate {
namespace {

namespace fs = std::filesystem;
using ident::SignalSet;
using ident::Variable;

model::ModelFile every_kind_of_term() {
  model::ModelFile m;
  m.sensor = dataset::SensorKind::Accelerometer;
  m.name = "acc1";
  m.t_ref = 25.0;
  m.sample_period_s = 1e-3;
  m.square_highpass_rad_s = 60.0;
  m.white_sd = 1e-4;
  m.output_sd = 2e-4;
  const std::vector<std::pair<const char*, double>> terms = {
      {"1", 3.4e-3},  {"a_i", 0.0877},     {"a_i^2", 4e-5},      {"a_i*abs(a_i)", -2e-5}, {"a_p^2", 3e-5},
      {"a_i*a_p", 9e-6}, {"a_p*a_o", 7e-6}, {"T", 2e-5},         {"a_i*T", 3e-6},         {"a_i[k-1]", 0.004},
      {"a_i^2[k-2]", 1e-5}, {"y[k-1]", 0.3}, {"T[k-1]", -1e-5},  {"y*T", 1e-4},           {"e[k-1]", 0.2}};
  for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
  const auto n = static_cast<Eigen::Index>(m.terms.size());
  const Eigen::MatrixXd a = Eigen::MatrixXd::Random(n, n) * 1e-7;
  m.covariance = a * a.transpose();
  m.range[Variable::Ai] = {-20.0, 20.0};
  m.range[Variable::T] = {-30.0, 30.0};
  return m;
}

/// Inputs of a shaken, tilted, warming sensor, and the model's output on them.
SignalSet record_of(const model::ModelFile& m, Eigen::Index n) {
  std::mt19937_64 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  SignalSet s(n, "vectors");
  Eigen::VectorXd ai(n), ap(n), ao(n), t(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double time = 1e-3 * static_cast<double>(k);
    ai(k) = 12.0 * std::sin(2.0 * M_PI * 7.0 * time) + 0.3 * g(rng) + (k > n / 2 ? 30.0 : 0.0);   // a stretch beyond the range
    ap(k) = 4.0 * std::cos(2.0 * M_PI * 3.0 * time);
    ao(k) = 9.8 + 0.5 * g(rng);
    t(k) = -10.0 + 30.0 * time;
  }
  s.set(Variable::Ai, ai);
  s.set(Variable::Ap, ap);
  s.set(Variable::Ao, ao);
  s.set(Variable::T, t);
  s.set(Variable::Y, Eigen::VectorXd::Zero(n));
  std::vector<ident::Term> terms;
  Eigen::VectorXd theta(static_cast<Eigen::Index>(m.terms.size()));
  for (std::size_t j = 0; j < m.terms.size(); ++j) {
    terms.push_back(m.terms[j].term);
    theta(static_cast<Eigen::Index>(j)) = m.terms[j].coefficient;
  }
  const Eigen::Index first = ident::first_usable_row(terms);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
  y.tail(n - first) = procedure::simulate_model(terms, theta, s, first, m.square_highpass_rad_s, 1e-3);
  for (Eigen::Index k = 0; k < n; ++k) y(k) += 1e-4 * g(rng);
  s.set(Variable::Y, y);
  return s;
}

/// Compiles DIR/model.c (written beside model.h and vectors.csv) with `driver` (cc -std=c99
/// -pedantic -Wall -Wextra -Werror) and runs it on the vectors; its exit status, -1 when the
/// compiler refused (its messages in `output`, else the driver's).
int compile_and_run_driver(const fs::path& dir, const char* driver_file, double tolerance, std::string& output) {
  const fs::path driver = fs::path(INERTIA_SOURCE_DIR) / "tests" / "unit" / "compensate" / driver_file;
  const std::string compile = "cc -std=c99 -pedantic -Wall -Wextra -Werror -O2 -I" + dir.string() + " " + (dir / "model.c").string() +
                              " " + driver.string() + " -lm -o " + (dir / "driver").string() + " > " + (dir / "cc.txt").string() + " 2>&1";
  if (std::system(compile.c_str()) != 0) {
    std::ifstream in(dir / "cc.txt");
    output = std::string(std::istreambuf_iterator<char>(in), {});
    return -1;
  }
  const std::string run = (dir / "driver").string() + " " + (dir / "vectors.csv").string() + " " + fmt::format("{}", tolerance) +
                          " 0.4 > " + (dir / "run.txt").string() + " 2>&1";
  const int status = std::system(run.c_str());
  std::ifstream in(dir / "run.txt");
  output = std::string(std::istreambuf_iterator<char>(in), {});
  return status;
}

/// Generates, compiles (cc -std=c99 -Wall -Wextra -Werror) and runs the driver; its exit status.
int compile_and_run(const model::ModelFile& m, CPrecision precision, double tolerance, std::string& output) {
  const inertia::testing::TempDir dir("inertia-c-export");
  const CSource c = generate_c(m, "model", precision);
  std::ofstream(dir.path / "model.h") << c.header;
  std::ofstream(dir.path / "model.c") << c.source;
  {
    std::ofstream vectors(dir.path / "vectors.csv");
    write_test_vectors(vectors, m, c.inputs, record_of(m, 3000), 1e-3);
  }
  return compile_and_run_driver(dir.path, "c_export_driver.c", tolerance, output);
}

TEST(CExport, DoubleAgreesWithTheAnalyzerTo1e12) {
  std::string output;
  EXPECT_EQ(compile_and_run(every_kind_of_term(), CPrecision::Double, 1e-12, output), 0) << output;
  std::cout << "[ figures ] double: " << output;
}

TEST(CExport, FloatAgreesWithTheAnalyzerTo1e6) {
  std::string output;
  EXPECT_EQ(compile_and_run(every_kind_of_term(), CPrecision::Float, 1e-6, output), 0) << output;
  std::cout << "[ figures ] float: " << output;
}

TEST(CExport, VectorsFlagWhatTheAnalyzerFlags) {
  const model::ModelFile m = every_kind_of_term();
  std::ostringstream vectors;
  write_test_vectors(vectors, m, generate_c(m, "model", CPrecision::Double).inputs, record_of(m, 3000), 1e-3);
  const std::string text = vectors.str();
  EXPECT_EQ(text.substr(0, text.find('\n')), "y,a_p,a_o,T,value,u_coefficients,u_noise,flag");
  EXPECT_NE(text.find(",1\n"), std::string::npos);   // the stretch beyond the range
  EXPECT_NE(text.find(",3\n"), std::string::npos);   // the history filling
  EXPECT_THROW((void)generate_c(m, "2bad", CPrecision::Double), InputError);
}


/// A unit of six members, each through its own turned frame: accelerometers with second-order,
/// cross-coupling, temperature, lagged and filtered-square terms, gyroscopes with eq. 5's rational
/// form and g-sensitivity; their outputs on a shaken, turning, warming unit. With `members` 3, its
/// accelerometer triad alone; `linear`: accelerometers of bias, scale, the cross axes and T.
struct UnitVectors {
  unit::UnitModel unit;
  std::vector<SignalSet> records;
};

UnitVectors unit_vectors(Eigen::Index n, int members = 6, bool linear = false) {
  UnitVectors u;
  u.unit.unit = "imu";
  std::mt19937_64 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd a(n, 3), w(n, 3);
  Eigen::VectorXd t(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double time = 1e-3 * static_cast<double>(k);
    a.row(k) << 8.0 * std::sin(2.0 * M_PI * 5.0 * time) + (k > n / 2 ? 40.0 : 0.0), 3.0 * std::cos(2.0 * M_PI * 2.0 * time),
        9.8 + 0.3 * g(rng);
    w.row(k) << 1.5 * std::sin(2.0 * M_PI * 1.0 * time), 0.4 * std::cos(2.0 * M_PI * 3.0 * time), 0.2 + 0.05 * g(rng);
    t(k) = -5.0 + 20.0 * time;
  }
  for (int member = 0; member < members; ++member) {
    const bool gyro = member >= 3;
    model::ModelFile m;
    m.sensor = gyro ? dataset::SensorKind::Gyroscope : dataset::SensorKind::Accelerometer;
    m.name = fmt::format("{}{}", gyro ? 'g' : 'a', static_cast<char>('x' + member % 3));
    m.unit = "imu";
    m.unit_axis = member % 3;
    m.t_ref = 25.0;
    m.sample_period_s = 1e-3;
    m.output_sd = 2e-4;
    using Terms = std::vector<std::pair<const char*, double>>;
    const Terms terms = gyro     ? Terms{{"1", 0.01}, {"w_i", 1.2}, {"w_p", 0.003}, {"a_i", 2e-4}, {"a_p", -1e-4}, {"y*T", 1e-4}, {"T", 3e-5}}
                        : linear ? Terms{{"1", 3.4e-3}, {"a_i", 0.0877}, {"a_p", 1e-4}, {"a_o", -2e-4}, {"T", 2e-5}}
                                 : Terms{{"1", 3.4e-3}, {"a_i", 0.0877}, {"a_i^2", 4e-5}, {"a_i*a_p", 9e-6},
                                         {"a_p^2", 3e-5}, {"T", 2e-5}, {"a_i[k-1]", 0.004}, {"y[k-1]", 0.3}};
    if (!gyro && !linear) m.square_highpass_rad_s = 60.0;
    for (const auto& [name, c] : terms) m.terms.push_back({ident::parse_term(name), c, std::nullopt});
    const auto p = static_cast<Eigen::Index>(m.terms.size());
    const Eigen::MatrixXd root = Eigen::MatrixXd::Random(p, p) * 1e-7;
    m.covariance = root * root.transpose();
    m.range[gyro ? Variable::Wi : Variable::Ai] = gyro ? model::ModelFile::Span{-3.0, 3.0} : model::ModelFile::Span{-20.0, 20.0};
    m.m_cs = frames::frame_rotation(Eigen::Vector3d(1.0, -2.0 + member, 0.5 * member), 3e-3 * (member + 1));
    const Eigen::Matrix3d to_sensor = m.m_cs * config::unit_axis_frame(m.unit_axis);
    SignalSet s(n, m.name);
    const Eigen::MatrixXd as = a * to_sensor.transpose(), ws = w * to_sensor.transpose();
    s.set(Variable::Ai, as.col(0));
    s.set(Variable::Ap, as.col(1));
    s.set(Variable::Ao, as.col(2));
    s.set(Variable::Wi, ws.col(0));
    s.set(Variable::Wp, ws.col(1));
    s.set(Variable::Wo, ws.col(2));
    s.set(Variable::T, t);
    s.set(Variable::Y, Eigen::VectorXd::Zero(n));
    std::vector<ident::Term> model_terms;
    Eigen::VectorXd theta(p);
    for (std::size_t j = 0; j < m.terms.size(); ++j) {
      model_terms.push_back(m.terms[j].term);
      theta(static_cast<Eigen::Index>(j)) = m.terms[j].coefficient;
    }
    const Eigen::Index first = ident::first_usable_row(model_terms);
    Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
    y.tail(n - first) = procedure::simulate_model(model_terms, theta, s, first, m.square_highpass_rad_s, 1e-3);
    for (Eigen::Index k = 0; k < n; ++k) y(k) += 2e-4 * g(rng);
    s.set(Variable::Y, y);
    u.unit.members.push_back(std::move(m));
    u.records.push_back(std::move(s));
  }
  return u;
}

/// The joint code for `u`, compiled with the joint driver and run on its vectors: its exit status.
int compile_and_run_joint(const UnitVectors& u, CPrecision precision, double tolerance, std::string& output) {
  const inertia::testing::TempDir dir("inertia-c-joint");
  const unit::UnitInverse inverse(u.unit);
  const std::size_t members = u.unit.members.size();
  const std::vector<std::string> outputs = members == 6 ? std::vector<std::string>{"ax", "ay", "az", "gx", "gy", "gz"}
                                                        : std::vector<std::string>{"ax", "ay", "az"};
  const std::vector<std::string> unknowns = members == 6 ? std::vector<std::string>{"a_x", "a_y", "a_z", "w_x", "w_y", "w_z"}
                                                         : std::vector<std::string>{"a_x", "a_y", "a_z"};
  const JointCSource c = generate_joint_c(inverse.joint(), outputs, unknowns, "model", precision, 1e-3);
  std::ofstream(dir.path / "model.h") << c.header;
  std::ofstream(dir.path / "model.c") << c.source;
  {
    std::vector<const SignalSet*> records;
    for (const SignalSet& s : u.records) records.push_back(&s);
    std::ofstream vectors(dir.path / "vectors.csv");
    write_joint_test_vectors(vectors, inverse.joint(), outputs, unknowns, c.inputs, records, 1e-3);
  }
  return compile_and_run_driver(dir.path, "c_joint_driver.c", tolerance, output);
}

TEST(CExport, AUnitsJointCodeInDoubleAgreesWithTheAnalyzerTo1e12) {
  std::string output;
  EXPECT_EQ(compile_and_run_joint(unit_vectors(3000), CPrecision::Double, 1e-12, output), 0) << output;
  std::cout << "[ figures ] joint, double: " << output;
}

TEST(CExport, AUnitsJointCodeInFloatAgreesWithTheAnalyzerTo1e6) {
  std::string output;
  EXPECT_EQ(compile_and_run_joint(unit_vectors(3000), CPrecision::Float, 1e-6, output), 0) << output;
  std::cout << "[ figures ] joint, float: " << output;
}

TEST(CExport, ATriadsJointCodeInDoubleAgreesWithTheAnalyzerTo1e12) {
  // Three unknowns: the inverse by cofactors, for a nonlinear and for a linear triad.
  for (const bool linear : {false, true}) {
    std::string output;
    EXPECT_EQ(compile_and_run_joint(unit_vectors(3000, 3, linear), CPrecision::Double, 1e-12, output), 0) << output;
    std::cout << "[ figures ] triad (" << (linear ? "linear" : "nonlinear") << "), double: " << output;
  }
}

TEST(CExport, ATriadsJointCodeInFloatAgreesWithTheAnalyzerTo1e6) {
  for (const bool linear : {false, true}) {
    std::string output;
    EXPECT_EQ(compile_and_run_joint(unit_vectors(3000, 3, linear), CPrecision::Float, 1e-6, output), 0) << output;
    std::cout << "[ figures ] triad (" << (linear ? "linear" : "nonlinear") << "), float: " << output;
  }
}

}  // namespace
}  // namespace inertia::compensate
