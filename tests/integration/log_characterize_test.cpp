// The whole chain on real binaries: inertia-daqd records a simulated bench (the shape of
// config/sim-paper.toml, shortened to 1 kHz and 10.5 s: config/sim-paper-daq.toml) into an
// event log; inertia-analyze characterize --log fuses it into a dataset and identifies the
// sensor; diagnose --log checks the model against the same log. Scored against the simulator's
// truth (inertia-analyze simulate on the same bench file writes truth.toml) and beside the
// characterization from the simulator's exact reference (the dataset simulate writes).
//
// Tolerances. The batch fit's coefficient standard deviations come from its residual, which holds
// the sensor noise (white 1e-4 g and pink 1.5e-3 g) and the fused reference's error (monitor WLS:
// 5e-4 g per monitor over four monitors at 45 deg to x_E gives ~3.5e-4 g per sample on the shaker;
// the table encoder's 1e-6 rad steps give ~1e-5 g of gravity direction): 5 sd covers both; the
// pink noise makes the sd somewhat optimistic, so the bound is not tighter. Input axis: the exact
// reference run on the same truth reaches e_exact; the fused reference adds its noise, bounded by
// 0.1 deg (the paper's table 4 level on 1/10 of its samples).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <chrono>
#include <thread>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <regex>

#include "analyzer/commands/truth_file.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/model/model_file.hpp"
#include "analyzer/record/record_store.hpp"
#include "common/dataset/dataset.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/procedure/model_simulation.hpp"
#include "analyzer/procedure/misalignment.hpp"
#include "common/units.hpp"
#include "tests/integration/daqd_harness.hpp"
#include "tests/support/files.hpp"

namespace inertia::daq::testing {
namespace {

using inertia::testing::analyze_binary;

int run_command(const std::string& command, const fs::path& output) {
  const int st = std::system((command + " > " + output.string() + " 2>&1").c_str());
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double coefficient(const model::ModelFile& m, const std::string& name, double* sd) {
  for (const model::ModelTerm& t : m.terms) {
    if (t.term.to_string() == name) {
      if (sd) *sd = t.std.value_or(0.0);
      return t.coefficient;
    }
  }
  ADD_FAILURE() << "model has no term " << name;
  return 0.0;
}

// "  case NAME: M_E^S input axis [+x +y +z]" lines of characterize's output.
std::map<std::string, Eigen::Vector3d> input_axes(const std::string& out) {
  std::map<std::string, Eigen::Vector3d> axes;
  const std::regex line(R"(case (\S+): M_E\^S input axis \[([-+0-9.e]+) ([-+0-9.e]+) ([-+0-9.e]+)\])");
  for (std::sregex_iterator it(out.begin(), out.end(), line), end; it != end; ++it)
    axes[(*it)[1]] = Eigen::Vector3d(std::stod((*it)[2]), std::stod((*it)[3]), std::stod((*it)[4]));
  return axes;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return rad_to_deg(std::atan2(a.normalized().cross(b.normalized()).norm(), a.normalized().dot(b.normalized())));
}

TEST(LogCharacterize, DaqdLogToModelMatchesTheSimulatorTruth) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = source_path("config/sim-paper-daq.toml");
  DaqdProcess daqd({"--config", config, "--fast", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(900.0), 0) << daqd.output();
  std::vector<fs::path> logs;
  for (const auto& e : fs::directory_iterator(tmp.path / "log")) logs.push_back(e.path());
  ASSERT_EQ(logs.size(), 1u);
  const std::string log = logs[0].string();

  // Truth, and the exact-reference characterization for comparison.
  ASSERT_EQ(run_command(analyze_binary() + " simulate --bench " + config + " --out " + (tmp.path / "sim").string(),
                        tmp.path / "simulate.txt"),
            0)
      << read_text(tmp.path / "simulate.txt");
  const std::optional<commands::Truth> truth = commands::read_truth(tmp.path / "sim");
  ASSERT_TRUE(truth.has_value());
  ASSERT_EQ(run_command(analyze_binary() + " characterize --dataset " + (tmp.path / "sim").string() + " --out " +
                            (tmp.path / "exact").string(),
                        tmp.path / "exact.txt"),
            0)
      << read_text(tmp.path / "exact.txt");

  const std::string record_db = (tmp.path / "record.sqlite").string();
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + log + " --out " + (tmp.path / "out").string() +
                            " --dataset-out " + (tmp.path / "ds").string() + " --record " + record_db,
                        tmp.path / "characterize.txt"),
            0)
      << read_text(tmp.path / "characterize.txt");
  const std::string out = read_text(tmp.path / "characterize.txt");
  const model::ModelFile fused = model::read_model(tmp.path / "out" / "model.toml");
  // The daemon's run is in the lab's record by its log: path and SHA-256 of the log's bytes.
  const std::vector<record::Characterization> recorded = record::RecordStore(record_db).list();
  ASSERT_EQ(recorded.size(), 1u);
  EXPECT_EQ(recorded[0].input_path, std::filesystem::absolute(log).string());
  EXPECT_EQ(recorded[0].input_sha256, record::input_sha256(log));
  EXPECT_EQ(recorded[0].sensor_name, fused.name);
  const model::ModelFile exact = model::read_model(tmp.path / "exact" / "model.toml");
  EXPECT_TRUE(fs::exists(tmp.path / "ds" / "dataset.toml"));

