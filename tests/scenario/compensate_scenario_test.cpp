// Compensation on held-out data: a sensor characterized on one simulated run of its bench, then
// its model applied by `compensate` to another run (another seed: other noise, the same sensor
// and fixtures). Scored against the run's reference input along the sensed axis, beside
//   the raw output over the nominal scale factor, and
//   the simulator's true model, each case in its true M_E^S (the best any model can do).
// The error's rms over its stated standard uncertainty is about 1.
// The seeds here are what CI time allows (INERTIA_SCENARIO_SEEDS raises them, e.g. to 20).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "analyzer/commands/characterize.hpp"
#include "analyzer/commands/compensate.hpp"
#include "analyzer/commands/truth_file.hpp"
#include "analyzer/record/record_store.hpp"
#include "analyzer/report/parameter_sheet.hpp"
#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"
#include "common/config/bench_config.hpp"
#include "common/dataset/dataset.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/simulate.hpp"
#include "tests/support/scratch_dirs.hpp"
#include "tests/support/skip_or_fail.hpp"

namespace {

namespace fs = std::filesystem;
using namespace inertia;

int seeds_from_environment(int fallback) {
  const char* text = std::getenv("INERTIA_SCENARIO_SEEDS");
  return text != nullptr ? std::max(1, std::atoi(text)) : fallback;
}

fs::path simulated(const fs::path& bench_file, std::uint64_t seed, const fs::path& out) {
  config::BenchConfig bench = config::load_bench_config(bench_file);
  config::reseed(bench, seed);
  sim::write_simulation(bench, sim::simulate_bench(bench), out);
  return out;
}

struct Errors {
  double sum2 = 0.0, raw2 = 0.0, z2 = 0.0;   // z: error over its stated u
  long n = 0;
  long flagged = 0;
  [[nodiscard]] double rms() const { return std::sqrt(sum2 / static_cast<double>(n)); }
  [[nodiscard]] double raw_rms() const { return std::sqrt(raw2 / static_cast<double>(n)); }
  [[nodiscard]] double z_rms() const { return std::sqrt(z2 / static_cast<double>(n)); }
};

/// The CSV compensate wrote: error of each compensated sample against its reference, and of the
/// raw output over `scale`.
Errors csv_errors(const fs::path& csv, const std::string& sensed, double scale) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "case,t,y," + sensed + ",u,u_coefficients,u_noise,flag," + sensed + "_reference");
  Errors e;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream row(line);
    for (std::string field; std::getline(row, field, ',');) f.push_back(field);
    const double y = std::stod(f[2]), value = std::stod(f[3]), u = std::stod(f[4]), reference = std::stod(f[8]);
    if (f[7] == "not_converged") {
      ++e.flagged;
      continue;
    }
    e.sum2 += (value - reference) * (value - reference);
    e.raw2 += (y / scale - reference) * (y / scale - reference);
    e.z2 += (value - reference) * (value - reference) / (u * u);
    ++e.n;
  }
  return e;
}

/// The true model on the same record, each case in its true M_E^S.
Errors true_model_errors(const fs::path& dataset_dir) {
  const model::ModelFile truth = model::read_model(dataset_dir / "truth.toml");
  const std::optional<commands::Truth> t = commands::read_truth(dataset_dir);
  const dataset::Dataset data = dataset::read_dataset(dataset_dir);
  const compensate::InverseModel inverse(truth);
  Errors e;
  for (const dataset::CaseData& c : data.cases) {
    const ident::SignalSet s = ident::signals_from_case(c, t->m_es.at(c.name), *truth.t_ref);
    const compensate::CompensatedSignal r = inverse.compensate(s, c.sample_period_s);
    const Eigen::VectorXd reference = s.get(inverse.sensed()).tail(r.value.size());
    for (Eigen::Index k = 0; k < r.value.size(); ++k) {
      if (!std::isfinite(r.value(k))) {
        ++e.flagged;
        continue;
      }
      e.sum2 += std::pow(r.value(k) - reference(k), 2);
      ++e.n;
    }
  }
  return e;
}

