// `inertia-analyze online` live: the real daemon plays a simulated bench in real time on a private
// multicast port, the real analyzer subscribes, fuses and estimates, and a third process (this
// test) receives what lcm-spy would show. The answer is held against `characterize --log` of the
// daemon's own log and against the simulator's truth (truth.toml of `simulate` on the same bench).
#include <gtest/gtest.h>

#include <fstream>

#include <cmath>
#include <iterator>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <sstream>

#include "analyzer/model/model_file.hpp"
#include "common/config/bench_config.hpp"
#include "daqd_harness.hpp"
#include "inertia/analyzer_status_t.hpp"
#include "inertia/bench_config_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/model_estimate_t.hpp"
#include "inertia/structure_table_t.hpp"

namespace inertia::daq::testing {
namespace {

std::string analyze_binary() { return std::string(INERTIA_BINARY_DIR) + "/bin/inertia-analyze"; }

template <class T>
std::vector<std::pair<std::int64_t, T>> decoded(const std::vector<LcmCollector::Received>& received, const std::string& channel) {
  std::vector<std::pair<std::int64_t, T>> out;
  for (const auto& r : received) {
    if (r.channel != channel) continue;
    T m;
    if (m.decode(r.data.data(), 0, static_cast<int>(r.data.size())) >= 0) out.emplace_back(r.mono_ns, std::move(m));
  }
  return out;
}

/// Waits until the live analyzer says it is listening (its "online: bench ..." line, printed once
/// it has subscribed), at most 30 s: a message published before that is lost to it, and a loaded
/// machine can take longer than any fixed pause to start the process.
[[nodiscard]] bool listening(const DaqdProcess& online) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < deadline) {
    if (online.output().find("online: bench ") != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

struct LiveRun {
  std::vector<LcmCollector::Received> received;
  std::string online_output, daqd_output;
  fs::path log;
};

/// The daemon paced on `config` with the analyzer beside it, everything collected.
LiveRun run_live(const TempDir& tmp, const std::string& config, const std::vector<std::string>& online_extra = {}) {
  LiveRun run;
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  EXPECT_TRUE(live.good());
  std::vector<std::string> args = {"online", "--config", config, "--lcm-url", url, "--publish-hz", "10"};
  args.insert(args.end(), online_extra.begin(), online_extra.end());
  DaqdProcess online(args, {}, tmp.path / "online.txt", analyze_binary());
  EXPECT_TRUE(listening(online)) << online.output();   // subscribed before the daemon's first message
  DaqdProcess daqd({"--config", config, "--lcm-url", url, "--log", (tmp.path / "log").string()}, {}, tmp.path / "daqd.txt");
  EXPECT_EQ(daqd.wait(120), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));   // the last blocks reach the analyzer
  online.signal(SIGTERM);                                         // graceful: fuses what is held back, publishes
  EXPECT_EQ(online.wait(30), 0) << online.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  run.received = live.take();
  run.online_output = online.output();
  run.daqd_output = daqd.output();
  for (const auto& e : fs::directory_iterator(tmp.path / "log"))
    if (e.path().extension() == ".lcmlog") run.log = e.path();
  return run;
}

double coefficient(const model_estimate_t& m, const std::string& term, double* sd) {
  for (std::int32_t j = 0; j < m.num_terms; ++j) {
    if (m.terms[static_cast<std::size_t>(j)] == term) {
      *sd = m.std_devs[static_cast<std::size_t>(j)];
      return m.values[static_cast<std::size_t>(j)];
    }
  }
  ADD_FAILURE() << "no term " << term;
  return NAN;
}

// The paper's bench: a rotation table mounting (2 deg about case z) and a shaker fixture carrying
// three orientations (2 deg about [1,1,1]). sim-paper-daq is it shortened, 10.5 s at 1 kHz;
// sim-paper is the whole plan, 47.5 s at 10 kHz.
class OnlineLivePaperBench : public ::testing::TestWithParam<const char*> {};

TEST_P(OnlineLivePaperBench, TwoMountingsPacedEstimatesEverySecondAndEqualCharacterizeOfTheSameLog) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = source_path(std::string("config/") + GetParam());
  const LiveRun run = run_live(tmp, config, {"--history", (tmp.path / "history.csv").string()});
  ASSERT_FALSE(run.log.empty()) << run.daqd_output;
  const config::BenchConfig bench = config::load_bench_config(config);

  std::int64_t first_raw = 0, last_raw = 0;
  for (const auto& r : run.received) {
    if (r.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
    if (first_raw == 0) first_raw = r.mono_ns;
    last_raw = r.mono_ns;
  }
  ASSERT_GT(last_raw, first_raw);
  const auto estimates = decoded<model_estimate_t>(run.received, "INERTIA_ESTIMATE_ACC1");
  const double run_s = 1e-9 * static_cast<double>(last_raw - first_raw);
  ASSERT_GE(static_cast<double>(estimates.size()), 7.5 * run_s) << "10 Hz over the " << run_s << " s run\n"
                                                                 << run.online_output;

  // Cadence: samples in the estimate within 3 s of the first raw block, and more of them in every
  // one-second window while the daemon samples.
  std::int64_t first_with_samples = 0;
  for (const auto& [t, m] : estimates) {
    if (m.samples_used > 0) {
      first_with_samples = t;
      break;
    }
  }
  ASSERT_GT(first_with_samples, 0);
  EXPECT_LT(1e-9 * static_cast<double>(first_with_samples - first_raw), 3.0) << run.online_output;
  std::int64_t previous_max = -1;
  for (std::int64_t w = first_with_samples; w + 1'000'000'000 <= last_raw; w += 1'000'000'000) {
    std::int64_t window_max = -1;
    for (const auto& [t, m] : estimates)
      if (t >= w && t < w + 1'000'000'000) window_max = std::max(window_max, m.samples_used);
    EXPECT_GT(window_max, previous_max) << "window starting " << 1e-9 * static_cast<double>(w - first_raw) << " s";
    previous_max = window_max;
  }

  const model_estimate_t& last = estimates.back().second;
  EXPECT_EQ(last.sensor, "acc1");
  EXPECT_TRUE(last.converged) << last.convergence << "\n" << run.online_output;
  ASSERT_EQ(last.num_mountings, 2);
  EXPECT_EQ(last.mountings[0], "rotation-table");
  EXPECT_EQ(last.mountings[1], "shaker-fixture");
  EXPECT_TRUE(last.mounting_determined[0] && last.mounting_determined[1]);
  EXPECT_EQ(last.cases_used, 4);

  // The same log through the batch procedure.
  DaqdProcess characterize({"characterize", "--log", run.log.string(), "--out", (tmp.path / "char").string()}, {},
                           tmp.path / "char.txt", analyze_binary());
  ASSERT_EQ(characterize.wait(120), 0) << characterize.output();
  const model::ModelFile offline = model::read_model(tmp.path / "char" / "model.toml");
  int common = 0;
  for (const model::ModelTerm& t : offline.terms) {
    const std::string name = t.term.to_string();
    double sd = 0.0;
    const auto it = std::find(last.terms.begin(), last.terms.end(), name);
    if (it == last.terms.end()) continue;
    ++common;
    const double live_value = coefficient(last, name, &sd);
    ASSERT_TRUE(t.std.has_value()) << name;
    const double combined = std::hypot(sd, *t.std);
    EXPECT_NEAR(live_value, t.coefficient, 3.0 * combined) << name << "\n" << run.online_output << characterize.output();
    if (name == "a_i") {
      EXPECT_NEAR(live_value, t.coefficient, 5e-4 * std::abs(t.coefficient));
    }
    if (name == "1" || name.find('*') != std::string::npos) {
      EXPECT_NEAR(live_value, t.coefficient, 0.1 * std::abs(t.coefficient)) << name;
    }
  }
  EXPECT_GE(common, 6) << characterize.output();

  // And the simulator's truth (the same bench and seed through `simulate`): the scale factor and
  // the squares' high-frequency gains within the noise and the reference's calibration error
  // (the monitors' uncalibrated scale errors up to 1.2e-3).
  DaqdProcess simulate({"simulate", "--bench", config, "--out", (tmp.path / "sim").string()}, {}, tmp.path / "sim.txt",
                       analyze_binary());
  ASSERT_EQ(simulate.wait(120), 0) << simulate.output();
  const model::ModelFile truth = model::read_model(tmp.path / "sim" / "truth.toml");
  for (const char* name : {"a_i", "a_i^2", "a_p^2", "a_o^2"}) {
    double sd = 0.0;
    const double live_value = coefficient(last, name, &sd);
    const double want = *truth.coefficient(ident::parse_term(name));
    EXPECT_NEAR(live_value, want, 4.0 * sd + 2.5e-3 * std::abs(want)) << name;
  }
  EXPECT_TRUE(std::isfinite(last.square_corner_rad_s));
  EXPECT_NEAR(last.square_corner_rad_s, 500.0, 0.15 * 500.0) << "eq. 12's corner (truth 500 rad/s)";

  // The structure table and the analyzer's status are on their channels.
  const auto tables = decoded<structure_table_t>(run.received, "INERTIA_STRUCTURE_ACC1");
  ASSERT_FALSE(tables.empty());
  const structure_table_t& table = tables.back().second;
  EXPECT_GT(table.num_candidates, 5);
  for (std::int32_t j = 0; j < table.num_candidates; ++j) {
    EXPECT_GE(table.err[static_cast<std::size_t>(j)], 0.0);
    EXPECT_LE(table.err[static_cast<std::size_t>(j)], 1.0);
  }
  const auto status = decoded<analyzer_status_t>(run.received, "INERTIA_ANALYZER_STATUS");
  ASSERT_GE(status.size(), 5u);
  const analyzer_status_t& s = status.back().second;
  EXPECT_GT(s.received, 3000);
  EXPECT_EQ(s.skipped_malformed + s.skipped_invalid + s.skipped_refused + s.queue_drops, 0);
  EXPECT_EQ(s.bench, bench.name);
  EXPECT_TRUE(fs::file_size(tmp.path / "history.csv") > 1000);
}

INSTANTIATE_TEST_SUITE_P(Bench, OnlineLivePaperBench, ::testing::Values("sim-paper-daq.toml", "sim-paper.toml"),
                         [](const ::testing::TestParamInfo<const char*>& info) { return bench_test_name(info.param); });

// Every other shipped bench, sensor by sensor: the live answer on
// the daemon's log (`online --replay`, the live worker as fast as it reads) against the batch's
// (`characterize --log`) on the same log. The terms both determine agree within 3 combined sd;
// what the batch's selection left out the live model may still carry, within 4 sd of the
// simulator's truth like every live term, and what the live estimate
// leaves undetermined (sim-shaker aligns no mounting: the frame-free terms only) is NaN, never a
// number. And the last estimate is converged: on a plan with no case to spare (sim-rotation-table's
// rate series alone gives acc1's centripetal terms; sim-thermal's two poses) by its phases.
struct EveryBenchCase {
  const char* bench;
  std::vector<const char*> sensors;
};

class OnlineReplay : public ::testing::TestWithParam<EveryBenchCase> {};

/// The mountings whose twist `text` says is held (procedure::held_twist_note, which live and the
/// batch both write).
std::set<std::string> held_twists(const std::string& text) {
  std::set<std::string> out;
  constexpr std::string_view kMounting = "twist about n_i of mounting '";
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.find("held at the nominal frame, and what the tolerance moves is in the sd") == std::string::npos) continue;
    for (std::size_t at = line.find(kMounting); at != std::string::npos; at = line.find(kMounting, at + 1)) {
      const std::size_t begin = at + kMounting.size();
      out.insert(line.substr(begin, line.find('\'', begin) - begin));
    }
  }
  return out;
}

/// What `online --replay` printed of `sensor` at the end: from its history's heading to the next sensor's.
std::string sensor_block(const std::string& output, const std::string& sensor) {
  const std::size_t begin = output.find("online: " + sensor + ": live estimate history");
  if (begin == std::string::npos) return {};
  return output.substr(begin, output.find("\nonline: ", begin + 1) - begin);
}

TEST_P(OnlineReplay, TheLiveAnswerOnTheDaemonsLogEqualsCharacterizeOfIt) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = source_path(std::string("config/") + GetParam().bench);
  DaqdProcess daqd({"--config", config, "--fast", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()}, {},
                   tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(120), 0) << daqd.output();
  fs::path log;
  for (const auto& e : fs::directory_iterator(tmp.path / "log"))
    if (e.path().extension() == ".lcmlog") log = e.path();
  ASSERT_FALSE(log.empty());
  DaqdProcess replay({"online", "--config", config, "--replay", log.string(), "--history", (tmp.path / "history.csv").string()},
                     {}, tmp.path / "online.txt", analyze_binary());
  ASSERT_EQ(replay.wait(120), 0) << replay.output();
  // The last history row of each sensor: name, t, samples, cases, converged, then value and sd per term.
  std::ifstream history(tmp.path / "history.csv");
  std::string line;
  std::getline(history, line);
  std::vector<std::string> header;
  for (std::stringstream h(line); std::getline(h, line, ',');) header.push_back(line);
  std::map<std::string, std::vector<std::string>> last;
  while (std::getline(history, line)) {
    std::vector<std::string> cells;
    for (std::stringstream r(line); std::getline(r, line, ',');) cells.push_back(line);
    cells.resize(header.size());   // another sensor's terms: empty cells (getline drops trailing ones)
    if (!cells[0].empty()) last[cells[0]] = cells;
  }
  for (const char* sensor : GetParam().sensors) {
    SCOPED_TRACE(sensor);
    const fs::path out = tmp.path / (std::string("char-") + sensor);
    DaqdProcess characterize({"characterize", "--log", log.string(), "--sensor", sensor, "--out", out.string()}, {},
                             tmp.path / (std::string("char-") + sensor + ".txt"), analyze_binary());
    ASSERT_EQ(characterize.wait(120), 0) << characterize.output();
    const model::ModelFile offline = model::read_model(out / "model.toml");
    ASSERT_EQ(last.count(sensor), 1u) << replay.output();
    const std::vector<std::string>& row = last[sensor];
    ASSERT_EQ(row.size(), header.size());
    EXPECT_EQ(row[4], "1") << "not converged at the end\n" << replay.output();
    int common = 0;
    for (std::size_t c = 5; c + 1 < header.size(); c += 2) {
      if (row[c].empty()) continue;   // another sensor's term
      const double value = std::stod(row[c]), sd = std::stod(row[c + 1]);
      EXPECT_EQ(std::isfinite(value), std::isfinite(sd)) << header[c];
      const auto it = std::find_if(offline.terms.begin(), offline.terms.end(),
                                   [&](const model::ModelTerm& t) { return t.term.to_string() == header[c]; });
      if (it == offline.terms.end() || !std::isfinite(value)) continue;
      ++common;
      ASSERT_TRUE(it->std.has_value()) << header[c];
      EXPECT_NEAR(value, it->coefficient, 3.0 * std::hypot(sd, *it->std)) << header[c] << "\n" << replay.output();
    }
    EXPECT_GE(common, 1) << "the scale factor at least\n" << replay.output() << characterize.output();
    // Both hold the same twists: one search (procedure::search_turns), and the live turns' sd by the
    // sandwich the batch's is (LiveSolver::turn_covariance).
    std::ifstream report_file(out / "report.md");
    const std::string report((std::istreambuf_iterator<char>(report_file)), std::istreambuf_iterator<char>());
    EXPECT_EQ(held_twists(sensor_block(replay.output(), sensor)), held_twists(report)) << replay.output() << report;
  }
  // Every live term, kept by the batch or not, within 4 of its sd of the simulator's truth (0 for
  // a term the truth lacks): the live model may carry more than the batch's, never what the plan
  // fakes (a shaker's remounts, seen through gravity times the vibration, look like cross terms).
  // The simulator's truth of the same bench and seed (one folder per sensor where there are several).
  DaqdProcess simulate({"simulate", "--bench", config, "--out", (tmp.path / "sim").string()}, {}, tmp.path / "sim.txt",
                       analyze_binary());
  ASSERT_EQ(simulate.wait(120), 0) << simulate.output();
  for (const char* sensor : GetParam().sensors) {
    SCOPED_TRACE(sensor);
    const fs::path own = tmp.path / "sim" / sensor / "truth.toml";
    const model::ModelFile truth = model::read_model(fs::exists(own) ? own : tmp.path / "sim" / "truth.toml");
    const std::vector<std::string>& row = last[sensor];
    for (std::size_t c = 5; c + 1 < header.size(); c += 2) {
      if (row[c].empty() || !std::isfinite(std::stod(row[c]))) continue;
      const double value = std::stod(row[c]), sd = std::stod(row[c + 1]);
      const double want = truth.coefficient(ident::parse_term(header[c])).value_or(0.0);
      EXPECT_NEAR(value, want, 4.0 * sd) << header[c] << "\n" << replay.output();
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Bench, OnlineReplay,
                         ::testing::Values(EveryBenchCase{"sim-rotation-table.toml", {"acc1", "fog1"}},
                                           EveryBenchCase{"sim-shaker.toml", {"acc-a", "acc-b"}},
                                           EveryBenchCase{"sim-thermal.toml", {"acc1"}},
                                           EveryBenchCase{"sim-tumble.toml", {"mems1"}},
                                           EveryBenchCase{"sim-gyro-thermal.toml", {"fog1"}},
                                           EveryBenchCase{"sim-imu-tumble.toml", {"ax", "ay", "az"}},
                                           EveryBenchCase{"sim-imu.toml", {"ax", "gx", "gz"}}),
                         [](const ::testing::TestParamInfo<EveryBenchCase>& info) { return bench_test_name(info.param.bench); });

TEST(OnlineLive, ShakerOnlyBenchMatchesTheSimulatorsTruth) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  // One mounting, four shaker cases, no table: the bias stays in the mounting's fit (no other
  // mounting supplies it) and the data determines it.
  TempDir tmp;
  const std::string config = source_path("tests/integration/configs/online-shaker.toml");
  const LiveRun run = run_live(tmp, config);
  const auto estimates = decoded<model_estimate_t>(run.received, "INERTIA_ESTIMATE_ACC1");
  ASSERT_GE(estimates.size(), 40u) << run.online_output;
  const model_estimate_t& last = estimates.back().second;
  EXPECT_TRUE(last.converged) << last.convergence << "\n" << run.online_output;
  const config::BenchConfig bench = config::load_bench_config(config);
  double planned_s = 0.0;
  for (const auto& c : bench.cases)
    for (const auto& p : c.phases) planned_s += p.duration_s;
  // Every planned sample, less the first rows of each case the noise model's A(q) needs.
  const auto planned = static_cast<std::int64_t>(std::llround(planned_s * bench.sample_rate_hz));
  EXPECT_EQ(last.samples_used, planned - static_cast<std::int64_t>(bench.cases.size()) * last.noise_ar_order) << run.online_output;
  for (std::size_t i = 1; i < estimates.size(); ++i) EXPECT_GE(estimates[i].second.samples_used, estimates[i - 1].second.samples_used);

  DaqdProcess simulate({"simulate", "--bench", config, "--out", (tmp.path / "sim").string()}, {}, tmp.path / "sim.txt",
                       analyze_binary());
  ASSERT_EQ(simulate.wait(120), 0) << simulate.output();
  const model::ModelFile truth = model::read_model(tmp.path / "sim" / "truth.toml");
  // The fused reference carries the monitors' uncalibrated scale errors (largest 1.2e-3) and
  // misalignments (<= 0.06 deg): a relative error of the reference up to ~1.5e-3 beside the sd.
  constexpr double reference_relative = 1.5e-3;
  for (const char* name : {"a_i", "1"}) {
    double sd = 0.0;
    const double live_value = coefficient(last, name, &sd);
    const double want = *truth.coefficient(ident::parse_term(name));
    EXPECT_NEAR(live_value, want, 4.0 * sd + reference_relative * std::abs(want)) << name << "\n" << run.online_output;
  }
  // Residual: at least the sensor's white noise.
  EXPECT_GT(std::sqrt(last.residual_variance), 0.9 * 0.86 * 1e-4);
}

// Beside a daemon that runs a simulated bench faster than real time, the samples carry the
// simulated clock, ahead of the host's: the closing summary says the latency was not measured
// instead of printing negative milliseconds.
TEST(OnlineLive, BesideAFastSimulatedRunTheLatencyIsNamedNotMeasured) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = source_path("config/sim-tumble.toml");
  const std::string url = private_lcm_url();
  DaqdProcess online({"online", "--config", config, "--lcm-url", url, "--publish-hz", "10"}, {}, tmp.path / "online.txt",
                     analyze_binary());
  ASSERT_TRUE(listening(online)) << online.output();
  DaqdProcess daqd({"--config", config, "--fast", "--lcm-url", url}, {}, tmp.path / "daqd.txt");
  ASSERT_EQ(daqd.wait(120), 0) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  online.signal(SIGTERM);
  ASSERT_EQ(online.wait(30), 0) << online.output();
  const std::string text = online.output();
  EXPECT_NE(text.find("sample-to-estimate latency not measured: samples' times ran up to"), std::string::npos) << text;
  EXPECT_EQ(text.find("latency p50 -"), std::string::npos) << text;
}