  for (const char* name : {"a_i", "1"}) {
    SCOPED_TRACE(name);
    double sd = 0.0, sd_exact = 0.0;
    const double value = coefficient(fused, name, &sd);
    const double value_exact = coefficient(exact, name, &sd_exact);
    const double want = truth->terms.at(name);
    std::cout << "[ figures ] " << name << ": truth " << want << ", log " << value << " +- " << sd << ", exact reference "
              << value_exact << " +- " << sd_exact << "\n";
    EXPECT_NEAR(value, want, 5 * sd);
  }
  const auto axes = input_axes(out);
  const auto axes_exact = input_axes(read_text(tmp.path / "exact.txt"));
  ASSERT_EQ(axes.size(), 4u) << out;
  for (const auto& [name, axis] : axes) {
    SCOPED_TRACE(name);
    const Eigen::Vector3d want = truth->m_es.at(name).row(0).transpose();
    const double e = angle_deg(axis, want);
    const double e_exact = axes_exact.count(name) ? angle_deg(axes_exact.at(name), want) : -1.0;
    std::cout << "[ figures ] " << name << ": input axis error " << e << " deg from the log, " << e_exact
              << " deg from the exact reference\n";
    EXPECT_LT(e, 0.1);
  }

  // diagnose on the same log with the model just characterized.
  const fs::path json = tmp.path / "diag.json";
  ASSERT_EQ(run_command(analyze_binary() + " diagnose --model " + (tmp.path / "out" / "model.toml").string() +
                            " --log " + log + " --json " + json.string(),
                        tmp.path / "diagnose.txt"),
            0)
      << read_text(tmp.path / "diagnose.txt");
  const nlohmann::json j = nlohmann::json::parse(read_text(json));
  std::cout << "[ figures ] diagnose: " << j["findings"].size() << " finding(s), "
            << j["case_misalignments"].size() << " case misalignment finding(s)\n"
            << read_text(tmp.path / "diagnose.txt");
  // A finding must be justified: significant at the level the search demanded.
  for (const auto& f : j["findings"]) EXPECT_LT(f["p_value"].get<double>(), f["p_needed"].get<double>()) << f.dump();