/// `per_run_z`: whether one run's error / u is held to 1 +- 0.15. A long record averages its
/// noise's variance to a few percent of the law's; a short one dominated by flicker does not (the
/// paper plan's 10 s record: 0.71 to 1.41 over 20 seeds, pooled 1.00; docs/validation.md), and is
/// held to the pooled value once ten or more seeds run.
void check_bench(const std::string& bench_name, const std::string& sensor, int seeds, bool per_run_z) {
  double pooled_z2 = 0.0;
  const fs::path bench = fs::path(INERTIA_SOURCE_DIR) / "config" / (bench_name + ".toml");
  for (int s = 0; s < seeds; ++s) {
    SCOPED_TRACE(bench_name + " seed " + std::to_string(301 + 2 * s));
    const inertia::testing::TempDir dir("inertia-compensate");
    const fs::path characterized = simulated(bench, 301 + 2 * s, dir.path / "characterized");
    const fs::path held_out = simulated(bench, 302 + 2 * s, dir.path / "held-out");
    // One sensor's folder: OUT/<sensor>/ on a bench of several, OUT itself on a bench of one.
    const auto folder = [&](const fs::path& out) { return fs::exists(out / sensor) ? out / sensor : out; };
    commands::CharacterizeOptions c;
    c.dataset = folder(characterized);
    c.out = dir.path / "model";
    c.plots = false;
    std::ostringstream sink;
    ASSERT_EQ(commands::run_characterize(c, sink), 0);
    const model::ModelFile model = model::read_model(c.out / "model.toml");

    commands::CompensateOptions o;
    o.model = c.out / "model.toml";
    o.dataset = folder(held_out);
    o.out = dir.path / "compensated.csv";
    std::ostringstream summary;
    ASSERT_EQ(commands::run_compensate(o, summary), 0);
    const std::string sensed = model.sensor == dataset::SensorKind::Accelerometer ? "a_i" : "w_i";
    const Errors compensated = csv_errors(o.out, sensed, *model.coefficient(ident::parse_term(sensed)));
    const Errors best = true_model_errors(folder(held_out));
    std::cout << "[ figures ] " << bench_name << " " << sensor << ": rms error " << compensated.rms() << " SI (raw "
              << compensated.raw_rms() << ", true model " << best.rms() << "), no root " << compensated.flagged << " (true model "
              << best.flagged << ") of " << compensated.n << ", rms of error / u " << compensated.z_rms() << "\n";
    EXPECT_EQ(compensated.flagged, 0) << summary.str();
    EXPECT_LT(compensated.rms(), 1.5 * best.rms()) << summary.str();
    EXPECT_GT(compensated.raw_rms(), 10.0 * compensated.rms()) << summary.str();
    // u states the error's size: the noise's variance, estimated on the characterizing run, holds
    // on the held-out one to the scatter of a coloured record's variance between runs.
    if (per_run_z) {
      EXPECT_NEAR(compensated.z_rms(), 1.0, 0.15) << summary.str();
    }
    pooled_z2 += compensated.z_rms() * compensated.z_rms();
  }
  if (!per_run_z && seeds >= 10) {
    EXPECT_NEAR(std::sqrt(pooled_z2 / seeds), 1.0, 0.15);
  }
}

TEST(CompensateScenario, HeldOutRotationTableRunWithinItsTrueModelsError) {
  check_bench("sim-rotation-table", "acc1", seeds_from_environment(2), true);
}

TEST(CompensateScenario, HeldOutRateTableGyroRunWithinItsTrueModelsError) {
  check_bench("sim-rotation-table", "fog1", seeds_from_environment(1), true);
}

TEST(CompensateScenario, HeldOutPaperRunWithinItsTrueModelsError) {
  check_bench("sim-paper-daq", "acc1", seeds_from_environment(1), false);
}

// The parameter sheet's intervals (k = 2) against the simulator's truth: the same definitions
// applied to truth.toml (the true model in the model file's form). Misalignment (scored against
// the true M_E^S by characterize's own tests) and the noise terms (truth.toml states the noise's
// law, not Q N B K) are left out. A parameter counts where both sheets determine it.
struct Coverage {
  std::map<std::string, std::pair<int, int>> by_parameter;   // covered, total
  int covered = 0, total = 0;
};