// An engineer starts the live analyzer beside a daemon that is already running: the first blocks
// come before the daemon's bench file (sent at start and every 10 s) and are counted, the case
// under way when the bench came is not estimated (its start marker went by), and the estimate
// begins at the next case's start. The joined stream is the daemon's log of sim-tumble from the
// middle of its first case, with its bench message moved to just before the second case starts.
TEST(OnlineReplay, AnAnalyzerThatJoinsARunningDaemonEstimatesFromTheNextCase) {
  INERTIA_REQUIRE_LCM_ROUTE();
  TempDir tmp;
  const std::string config = source_path("config/sim-tumble.toml");
  DaqdProcess record({"--config", config, "--fast", "--lcm-url", private_lcm_url(), "--log", (tmp.path / "log").string()}, {},
                     tmp.path / "record.txt");
  ASSERT_EQ(record.wait(120), 0) << record.output();
  const std::vector<LogEvent> events = read_log_dir(tmp.path / "log");
  std::vector<std::size_t> case_starts;
  std::optional<std::size_t> bench;
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (events[i].channel == "INERTIA_BENCH" && !bench) bench = i;
    if (events[i].channel != "INERTIA_EVENT") continue;
    plan_event_t ev;
    ASSERT_GE(ev.decode(events[i].data.data(), 0, static_cast<int>(events[i].data.size())), 0);
    if (ev.mark == plan_event_t::MARK_CASE_START) case_starts.push_back(i);
  }
  const config::BenchConfig bench_config = config::load_bench_config(config);
  ASSERT_TRUE(bench);
  ASSERT_EQ(case_starts.size(), bench_config.cases.size());
  ASSERT_GE(case_starts.size(), 3u);
  const fs::path joined = tmp.path / "joined.lcmlog";
  {
    lcm::LogFile out(joined.string(), "w");
    ASSERT_TRUE(out.good());
    const auto write = [&](const LogEvent& e) {
      lcm::LogEvent le{};
      le.timestamp = e.utime;
      le.channel = e.channel;
      le.datalen = static_cast<int32_t>(e.data.size());
      le.data = const_cast<std::uint8_t*>(e.data.data());
      out.writeEvent(&le);
    };
    const std::size_t from = (case_starts[0] + case_starts[1]) / 2;
    for (std::size_t i = from; i < events.size(); ++i) {
      if (i == case_starts[1]) write(events[*bench]);
      if (i != *bench) write(events[i]);
    }
  }
  DaqdProcess online({"online", "--config", config, "--replay", joined.string()}, {}, tmp.path / "online.txt", analyze_binary());
  ASSERT_EQ(online.wait(120), 0) << online.output();
  const std::string text = online.output();
  std::cout << "[ figures ] online --replay of the joined stream:\n" << text;
  EXPECT_NE(text.find("joined a running inertia-daqd"), std::string::npos) << text;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex(R"((\d+) fused rows, \d+ gap\(s\), \d+ exclusion\(s\), (\d+) block\(s\) before the bench)")))
      << text;
  // Every sample of the cases from the second on, and none of the first's.
  double after_first_s = 0.0;
  for (std::size_t c = 1; c < bench_config.cases.size(); ++c)
    for (const config::Phase& phase : bench_config.cases[c].phases) after_first_s += phase.duration_s;
  EXPECT_EQ(std::stol(m[1]), std::lround(after_first_s * bench_config.sample_rate_hz)) << text;
  EXPECT_GT(std::stol(m[2]), 0) << text;
}