  // compensate on the same log with that model: every sample has a root, and the error against
  // the log's fused reference is what u states (rms of error / u near 1: the record is the one
  // output_sd was measured on, so no run-to-run scatter of the flicker's variance enters).
  ASSERT_EQ(run_command(analyze_binary() + " compensate --model " + (tmp.path / "out" / "model.toml").string() + " --log " + log +
                            " --out " + (tmp.path / "compensated.csv").string(),
                        tmp.path / "compensate.txt"),
            0)
      << read_text(tmp.path / "compensate.txt");
  const std::string compensated = read_text(tmp.path / "compensate.txt");
  std::cout << "[ figures ] compensate --log:\n" << compensated;
  EXPECT_NE(compensated.find(" 0 without a root"), std::string::npos) << compensated;
  EXPECT_NE(compensated.find("M_E^S as characterized"), std::string::npos) << compensated;
  {
    std::ifstream csv(tmp.path / "compensated.csv");
    std::string line;
    std::getline(csv, line);
    ASSERT_EQ(line, "case,t,y,a_i,u,u_coefficients,u_noise,flag,a_i_reference");
    double z2 = 0.0;
    long n = 0;
    while (std::getline(csv, line)) {
      std::vector<std::string> f;
      std::stringstream row(line);
      for (std::string field; std::getline(row, field, ',');) f.push_back(field);
      const double e = std::stod(f[3]) - std::stod(f[8]), u = std::stod(f[4]);
      z2 += e * e / (u * u);
      ++n;
    }
    ASSERT_GT(n, 0);
    EXPECT_NEAR(std::sqrt(z2 / static_cast<double>(n)), 1.0, 0.25);
  }

  // Bad input: exit 2 naming the file.
  const fs::path junk = tmp.path / "junk.lcmlog";
  std::ofstream(junk) << "not a log";
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + junk.string() + " --out " + (tmp.path / "x").string(),
                        tmp.path / "junk.txt"),
            2);
  EXPECT_NE(read_text(tmp.path / "junk.txt").find("not an LCM event log"), std::string::npos);
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + log + " --sensor nosuch --out " +
                            (tmp.path / "x").string(),
                        tmp.path / "sensor.txt"),
            2);
  EXPECT_NE(read_text(tmp.path / "sensor.txt").find("unknown sensor 'nosuch'"), std::string::npos);
}

// A log without a single plan marker (a real bench nobody marked) is cut into the
// plan's cases and phases from the references' motion; the model equals the marked log's within
// 3 combined sd, and the output says where it cut.
TEST(LogCharacterize, ALogWithoutMarkersIsSegmentedFromTheReferences) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  DaqdProcess daqd({"--config", source_path("config/sim-paper-daq.toml"), "--fast", "--log", (tmp.path / "log").string(),
                    "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(900.0), 0) << daqd.output();
  std::vector<fs::path> logs;
  for (const auto& e : fs::directory_iterator(tmp.path / "log")) logs.push_back(e.path());
  ASSERT_EQ(logs.size(), 1u);
  const fs::path unmarked = tmp.path / "unmarked.lcmlog";
  int markers = 0;
  {
    lcm::LogFile in(logs[0].string(), "r");
    lcm::LogFile out(unmarked.string(), "w");
    ASSERT_TRUE(in.good() && out.good());
    for (const lcm::LogEvent* e = in.readNextEvent(); e != nullptr; e = in.readNextEvent()) {
      if (e->channel == "INERTIA_EVENT") {
        ++markers;
        continue;
      }
      out.writeEvent(const_cast<lcm::LogEvent*>(e));
    }
  }
  ASSERT_GT(markers, 0);
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + logs[0].string() + " --out " + (tmp.path / "marked").string(),
                        tmp.path / "marked.txt"),
            0)
      << read_text(tmp.path / "marked.txt");
  const model::ModelFile marked = model::read_model(tmp.path / "marked" / "model.toml");
  // The same model on the cut log: a selection that differs on the boundary rows would make the
  // coefficients incomparable; what is tested is the cut.
  std::string terms;
  for (const model::ModelTerm& t : marked.terms) terms += (terms.empty() ? "" : ",") + t.term.to_string();
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + unmarked.string() + " --fixed-model " + terms + " --out " +
                            (tmp.path / "unmarked").string(),
                        tmp.path / "unmarked.txt"),
            0)
      << read_text(tmp.path / "unmarked.txt");
  const std::string out = read_text(tmp.path / "unmarked.txt");
  std::cout << out.substr(0, out.find("\n\n"));
  EXPECT_NE(out.find("no plan markers in this log"), std::string::npos) << out;
  for (const char* c : {"rotation-table", "shaker-ia", "shaker-pa", "shaker-oa"})
    EXPECT_NE(out.find(std::string("  case ") + c + ": static"), std::string::npos) << c << "\n" << out;

  const model::ModelFile cut = model::read_model(tmp.path / "unmarked" / "model.toml");
  int common = 0;
  for (const model::ModelTerm& t : marked.terms) {
    const std::string name = t.term.to_string();
    const auto it = std::find_if(cut.terms.begin(), cut.terms.end(), [&](const model::ModelTerm& f) { return f.term.to_string() == name; });
    if (it == cut.terms.end() || !t.std || !it->std) continue;
    ++common;
    const double combined = std::hypot(*t.std, *it->std);
    std::cout << "[ figures ] " << name << ": unmarked " << it->coefficient << ", marked " << t.coefficient << " +- " << *t.std
              << ", z " << (it->coefficient - t.coefficient) / combined << "\n";
    EXPECT_NEAR(it->coefficient, t.coefficient, 3.0 * combined) << name;
  }
  EXPECT_EQ(common, static_cast<int>(marked.terms.size()));
}