void sheet_against_truth(const std::string& bench_name, const std::string& sensor, int seeds, Coverage& coverage) {
  const fs::path bench = fs::path(INERTIA_SOURCE_DIR) / "config" / (bench_name + ".toml");
  for (int s = 0; s < seeds; ++s) {
    const inertia::testing::TempDir dir("inertia-sheet");
    const fs::path data = simulated(bench, 401 + s, dir.path / "data");
    const fs::path folder = fs::exists(data / sensor) ? data / sensor : data;
    commands::CharacterizeOptions c;
    c.dataset = folder;
    c.out = dir.path / "model";
    c.plots = false;
    std::ostringstream sink;
    ASSERT_EQ(commands::run_characterize(c, sink), 0);
    const model::ModelFile characterized = model::read_model(c.out / "model.toml");
    const report::ParameterSheet estimated = report::parameter_sheet(characterized);
    // The truth over the same characterized range (a range-dependent parameter, as the nonlinearity).
    model::ModelFile true_model = model::read_model(folder / "truth.toml");
    true_model.range = characterized.range;
    const report::ParameterSheet truth = report::parameter_sheet(true_model);
    for (const report::SheetEntry& e : estimated.entries) {
      if (e.status != report::SheetEntry::Status::Determined || e.name.find("misalignment") != std::string::npos ||
          e.terms.front().rfind("noise", 0) == 0)
        continue;
      const auto t = std::find_if(truth.entries.begin(), truth.entries.end(), [&](const report::SheetEntry& x) { return x.name == e.name; });
      // A parameter the truth lacks is 0 there (the simulator has no such effect).
      const double want = t->status == report::SheetEntry::Status::Determined ? t->value : 0.0;
      const bool covered = std::abs(e.value - want) <= e.expanded_uncertainty;
      auto& [c_covered, c_total] = coverage.by_parameter[bench_name + " " + sensor + " " + e.name];
      c_covered += covered;
      ++c_total;
      coverage.covered += covered;
      ++coverage.total;
      if (!covered)
        std::cout << "[ figures ] not covered: " << bench_name << " " << sensor << " seed " << 401 + s << " " << e.name << " "
                  << e.value << " +- " << e.expanded_uncertainty << ", truth " << want << "\n";
    }
  }
}

TEST(ParameterSheetScenario, IntervalsCoverTheSimulatorsTruth) {
  Coverage coverage;
  const int seeds = seeds_from_environment(2);
  sheet_against_truth("sim-rotation-table", "acc1", seeds, coverage);
  sheet_against_truth("sim-rotation-table", "fog1", seeds, coverage);
  sheet_against_truth("sim-thermal", "acc1", seeds, coverage);
  sheet_against_truth("sim-gyro-thermal", "fog1", seeds, coverage);
  for (const auto& [name, counts] : coverage.by_parameter)
    std::cout << "[ figures ] " << name << ": covered " << counts.first << " of " << counts.second << "\n";
  ASSERT_GT(coverage.total, 0);
  // k = 2 intervals cover 95 % of the time; at least 90 % here (the target).
  EXPECT_GE(static_cast<double>(coverage.covered) / coverage.total, 0.9) << coverage.covered << " of " << coverage.total;
}

// The lab's record over a sensor's calibrations (docs/record.md): sim-rotation-table's acc1 at
// calibrations 0..4, each characterized with --record into one database, then record's history
// of its bias. An aging sensor drifts 3 sd of its bias per calibration ([sensor.aging] k_b);
// `find_drift` (family-wise 5 % over the comparisons with the first) must flag it by the second
// step, and flag nothing on a stable sensor.
std::string aged_bench(const fs::path& source, int calibration, double k_b_drift_g) {
  std::ifstream in(source);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string name = "name = \"acc1\"\n";
  text.replace(text.find(name), name.size(), name + "calibration = " + std::to_string(calibration) + "\n");
  // [sensor.aging] closes acc1's tables: before the next [[sensor]].
  const std::size_t next = text.find("[[sensor]]", text.find(name));
  text.insert(next, fmt::format("[sensor.aging]\nk_b = {}\n\n", k_b_drift_g));
  return text;
}