TEST(OnlineLive, BadInputExitsTwoNamingIt) {
  TempDir tmp;
  DaqdProcess missing({"online", "--config", (tmp.path / "nope.toml").string()}, {}, tmp.path / "a.txt", analyze_binary());
  EXPECT_EQ(missing.wait(30), 2);
  EXPECT_NE(missing.output().find("nope.toml"), std::string::npos) << missing.output();
  DaqdProcess wrong_sensor({"online", "--config", source_path("tests/integration/configs/online-shaker.toml"),
                            "--model", "accX=" + source_path("tests/integration/configs/online-shaker.toml")},
                           {}, tmp.path / "b.txt", analyze_binary());
  EXPECT_EQ(wrong_sensor.wait(30), 2);
  EXPECT_NE(wrong_sensor.output().find("accX"), std::string::npos) << wrong_sensor.output();
  // A replay publishes nothing and reads to the log's end: --duration and --lcm-url would be ignored.
  const fs::path log = tmp.path / "empty.lcmlog";
  std::ofstream(log).put('\0');
  for (const char* option : {"--duration", "--lcm-url"}) {
    DaqdProcess replay({"online", "--config", source_path("tests/integration/configs/online-shaker.toml"), "--replay", log.string(), option,
                        option == std::string("--duration") ? "5" : private_lcm_url()},
                       {}, tmp.path / "c.txt", analyze_binary());
    EXPECT_EQ(replay.wait(30), 2) << option;
    EXPECT_NE(replay.output().find(std::string(option) + " excludes --replay"), std::string::npos) << replay.output();
  }
}

}  // namespace
}  // namespace inertia::daq::testing