/// The log inertia-daqd --fast writes of `bench` into dir/log (its output in dir/daqd.txt), or an
/// empty path when the daemon failed.
fs::path record_fast(const std::string& bench, const fs::path& dir) {
  DaqdProcess daqd({"--config", bench, "--fast", "--log", (dir / "log").string(), "--lcm-url", private_lcm_url()}, {},
                   dir / "daqd.txt");
  if (daqd.wait(300.0) != 0) return {};
  for (const auto& e : fs::directory_iterator(dir / "log"))
    if (e.path().extension() == ".lcmlog") return e.path();
  return {};
}

TEST(LogCharacterize, AGyroscopeFromTheDaemonsLogMatchesTheSimulatorTruth) {
  // sim-rotation-table's fog1: its scale factor, rate nonlinearity (y*w_i) and g-sensitivity from
  // the table rates the fusion derives from the encoder. A rate phase runs at its rate from its
  // first sample, so the rate steps between phases; differenced across the step, the rate came out
  // half of each on the wrong phase's axis in 23 rows, and those rows left the fit a residual of
  // 2.7e-3 rad/s (1.1e-5 on the simulator's exact rates) and a g-sensitivity a_o of 4.4e-3 where
  // the truth has none. Each phase of a table case is now differenced on its own.
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string bench = source_path("config/sim-rotation-table.toml");
  const fs::path log = record_fast(bench, tmp.path);
  ASSERT_FALSE(log.empty()) << read_text(tmp.path / "daqd.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + log.string() + " --sensor fog1 --out " +
                            (tmp.path / "char").string(),
                        tmp.path / "char.txt"),
            0)
      << read_text(tmp.path / "char.txt");
  ASSERT_EQ(run_command(analyze_binary() + " simulate --bench " + bench + " --out " + (tmp.path / "sim").string(),
                        tmp.path / "sim.txt"),
            0)
      << read_text(tmp.path / "sim.txt");
  const model::ModelFile fit = model::read_model(tmp.path / "char" / "model.toml");
  const model::ModelFile truth = model::read_model(tmp.path / "sim" / "fog1" / "truth.toml");
  const std::string out = read_text(tmp.path / "char.txt");
  for (const char* required : {"w_i", "y*w_i"}) {
    EXPECT_TRUE(fit.coefficient(ident::parse_term(required)).has_value()) << required << "\n" << out;
  }
  for (const model::ModelTerm& t : fit.terms) {
    ASSERT_TRUE(t.std.has_value()) << t.term.to_string();
    const double want = truth.coefficient(t.term).value_or(0.0);
    std::cout << "[ figures ] fog1 " << t.term.to_string() << ": log " << t.coefficient << " +- " << *t.std << ", truth " << want
              << "\n";
    EXPECT_NEAR(t.coefficient, want, 3.0 * *t.std) << t.term.to_string() << "\n" << out;
  }
}