std::optional<std::size_t> drift_over_calibrations(double drift_g, std::uint64_t seed, double* bias_sd_ug = nullptr) {
  const fs::path source = fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-rotation-table.toml";
  const inertia::testing::TempDir dir("inertia-aging");
  const fs::path db = dir.path / "record.sqlite";
  for (int n = 0; n < 5; ++n) {
    const fs::path bench_file = dir.path / fmt::format("bench-{}.toml", n);
    std::ofstream(bench_file) << aged_bench(source, n, drift_g);
    const fs::path data = simulated(bench_file, seed * 10 + static_cast<std::uint64_t>(n), dir.path / fmt::format("data-{}", n));
    commands::CharacterizeOptions c;
    c.dataset = data / "acc1";
    c.out = dir.path / fmt::format("char-{}", n);
    c.plots = false;
    c.record_db = db.string();
    c.serial = "SN-AGING";
    std::ostringstream sink;
    if (commands::run_characterize(c, sink) != 0) ADD_FAILURE() << sink.str();
  }
  const std::vector<record::ParameterPoint> history = record::RecordStore(db).history("SN-AGING", "bias");
  EXPECT_EQ(history.size(), 5u);
  if (bias_sd_ug != nullptr && !history.empty()) *bias_sd_ug = *history.front().expanded_uncertainty / 2.0;
  return record::find_drift(history).first_flagged;
}

