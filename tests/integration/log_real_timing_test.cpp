// The simulated bench with what real hardware does to time ([bench.sim_timing]: CAN
// receive stamps 200 us late on average, one-sided; the bench's sample clock 50 ppm fast against
// CLOCK_MONOTONIC; 0.1 % of the CAN frames lost). The daemon times each device by its own clock
// (numbered frames, daq/clock_fit.hpp) and a lost frame leaves exactly its samples invalid.
// Without loss, `characterize --log` of the paced run equals `characterize --dataset` of the
// simulator's own output within 3 combined sd; with loss, every lost frame is in the fusion's
// exclusions; either way the live analyzer beside the daemon takes the stream without a gap.
// A 16-bit frame counter whose adapter resets mid-run (the counter restarts at 0 after 50 ms of
// silence): the daemon opens a new clock segment there, and the log's model is the dataset's.
//
// A paced run simulates the devices' timing only while this host runs the simulator on time: a
// simulated device is a thread of the daemon, so on a host starved for longer than a clock-fit
// window the device itself is late and its stamps read as a slow sample clock
// (SimBench::behind_schedule_s). Such a run tests the host, not the daemon: the daemon says so,
// and the run is made again (at most three times).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "analyzer/model/model_file.hpp"
#include "tests/integration/daqd_harness.hpp"
#include "tests/support/files.hpp"