TEST(LogCharacterize, AThermalBenchFromAFastLogCarriesTheFixtureTemperature) {
  // sim-thermal: no monitors (a static pose's reference is the pose's gravity), and the fixture
  // temperature from the Modbus controller. Two things kept it from a log: the fusion asked for
  // three monitors in every non-table case, and a segment took temperature only if a reading had
  // come by its first row (the controller's first poll comes later); in a --fast run the
  // controllers were also polled in wall time: 16 readings for the 3060 s plan. Now a thermal case
  // waits for the first reading and a fast run polls on simulated time (daq::SimulatedClock).
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string bench = source_path("config/sim-thermal.toml");
  const fs::path log = record_fast(bench, tmp.path);
  ASSERT_FALSE(log.empty()) << read_text(tmp.path / "daqd.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + log.string() + " --dataset-out " +
                            (tmp.path / "fused").string() + " --out " + (tmp.path / "char").string(),
                        tmp.path / "char.txt"),
            0)
      << read_text(tmp.path / "char.txt");
  // The fixture's temperature through the plan: a reading every 0.1 s of its 3060 s, held
  // between them (the first case alone ramps 25 -> 40 -> 10 -> 25 degC over 1860 s).
  {
    std::ifstream csv(tmp.path / "fused" / "thermal-up.csv");
    std::string line;
    std::getline(csv, line);
    std::size_t column = 0;
    for (std::stringstream h(line); std::getline(h, line, ',') && line != "temp";) ++column;
    std::set<std::string> readings;
    while (std::getline(csv, line)) {
      std::stringstream r(line);
      std::string cell;
      for (std::size_t c = 0; c <= column && std::getline(r, cell, ','); ++c) {
      }
      readings.insert(cell);
    }
    EXPECT_GT(readings.size(), 1000u) << "distinct temperatures in the first case";
  }
  ASSERT_EQ(run_command(analyze_binary() + " simulate --bench " + bench + " --out " + (tmp.path / "sim").string(),
                        tmp.path / "sim.txt"),
            0)
      << read_text(tmp.path / "sim.txt");
  const model::ModelFile fit = model::read_model(tmp.path / "char" / "model.toml");
  const model::ModelFile truth = model::read_model(tmp.path / "sim" / "truth.toml");
  const std::string out = read_text(tmp.path / "char.txt");
  for (const char* name : {"1", "a_i", "T", "a_i*T"}) {
    const auto it = std::find_if(fit.terms.begin(), fit.terms.end(),
                                 [&](const model::ModelTerm& t) { return t.term.to_string() == name; });
    ASSERT_NE(it, fit.terms.end()) << name << "\n" << out;
    ASSERT_TRUE(it->std.has_value());
    const double want = *truth.coefficient(ident::parse_term(name));
    std::cout << "[ figures ] " << name << ": log " << it->coefficient << " +- " << *it->std << ", truth " << want << "\n";
    EXPECT_NEAR(it->coefficient, want, 3.0 * *it->std) << name << "\n" << out;
  }
}