// The bench file states the sensor's serial and part: characterize records them (and writes them
// in the model), refuses another --serial before any work, and compensate refuses the model on
// data of another serial.
TEST(RecordScenario, TheBenchsSerialIsRecordedAndAnotherIsRefused) {
  const fs::path source = fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-rotation-table.toml";
  const inertia::testing::TempDir dir("inertia-serial");
  const auto bench_with_serial = [&](const std::string& serial) {
    std::ifstream in(source);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string name = "name = \"acc1\"\n";
    text.replace(text.find(name), name.size(), name + "serial = \"" + serial + "\"\npart = \"QA-SIM\"\n");
    const fs::path file = dir.path / ("bench-" + serial + ".toml");
    std::ofstream(file) << text;
    return file;
  };
  const fs::path data = simulated(bench_with_serial("SN-7"), 71, dir.path / "data-7");
  const std::string db = (dir.path / "record.sqlite").string();
  commands::CharacterizeOptions c;
  c.dataset = data / "acc1";
  c.out = dir.path / "char-wrong";
  c.plots = false;
  c.record_db = db;
  c.serial = "SN-8";
  std::ostringstream sink;
  try {
    commands::run_characterize(c, sink);
    ADD_FAILURE() << "characterize took --serial SN-8 for the bench's SN-7";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("SN-7"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(c.out)) << "refused before any work";
  EXPECT_TRUE(record::RecordStore(db).list().empty());

  c.serial.clear();
  c.out = dir.path / "char";
  ASSERT_EQ(commands::run_characterize(c, sink), 0) << sink.str();
  const std::vector<record::Characterization> recorded = record::RecordStore(db).list();
  ASSERT_EQ(recorded.size(), 1u);
  EXPECT_EQ(recorded[0].serial, "SN-7");
  EXPECT_EQ(recorded[0].part, "QA-SIM");
  const model::ModelFile model = model::read_model(c.out / "model.toml");
  EXPECT_EQ(model.serial, "SN-7");
  EXPECT_EQ(model.part, "QA-SIM");

  const fs::path other = simulated(bench_with_serial("SN-9"), 72, dir.path / "data-9");
  commands::CompensateOptions k;
  k.model = c.out / "model.toml";
  k.dataset = other / "acc1";
  k.out = dir.path / "compensated.csv";
  std::ostringstream summary;
  try {
    commands::run_compensate(k, summary);
    ADD_FAILURE() << "compensate applied SN-7's model to SN-9's data";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("serial number 'SN-7'"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(k.out));
}

TEST(RecordScenario, HistoryFindsAnAgingSensorByTheSecondStepAndNotAStableOne) {
  const int runs = seeds_from_environment(2);
  int stable_flagged = 0;
  double sd_sum = 0.0;
  for (int s = 0; s < runs; ++s) {
    double sd_ug = 0.0;
    stable_flagged += drift_over_calibrations(0.0, 500 + static_cast<std::uint64_t>(s), &sd_ug).has_value();
    sd_sum += sd_ug;
  }
  const double sd_ug = sd_sum / runs;
  std::cout << "[ figures ] stable sensor: drift flagged in " << stable_flagged << " of " << runs << " histories; bias sd "
            << sd_ug << " ug (mean of their first calibrations)\n";
  // At most 1 in 20 (the family-wise 5 %); none in CI's two.
  EXPECT_LE(stable_flagged, runs / 20);
  // 3 sd of the bias per calibration. At the second step the change is 6 sd, its scatter 1.41 sd,
  // and En > 1.25 asks for 3.54 sd: missed with p = Phi(-1.74) = 0.04 per history. The misses
  // allowed are the 95 % quantile of Binomial(runs, 0.04): none for CI's one history.
  const int aging_runs = std::max(1, runs / 2);
  int by_second_step = 0;
  for (int s = 0; s < aging_runs; ++s) {
    const std::optional<std::size_t> aging = drift_over_calibrations(3.0 * sd_ug * 1e-6, 600 + static_cast<std::uint64_t>(s));
    std::cout << "[ figures ] aging sensor: drift flagged at calibration " << (aging ? std::to_string(*aging) : "none") << "\n";
    by_second_step += aging.has_value() && *aging <= 2;
  }
  int allowed = 0;
  for (double cdf = 0.0;; ++allowed) {
    cdf += std::exp(std::lgamma(aging_runs + 1.0) - std::lgamma(allowed + 1.0) - std::lgamma(aging_runs - allowed + 1.0) +
                    allowed * std::log(0.04) + (aging_runs - allowed) * std::log(0.96));
    if (cdf >= 0.95) break;
  }
  EXPECT_GE(by_second_step, aging_runs - allowed) << by_second_step << " of " << aging_runs;
}

// The compensated CSV grows with the record: on a disk that cannot hold it, compensate is refused
// before any work, with the figures, and writes nothing.
TEST(CompensateScenario, ADiskTooSmallForTheCsvIsRefusedBeforeWork) {
  const inertia::testing::TempDir dir("inertia-compensate");
  const inertia::testing::SmallDisk disk(dir.path / "small", "1m");
  if (!disk.why_not.empty()) INERTIA_SKIP_OR_FAIL_IN_CI(disk.why_not);
  const fs::path data = simulated(fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-rotation-table.toml", 5, dir.path / "data");
  commands::CompensateOptions o;
  o.model = data / "acc1" / "truth.toml";
  o.dataset = data / "acc1";
  o.out = disk.path / "compensated.csv";
  std::ostringstream sink;
  try {
    (void)commands::run_compensate(o, sink);
    ADD_FAILURE() << "compensate wrote 109000 samples onto a 1 MB disk";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("compensated samples"), std::string::npos) << e.what();
    std::cout << "[ figures ] " << e.what() << "\n";
  }
  EXPECT_TRUE(fs::is_empty(disk.path));
  EXPECT_EQ(sink.str().find("per case"), std::string::npos) << "refused before any sample was compensated";
}

TEST(CompensateScenario, RefusesAnotherSensorsRecord) {
  const inertia::testing::TempDir dir("inertia-compensate");
  const fs::path bench = fs::path(INERTIA_SOURCE_DIR) / "config" / "sim-rotation-table.toml";
  const fs::path data = simulated(bench, 5, dir.path / "data");
  commands::CompensateOptions o;
  o.out = dir.path / "x.csv";
  std::ostringstream sink;
  // The accelerometer's true model on the gyroscope's record: another kind.
  o.model = data / "acc1" / "truth.toml";
  o.dataset = data / "fog1";
  EXPECT_THROW((void)commands::run_compensate(o, sink), InputError);
  // Another accelerometer's name.
  model::ModelFile other = model::read_model(data / "acc1" / "truth.toml");
  other.name = "acc7";
  model::write_model(dir.path / "acc7.toml", other);
  o.model = dir.path / "acc7.toml";
  o.dataset = data / "acc1";
  try {
    (void)commands::run_compensate(o, sink);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sensor 'acc7'"), std::string::npos) << e.what();
  }
  // Lags counted at another sample period.
  other.name = "acc1";
  other.sample_period_s = 1e-4;
  model::write_model(dir.path / "fast.toml", other);
  o.model = dir.path / "fast.toml";
  EXPECT_THROW((void)commands::run_compensate(o, sink), InputError);
  EXPECT_FALSE(fs::exists(o.out));
}

}  // namespace