namespace inertia::daq::testing {
namespace {

std::vector<std::uint8_t> encode_message(const auto& msg) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(msg.getEncodedSize()));
  msg.encode(out.data(), 0, static_cast<int>(out.size()));
  return out;
}

/// Whether an INERTIA_ANALYZER_STATUS counting `oversized` skipped oversized messages arrives
/// within 5 s (the analyzer publishes its status once a second).
bool status_counts_oversized(LcmCollector& live, std::int64_t oversized) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  std::size_t seen = 0;
  while (std::chrono::steady_clock::now() < until) {
    const auto received = live.take();
    for (; seen < received.size(); ++seen) {
      if (received[seen].channel != "INERTIA_ANALYZER_STATUS") continue;
      analyzer_status_t st;
      if (st.decode(received[seen].data.data(), 0, static_cast<int>(received[seen].data.size())) >= 0 &&
          st.skipped_oversized >= oversized)
        return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

TEST(OnlineLive, HostileMessagesAreCountedAndSkippedAndTheEstimateStaysUnmixed) {
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const std::string config = source_path("config/sim-paper-daq.toml");
  // A clean recording of the bench, and the analyzer's answer for it.
  DaqdProcess record({"--config", config, "--fast", "--lcm-url", private_lcm_url(), "--log", (tmp.path / "log").string()}, {},
                     tmp.path / "record.txt");
  ASSERT_EQ(record.wait(120), 0) << record.output();
  std::size_t files = 0;
  const std::vector<LogEvent> events = read_log_dir(tmp.path / "log", &files);
  ASSERT_EQ(files, 1u);
  fs::path log;
  for (const auto& e : fs::directory_iterator(tmp.path / "log")) log = e.path();
  DaqdProcess clean({"online", "--config", config, "--replay", log.string()}, {}, tmp.path / "clean.txt", analyze_binary());
  ASSERT_EQ(clean.wait(120), 0) << clean.output();

  // The same messages live, with every kind of bad message among them.
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  DaqdProcess online({"online", "--config", config, "--lcm-url", url, "--publish-hz", "10"}, {}, tmp.path / "online.txt",
                     analyze_binary());
  ASSERT_TRUE(listening(online)) << online.output();
  lcm::LCM out(url);
  ASSERT_TRUE(out.good());
  int sent_malformed = 0, sent_oversized = 0, sent_invalid = 0, sent_refused = 0;
  std::optional<sample_block_t> old_block;
  int accel_blocks = 0;
  for (const LogEvent& e : events) {
    out.publish(e.channel, e.data.data(), static_cast<unsigned>(e.data.size()));
    std::this_thread::sleep_for(std::chrono::microseconds(700));
    if (e.channel != "INERTIA_RAW_ACCEL" || ++accel_blocks % 40 != 0) continue;
    sample_block_t b;
    ASSERT_GE(b.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    // Garbage, and a message of another type (wrong fingerprint), on a RAW channel.
    const std::vector<std::uint8_t> garbage(173, 0xA5);
    out.publish("INERTIA_RAW_ACCEL", garbage.data(), static_cast<unsigned>(garbage.size()));
    plan_event_t other{};
    const auto wrong = encode_message(other);
    out.publish("INERTIA_RAW_ACCEL", wrong.data(), static_cast<unsigned>(wrong.size()));
    sent_malformed += 2;
    // One byte longer than the analyzer takes on a RAW channel (1 MiB, far beyond any sample
    // block). It arrives as a burst of UDP fragments that can fill the receiver's socket buffer:
    // nothing more is sent until the analyzer's status has counted it, so that a loaded machine
    // does not drop the data blocks behind it in the kernel (which would change the estimate, not
    // mix into it), whatever runs beside the test.
    const std::vector<std::uint8_t> huge((1u << 20) + 1, 1);
    out.publish("INERTIA_RAW_ACCEL", huge.data(), static_cast<unsigned>(huge.size()));
    ++sent_oversized;
    ASSERT_TRUE(status_counts_oversized(live, sent_oversized)) << "the analyzer never counted the oversized message\n"
                                                               << online.output();
    // A bitmap that does not match num_samples, and a NaN period.
    sample_block_t bad = b;
    bad.valid_bytes += 3;
    for (auto& v : bad.valid) v.resize(static_cast<std::size_t>(bad.valid_bytes), 0xff);
    const auto bad_bytes = encode_message(bad);
    out.publish("INERTIA_RAW_ACCEL", bad_bytes.data(), static_cast<unsigned>(bad_bytes.size()));
    sample_block_t nan_period = b;
    nan_period.sample_period_s = std::nan("");
    const auto nan_bytes = encode_message(nan_period);
    out.publish("INERTIA_RAW_ACCEL", nan_bytes.data(), static_cast<unsigned>(nan_bytes.size()));
    sent_invalid += 2;
    // An old block again (out of order, NaN-laden), a marker of a case the plan lacks, another bench.
    if (old_block) {
      sample_block_t again = *old_block;
      for (auto& v : again.values) std::fill(v.begin(), v.end(), std::nan(""));
      const auto again_bytes = encode_message(again);
      out.publish("INERTIA_RAW_ACCEL", again_bytes.data(), static_cast<unsigned>(again_bytes.size()));
      ++sent_refused;
    }
    old_block = b;
    plan_event_t unknown{};
    unknown.mark = plan_event_t::MARK_CASE_START;
    unknown.case_name = "no-such-case";
    const auto unknown_bytes = encode_message(unknown);
    out.publish("INERTIA_EVENT", unknown_bytes.data(), static_cast<unsigned>(unknown_bytes.size()));
    ++sent_refused;
    bench_config_t stranger{};
    stranger.bench_name = "another-bench";
    const auto stranger_bytes = encode_message(stranger);
    out.publish("INERTIA_BENCH", stranger_bytes.data(), static_cast<unsigned>(stranger_bytes.size()));
    ++sent_refused;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  online.signal(SIGTERM);
  ASSERT_EQ(online.wait(30), 0) << online.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  const auto received = live.take();
  const auto status = decoded<analyzer_status_t>(received, "INERTIA_ANALYZER_STATUS");
  ASSERT_FALSE(status.empty()) << online.output();
  const analyzer_status_t& s = status.back().second;
  ASSERT_GE(sent_malformed, 20);   // 13 rounds of hostile messages
  EXPECT_EQ(s.skipped_malformed, sent_malformed) << online.output();
  EXPECT_EQ(s.skipped_oversized, sent_oversized);
  EXPECT_EQ(s.skipped_invalid, sent_invalid);
  EXPECT_EQ(s.skipped_refused, sent_refused);
  EXPECT_GT(s.invalid_values, 0) << "the NaN-laden block's values were seen as invalid before it was refused";
  EXPECT_FALSE(s.notes.empty());

  // Unmixed: the live estimate equals the clean log's, every data block having arrived.
  EXPECT_EQ(s.queue_drops, 0);
  EXPECT_EQ(s.gaps, 0) << "a data block was lost on its way (the estimate then differs)\n" << online.output();
  const auto estimates = decoded<model_estimate_t>(received, "INERTIA_ESTIMATE_ACC1");
  ASSERT_FALSE(estimates.empty());
  const model_estimate_t& last = estimates.back().second;
  const std::string clean_out = clean.output();
  SCOPED_TRACE("the live analyzer's own output:\n" + online.output() + "\nthe replay's:\n" + clean_out);
  // Every data block arrived: the fusion's account of the stream (rows, gaps, exclusions) is the
  // replay's. A block lost on the way (a reference's, which the sensor's gap count does not see)
  // shows as an exclusion, and the estimate then differs by what those rows held.
  const auto fused = [](const std::string& output) {
    const std::size_t at = output.find("online: acc1: ");
    const std::size_t rows = at == std::string::npos ? at : output.find(" fused rows", at);
    return rows == std::string::npos ? std::string() : output.substr(at, output.find('\n', rows) - at);
  };
  ASSERT_FALSE(fused(clean_out).empty()) << clean_out;
  ASSERT_EQ(fused(online.output()), fused(clean_out)) << "a data block was lost on its way";
  for (std::int32_t j = 0; j < last.num_terms; ++j) {
    const std::string& term = last.terms[static_cast<std::size_t>(j)];
    const auto at = clean_out.find("\n  " + term + " ");
    ASSERT_NE(at, std::string::npos) << term << "\n" << clean_out;
    std::istringstream line(clean_out.substr(at + 3 + term.size()));
    double value = 0.0;
    line >> value;
    EXPECT_NEAR(last.values[static_cast<std::size_t>(j)], value, 1e-6 * std::abs(value) + 1e-3 * last.std_devs[static_cast<std::size_t>(j)])
        << term;
  }
}

}  // namespace
}  // namespace inertia::daq::testing