TEST(ModelRoundTrip, SimulateFromAModelFileThenCharacterizeGivesTheModelBack) {
  // A model file (docs/design.md "Model file") as an engineer would write or characterize would: the
  // paper bench's plan simulated with this output, then characterized with the same terms.
  TempDir tmp;
  const fs::path model_file = tmp.path / "model.toml";
  std::ofstream(model_file) << "sensor = \"accelerometer\"\n"
                               "m_cs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
                               "[terms]\n\"1\" = 3.0e-3\n\"a_i\" = 0.0877\n\"a_i^2\" = 5.0e-7\n"
                               "\"a_i*a_p\" = 2.0e-5\n\"a_i*a_o\" = 9.0e-6\n"
                               "[noise]\nwhite_sd = 6.0e-4\n";
  const std::string bench = source_path("config/sim-paper.toml");
  ASSERT_EQ(run_command(analyze_binary() + " simulate --bench " + bench + " --model " + model_file.string() + " --out " +
                            (tmp.path / "sim").string(),
                        tmp.path / "sim.txt"),
            0)
      << read_text(tmp.path / "sim.txt");
  EXPECT_NE(read_text(tmp.path / "sim.txt").find("output from model"), std::string::npos) << read_text(tmp.path / "sim.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --dataset " + (tmp.path / "sim").string() +
                            " --fixed-model 1,a_i,a_i^2,a_i*a_p,a_i*a_o --out " + (tmp.path / "out").string(),
                        tmp.path / "char.txt"),
            0)
      << read_text(tmp.path / "char.txt");
  const model::ModelFile truth = model::read_model(model_file), fit = model::read_model(tmp.path / "out" / "model.toml");
  // truth.toml of the simulated folder is the model's, with each case's M_E^S: the output is the
  // model's free run on the references there plus white noise of its white_sd, exactly.
  const auto truth_file = commands::read_truth(tmp.path / "sim");
  ASSERT_TRUE(truth_file.has_value());
  EXPECT_EQ(truth_file->terms.at("a_i*a_p"), 2.0e-5);
  const dataset::Dataset data = dataset::read_dataset(tmp.path / "sim");
  std::vector<ident::Term> terms;
  Eigen::VectorXd theta(static_cast<Eigen::Index>(truth.terms.size()));
  for (const model::ModelTerm& t : truth.terms) {
    theta(static_cast<Eigen::Index>(terms.size())) = t.coefficient;
    terms.push_back(t.term);
  }
  double n = 0, sum = 0, sum2 = 0;
  for (const dataset::CaseData& c : data.cases) {
    const ident::SignalSet signals = ident::signals_from_case(c, truth_file->m_es.at(c.name), data.t_ref);
    const Eigen::VectorXd r = c.y - procedure::simulate_model(terms, theta, signals, 0);
    n += static_cast<double>(r.size());
    sum += r.sum();
    sum2 += r.squaredNorm();
  }
  const double mean = sum / n, noise_sd = std::sqrt(sum2 / n - mean * mean);
  std::cout << "[ figures ] output minus the model's free run: mean " << mean << ", sd " << noise_sd << " over " << n
            << " samples (model white sd 6e-4)\n";
  EXPECT_NEAR(mean, 0.0, 3.0 * 6.0e-4 / std::sqrt(n));
  EXPECT_NEAR(noise_sd, 6.0e-4, 3.0 * 6.0e-4 / std::sqrt(2.0 * n));

  // Characterize on it, the same terms: printed beside the model. Not asserted within its sd:
  // the batch sd is conditional on the estimated case misalignments and leaves their uncertainty
  // out (bias, a_i^2 and the cross-coupling magnitude land 3-7 of those sd off, 0.1-1 %; issue
  // 16), and the sensor's roll about its input axis is not observable on this plan, which turns
  // a_i*a_p into a_i*a_o. a_i, the residual and the absence of selected extras are asserted.
  const auto value = [](const model::ModelFile& m, const char* term) { return *m.coefficient(ident::parse_term(term)); };
  const auto sd = [](const model::ModelFile& m, const char* term) {
    for (const model::ModelTerm& t : m.terms)
      if (t.term.to_string() == term) return t.std.value_or(0.0);
    return 0.0;
  };
  for (const char* term : {"1", "a_i", "a_i^2", "a_i*a_p", "a_i*a_o"})
    std::cout << "[ figures ] " << term << ": fit " << value(fit, term) << " +- " << sd(fit, term) << ", model " << value(truth, term)
              << ", z " << (value(fit, term) - value(truth, term)) / sd(fit, term) << "\n";
  std::cout << "[ figures ] |a_i*a_p, a_i*a_o|: fit " << std::hypot(value(fit, "a_i*a_p"), value(fit, "a_i*a_o")) << ", model "
            << std::hypot(2.0e-5, 9.0e-6) << "\n";
  EXPECT_NEAR(value(fit, "a_i"), 0.0877, 3.0 * sd(fit, "a_i"));
  const std::string out = read_text(tmp.path / "char.txt");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"(batch model \((\d+) rows, residual sd ([0-9.eE+-]+) mA)"))) << out;
  const double rows = std::stod(m[1].str()), residual_sd = std::stod(m[2].str());
  std::cout << "[ figures ] characterize's residual sd " << residual_sd << " over " << rows << " rows\n";
  EXPECT_NEAR(residual_sd, 6.0e-4, 3.0 * 6.0e-4 / std::sqrt(2.0 * rows));
}