namespace inertia::daq::testing {
namespace {

using inertia::testing::analyze_binary;
using inertia::testing::text_of;

int run_command(const std::string& command, const fs::path& output) {
  const int st = std::system((command + " > " + output.string() + " 2>&1").c_str());
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

struct TimingCase {
  std::string name;
  double frame_loss = 0.0;
  std::string timing;                 // more [bench.sim_timing] keys
  std::vector<std::string> faults;    // --fault SPEC
};

class RealStyleTiming : public ::testing::TestWithParam<TimingCase> {};

TEST_P(RealStyleTiming, LogAgainstTheSimulatorsOwnDataset) {
  const double frame_loss = GetParam().frame_loss;
  INERTIA_REQUIRE_LCM_ROUTE();
  TempDir tmp;
  const fs::path config = tmp.path / "bench.toml";
  {
    std::ofstream out(config);
    out << text_of(source_path("config/sim-paper-daq.toml"))
        << "\n[bench.sim_timing]\njitter_us = 200.0\nclock_ppm = 50.0\nframe_loss = " << frame_loss << "\n" << GetParam().timing;
  }
  // The paced run, with the live analyzer beside the daemon as an engineer runs it: it must take
  // the real-style stream without a gap or a refused block.
  constexpr int kAttempts = 3;
  fs::path run;
  std::string live, daqd_out;
  for (int attempt = 1;; ++attempt) {
    run = tmp.path / ("run" + std::to_string(attempt));
    fs::create_directories(run);
    const std::string url = private_lcm_url();
    DaqdProcess online({"online", "--config", config.string(), "--publish-hz", "10", "--lcm-url", url}, {}, run / "online.txt",
                       analyze_binary());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    std::vector<std::string> daqd_args{"--config", config.string(), "--log", (run / "log").string(), "--lcm-url", url};
    for (const std::string& f : GetParam().faults) daqd_args.insert(daqd_args.end(), {"--fault", f});
    DaqdProcess daqd(daqd_args, {}, run / "daqd.txt");
    ASSERT_EQ(daqd.wait(120.0), 0) << daqd.output();
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    online.signal(SIGINT);
    ASSERT_EQ(online.wait(30.0), 0) << online.output();
    live = online.output();
    daqd_out = daqd.output();
    const std::optional<double> behind_ms = sim_schedule_lag_ms(daqd_out);
    ASSERT_TRUE(behind_ms) << daqd_out;
    std::cout << "[ figures ] attempt " << attempt << ": the simulator at most " << *behind_ms << " ms behind its schedule\n";
    if (daqd_out.find("could not run the simulated devices on time") == std::string::npos) break;
    ASSERT_LT(attempt, kAttempts) << "this host could not pace the simulated bench on " << kAttempts
                                  << " attempts: the run would test the host's load, not the daemon\n"
                                  << daqd_out;
  }
  std::cout << "[ figures ] online: " << live.substr(live.find("online: received")) << "\n";
  EXPECT_NE(live.find("skipped 0 malformed, 0 oversized, 0 invalid, 0 refused; 0 queue drop(s)"), std::string::npos) << live;
  if (GetParam().faults.empty()) {
    EXPECT_NE(live.find(" 0 gap(s)"), std::string::npos) << live;
  } else {
    // The reset's silence, and nothing else: one gap of at least 50 samples (50 ms at the bench's
    // 1 kHz). The frames after the reset are numbered on from the first one's receive stamp
    // (hal FrameCounter), so the gap also holds whatever delayed that frame on this host.
    EXPECT_NE(live.find(" 1 gap(s)"), std::string::npos) << live;
    std::smatch missing;
    ASSERT_TRUE(std::regex_search(live, missing, std::regex(R"(gap: accel missing (\d+) sample\(s\))"))) << live;
    std::cout << "[ figures ] the reset's gap as numbered: " << missing[1] << " samples\n";
    EXPECT_GE(std::stol(missing[1]), 50) << live;
  }
  EXPECT_EQ(live.find("overlap"), std::string::npos) << live;
  std::smatch lost_match;
  ASSERT_TRUE(std::regex_search(daqd_out, lost_match, std::regex(R"((\d+) CAN frame\(s\) lost on purpose)"))) << daqd_out;
  const long frames_lost = std::stol(lost_match[1]);
  std::vector<fs::path> logs;
  for (const auto& e : fs::directory_iterator(run / "log")) logs.push_back(e.path());
  ASSERT_EQ(logs.size(), 1u);

  ASSERT_EQ(run_command(analyze_binary() + " simulate --bench " + config.string() + " --out " + (tmp.path / "sim").string(),
                        tmp.path / "simulate.txt"),
            0)
      << text_of(tmp.path / "simulate.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --dataset " + (tmp.path / "sim").string() + " --out " +
                            (tmp.path / "exact").string(),
                        tmp.path / "exact.txt"),
            0)
      << text_of(tmp.path / "exact.txt");
  ASSERT_EQ(run_command(analyze_binary() + " characterize --log " + logs[0].string() + " --out " + (tmp.path / "out").string(),
                        tmp.path / "characterize.txt"),
            0)
      << text_of(tmp.path / "characterize.txt");
  const std::string out = text_of(tmp.path / "characterize.txt");
  std::cout << "[ figures ] " << frames_lost << " CAN frames lost\n" << out;

  // Every lost frame is an excluded sample of the sensor's output (its row), no more.
  long excluded = 0;
  const std::regex invalid(R"(case \S+: (\d+) sample\(s\) excluded: accel\.acc1 invalid)");
  for (std::sregex_iterator it(out.begin(), out.end(), invalid), end; it != end; ++it) excluded += std::stol((*it)[1]);
  EXPECT_EQ(excluded, frames_lost) << out;
  if (!GetParam().faults.empty()) {
    EXPECT_NE(daqd_out.find("clock segments 2"), std::string::npos) << "the reset opened a new clock segment\n" << daqd_out;
  }
  EXPECT_EQ(out.find("overlapping"), std::string::npos);

  const model::ModelFile fused = model::read_model(tmp.path / "out" / "model.toml");
  const model::ModelFile exact = model::read_model(tmp.path / "exact" / "model.toml");
  int common = 0;
  for (const model::ModelTerm& t : exact.terms) {
    const std::string name = t.term.to_string();
    const auto it = std::find_if(fused.terms.begin(), fused.terms.end(),
                                 [&](const model::ModelTerm& f) { return f.term.to_string() == name; });
    if (it == fused.terms.end() || !t.std || !it->std) continue;
    ++common;
    const double combined = std::hypot(*t.std, *it->std);
    std::cout << "[ figures ] " << name << ": log " << it->coefficient << " +- " << *it->std << ", dataset " << t.coefficient
              << " +- " << *t.std << ", z " << (it->coefficient - t.coefficient) / combined << "\n";
    // With lost frames the fusion goes on through each hole and only the output is cut there;
    // the pieces are one case of the plan (one weight, and a phase cut by a hole is one offset
    // cluster), and pieces shorter than 0.1 s are dropped (about 2 % of the rows here).
    EXPECT_NEAR(it->coefficient, t.coefficient, 3.0 * combined) << name;
  }
  EXPECT_GE(common, 2);
}

INSTANTIATE_TEST_SUITE_P(JitterDriftAndLoss, RealStyleTiming,
                         ::testing::Values(TimingCase{"NoFrameLost", 0.0, "", {}}, TimingCase{"OneFrameInAThousandLost", 0.001, "", {}},
                                           TimingCase{"SixteenBitCounterReset", 0.0, "counter_bits = 16\n", {"can-reset@5.3+0.05"}}),
                         [](const ::testing::TestParamInfo<TimingCase>& info) { return info.param.name; });

}  // namespace
}  // namespace inertia::daq::testing