TEST(LogCharacterize, OptionsForALogAloneAreRefusedWithADataset) {
  TempDir tmp;
  for (const std::string& command : {std::string("characterize --dataset ") + tmp.path.string() + " --sensor acc1 --out " + (tmp.path / "o").string(),
                                     std::string("characterize --dataset ") + tmp.path.string() + " --dataset-out " + (tmp.path / "d").string() +
                                         " --out " + (tmp.path / "o").string(),
                                     std::string("noise --dataset ") + tmp.path.string() + " --sensor acc1 --out " + (tmp.path / "o").string()}) {
    EXPECT_EQ(run_command(analyze_binary() + " " + command, tmp.path / "out.txt"), 2) << command;
    EXPECT_NE(read_text(tmp.path / "out.txt").find("requires --log"), std::string::npos) << read_text(tmp.path / "out.txt");
  }
}

/// sim-rotation-table simulated into tmp/data: its accelerometer's dataset folder (empty when
/// `simulate` failed; its output is tmp/simulate.txt).
fs::path simulated_rotation_table_acc1(const TempDir& tmp) {
  const fs::path data = tmp.path / "data";
  if (run_command(analyze_binary() + " simulate --bench " + std::string(INERTIA_SOURCE_DIR) + "/config/sim-rotation-table.toml --out " +
                      data.string(),
                  tmp.path / "simulate.txt") != 0)
    return {};
  return data / "acc1";
}

// A case with fewer rows than the report's whiteness checks have lags (a lossy log cuts a case
// into pieces; an operator aborts a case) is reported, not a reason to fail: its row in the
// verification table names it too short, and the rest of the report stands.
TEST(Characterize, ACaseTooShortForTheWhitenessChecksIsNamedSoInTheReport) {
  TempDir tmp;
  const fs::path out = tmp.path / "out";
  const fs::path dataset = simulated_rotation_table_acc1(tmp);
  ASSERT_FALSE(dataset.empty()) << read_text(tmp.path / "simulate.txt");
  {
    std::ifstream full(dataset / "rate-series.csv");
    std::ofstream cut(dataset / "cut-short.csv");
    std::string line;
    for (int k = 0; k < 16 && std::getline(full, line); ++k) cut << line << "\n";   // the header and 15 rows
    std::ofstream(dataset / "dataset.toml", std::ios::app)
        << "\n[[case]]\nname = \"cut-short\"\nkind = \"rotation_table\"\nfile = \"cut-short.csv\"\n"
           "m_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n";
  }
  ASSERT_EQ(run_command(analyze_binary() + " characterize --dataset " + dataset.string() + " --out " + out.string(),
                        tmp.path / "characterize.txt"),
            0)
      << read_text(tmp.path / "characterize.txt");
  const std::string report = read_text(out / "report.md");
  EXPECT_NE(report.find("| cut-short | all | 15 |"), std::string::npos) << report;
  EXPECT_NE(report.find("| - | too short (0/0 lags out) | too short (0/0) |"), std::string::npos) << report;
  EXPECT_NE(report.find("| rate-series | all | 48000 |"), std::string::npos) << report;
}

// A characterize stopped by SIGINT stops at once and leaves the folder as the last complete run
// left it: its model.toml and report.md, byte for byte, and no temporary file. --order 2 keeps
// the run in its computation well past the half second the signal waits.
TEST(Characterize, AnInterruptedRunLeavesTheLastCompleteOutputAsItWas) {
  TempDir tmp;
  const fs::path out = tmp.path / "out";
  const fs::path dataset = simulated_rotation_table_acc1(tmp);
  ASSERT_FALSE(dataset.empty()) << read_text(tmp.path / "simulate.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --dataset " + dataset.string() + " --out " + out.string(),
                        tmp.path / "first.txt"),
            0)
      << read_text(tmp.path / "first.txt");
  const std::string model = read_text(out / "model.toml"), report = read_text(out / "report.md");
  ASSERT_FALSE(model.empty());
  DaqdProcess run({"characterize", "--dataset", dataset.string(), "--out", out.string(), "--order", "2"}, {},
                  tmp.path / "second.txt", analyze_binary());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto signalled = std::chrono::steady_clock::now();
  run.signal(SIGINT);
  EXPECT_EQ(run.wait(5.0), 128 + SIGINT) << run.output();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count(), 1.0);
  EXPECT_EQ(read_text(out / "model.toml"), model);
  EXPECT_EQ(read_text(out / "report.md"), report);
  for (const fs::directory_entry& e : fs::directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << e.path();
}

}  // namespace
}  // namespace inertia::daq::testing
