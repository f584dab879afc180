// The test executive on the wire simulators: the real inertia-daqd on a backend =
// "real" bench whose controllers are the simulated ones (hal/wire_sim/bench_controllers.hpp)
// behind a real Modbus TCP server on loopback. The daemon runs the plan: every command is read
// back, settled and marked on INERTIA_EVENT (live and in the log) on the clock of the sample
// blocks; SIGTERM mid-phase puts every controller in its safe state within 100 ms, measured
// from the controllers' side; a controller that never confirms fails the phase and stops the
// plan safely; a plan beyond a register's limits is refused at load with file:line; and the
// operator's `inertia-daqd mark` turns into markers on a bench whose motion the daemon does not
// command.
#include <gtest/gtest.h>
#include <time.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "tests/integration/executive_bench.hpp"

namespace inertia::daq::testing {
namespace {

using Executive = RealBenchTest;

TEST_F(Executive, RunsThePlanOnTheControllersEachCommandReadBackSettledAndMarked) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kTableCase + kShakerCase + kThermalCase);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  const std::int64_t started = mono_now_ns();
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "60", "--log", (tmp.path / "log").string(), "--lcm-url", url}, {},
                   tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: finished", 40)) << daqd.output();
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::int64_t stopped = mono_now_ns();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  live.stop();
  const std::string out = daqd.output();

  // Markers, in the log: every case and phase started and ended, nothing failed or aborted.
  const auto events = read_log_dir(tmp.path / "log");
  const auto marks = decode_all<plan_event_t>(events, "INERTIA_EVENT");
  struct Expected { std::string case_name; int phases; };
  const std::vector<Expected> plan{{"table", 3}, {"shake", 1}, {"warm", 1}};
  std::size_t at = 0;
  auto next = [&](std::int8_t kind, const std::string& case_name, std::int32_t phase) -> const plan_event_t& {
    EXPECT_LT(at, marks.size());
    const plan_event_t& m = marks[std::min(at, marks.size() - 1)];
    EXPECT_EQ(m.mark, kind) << "marker " << at;
    EXPECT_EQ(m.case_name, case_name) << "marker " << at;
    EXPECT_EQ(m.phase_index, phase) << "marker " << at;
    ++at;
    return m;
  };
  std::vector<const plan_event_t*> phase_starts;
  std::int64_t previous = started;
  for (const Expected& c : plan) {
    const plan_event_t& cs = next(plan_event_t::MARK_CASE_START, c.case_name, -1);
    EXPECT_GE(cs.start_mono_ns, previous);
    for (int p = 0; p < c.phases; ++p) {
      const plan_event_t& ps = next(plan_event_t::MARK_PHASE_START, c.case_name, p);
      phase_starts.push_back(&ps);
      EXPECT_GE(ps.start_mono_ns, previous);
      const plan_event_t& pe = next(plan_event_t::MARK_PHASE_END, c.case_name, p);
      EXPECT_EQ(pe.start_mono_ns, ps.start_mono_ns);
      // Held for its duration, then ended when the next command went out.
      EXPECT_GE(pe.end_mono_ns - ps.start_mono_ns, ps.end_mono_ns - ps.start_mono_ns);
      EXPECT_LT(pe.end_mono_ns - ps.end_mono_ns, 100'000'000) << c.case_name << " phase " << p;
      previous = pe.end_mono_ns;
    }
    const plan_event_t& ce = next(plan_event_t::MARK_CASE_END, c.case_name, -1);
    EXPECT_EQ(ce.start_mono_ns, cs.start_mono_ns);
    EXPECT_LE(ce.end_mono_ns, stopped);
  }
  EXPECT_EQ(at, marks.size()) << "no other marker (no abort, no failed phase)";
  ASSERT_EQ(phase_starts.size(), 5u);
  EXPECT_EQ(phase_starts[1]->phase, "rotation");
  ASSERT_EQ(phase_starts[1]->setpoint_names.size(), 1u);
  EXPECT_EQ(phase_starts[1]->setpoint_names[0], "rate");
  EXPECT_NEAR(phase_starts[1]->setpoint_values[0], 45.0 * M_PI / 180.0, 1e-12);
  EXPECT_EQ(phase_starts[4]->kind, "thermal");

  // Each command confirmed by reading it back; settling judged where the bench file says.
  EXPECT_GE(count_of(out, "confirmed (read back"), 9u) << out;  // rate, rate 0, angle, run, profile, run, run 0, rate?, setpoint
  EXPECT_NE(out.find("table.rate_setpoint = 0.785398 rad/s confirmed (read back 0.785398 rad/s), ramped in"), std::string::npos) << out;
  EXPECT_NE(out.find("table settled (rate within 0.005 rad/s of 0.785398 rad/s for"), std::string::npos) << out;
  EXPECT_NE(out.find("table settled (status reporting settled"), std::string::npos) << out;
  EXPECT_NE(out.find("shaker.profile = 3 confirmed"), std::string::npos) << out;
  EXPECT_NE(out.find("shaker settled (status reporting running"), std::string::npos) << out;
  EXPECT_NE(out.find("thermal settled (temperature within 0.1 degC of 27 degC"), std::string::npos) << out;

  // The marker's start is when settling was confirmed: the controller's readings (its polls, in
  // the log) were within tolerance over settle_s before it, on the same clock.
  const auto table_rows = decode_all<sample_block_t>(events, "INERTIA_RAW_TABLE");
  ASSERT_FALSE(table_rows.empty());
  const int rate_ch = channel_index(table_rows[0], "rate");
  ASSERT_GE(rate_ch, 0);
  const std::int64_t rotation_start = phase_starts[1]->start_mono_ns;
  std::size_t checked = 0;
  for (const auto& b : table_rows)
    for (std::int32_t s = 0; s < b.num_samples; ++s) {
      const auto t = b.t0_mono_ns + static_cast<std::int64_t>(std::llround(s * b.sample_period_s * 1e9));
      if (t < rotation_start - 60'000'000 || t > rotation_start) continue;
      EXPECT_NEAR(b.values[static_cast<std::size_t>(rate_ch)][static_cast<std::size_t>(s)], 45.0 * M_PI / 180.0, 0.005);
      ++checked;
    }
  EXPECT_GE(checked, 2u);
  // Markers and sample blocks on CLOCK_MONOTONIC: each arrived on LCM shortly after its time.
  std::size_t live_marks = 0;
  for (const auto& r : live.take()) {
    if (r.channel == "INERTIA_EVENT") {
      plan_event_t m;
      ASSERT_GE(m.decode(r.data.data(), 0, static_cast<int>(r.data.size())), 0);
      EXPECT_GE(r.mono_ns, m.mono_ns);
      EXPECT_LT(r.mono_ns - m.mono_ns, 500'000'000);
      ++live_marks;
    } else if (r.channel == "INERTIA_RAW_TABLE") {
      sample_block_t b;
      ASSERT_GE(b.decode(r.data.data(), 0, static_cast<int>(r.data.size())), 0);
      EXPECT_GE(r.mono_ns, b.t0_mono_ns);
      EXPECT_LT(r.mono_ns - b.t0_mono_ns, 2'000'000'000);
    }
  }
  EXPECT_EQ(live_marks, marks.size());

  // After the plan, and again at SIGTERM: every controller in its safe state.
  const BenchControllerState end = controllers_->state();
  EXPECT_DOUBLE_EQ(end.table_rate_setpoint_rad_s, 0.0);
  EXPECT_FALSE(end.shaker_enable);
  EXPECT_DOUBLE_EQ(end.temperature_setpoint_degC, 25.0);
  EXPECT_NE(out.find("plan: finished: every case ran; disarmed: controllers in their safe state"), std::string::npos) << out;

  // Figures for the report: from the command (the previous marker) to the settled start of each phase.
  std::int64_t commanded = 0;
  for (const plan_event_t& m : marks) {
    if (m.mark == plan_event_t::MARK_PHASE_START)
      std::cout << "command to settled start: case " << m.case_name << " phase " << m.phase_index << " (" << m.phase
                << "): " << static_cast<double>(m.start_mono_ns - commanded) * 1e-6 << " ms\n";
    commanded = m.mono_ns;
  }
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);)
    if (line.find("settled (") != std::string::npos || line.find("confirmed") != std::string::npos) std::cout << line << "\n";
}

TEST_F(Executive, SigtermMidPhaseReachesTheSafeStateWithin100Ms) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // A warm-up that moves the thermal setpoint off its safe value, then a long rotation.
  const std::string long_turn =
      "\n[[case]]\nname = \"table\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
      "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nrate_deg_s = 60.0\nduration_s = 60.0\n";
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kThermalCase + long_turn);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "90", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // mid-phase
  const BenchControllerState before = controllers_->state();
  EXPECT_NEAR(before.table_rate_setpoint_rad_s, M_PI / 3.0, 1e-6);
  EXPECT_DOUBLE_EQ(before.temperature_setpoint_degC, 27.0);
  const std::int64_t sent = mono_now_ns();
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();

  // From the controllers' side: when each safe value was written (the server's write hook).
  const BenchControllerState after = controllers_->state();
  EXPECT_DOUBLE_EQ(after.table_rate_setpoint_rad_s, 0.0);
  EXPECT_FALSE(after.shaker_enable);
  EXPECT_DOUBLE_EQ(after.temperature_setpoint_degC, 25.0);
  std::int64_t reached = 0;
  for (int address : {reg::kTableRateSetpoint, reg::kShakerEnable, reg::kTemperatureSetpoint}) {
    const std::int64_t w = after.written_ns[static_cast<std::size_t>(address - reg::kHoldingStart)];
    EXPECT_GT(w, sent) << std::hex << address;
    reached = std::max(reached, w);
  }
  const double abort_ms = static_cast<double>(reached - sent) * 1e-6;
  std::cout << "SIGTERM to the last controller in its safe state (controller side): " << abort_ms << " ms\n";
  RecordProperty("abort_to_safe_state_us", static_cast<int>((reached - sent) / 1000));
  EXPECT_LT(abort_ms, 100.0) << out;

  EXPECT_NE(out.find("plan: abort (SIGTERM) during case table phase 0 (rotation); disarmed: controllers in their safe state"),
            std::string::npos)
      << out;
  const auto marks = decode_all<plan_event_t>(read_log_dir(tmp.path / "log"), "INERTIA_EVENT");
  ASSERT_FALSE(marks.empty());
  const plan_event_t& last = marks.back();
  EXPECT_EQ(last.mark, plan_event_t::MARK_ABORT);
  EXPECT_EQ(last.case_name, "table");
  EXPECT_EQ(last.phase_index, 0);
  EXPECT_GE(last.mono_ns, sent);
  EXPECT_LT(last.mono_ns - sent, 100'000'000);
}

TEST_F(Executive, AControllerThatNeverConfirmsFailsThePhaseAndThePlanStopsSafely) {
  INERTIA_REQUIRE_LCM_ROUTE();
  controllers_->update([](BenchControllerState& s) {
    // answers, never takes a rate (both words of the float32)
    s.ignore_writes = 3u << (reg::kTableRateSetpoint - reg::kHoldingStart);
    s.temperature_setpoint_degC = 40.0;                                       // off its safe value
  });
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kTableCase + kShakerCase);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "60", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: abort (phase failed", 30)) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the plan must not go on
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  // Why, on stderr (the journal line): what was written, what was read back.
  EXPECT_NE(out.find("plan: phase failed: case table phase 1 (rotation): table.rate_setpoint = 0.785398 rad/s: written as 0.4 rad/s "
                     "but read back 0 rad/s: the controller did not confirm the command; the plan stops"),
            std::string::npos)
      << out;
  const auto marks = decode_all<plan_event_t>(read_log_dir(tmp.path / "log"), "INERTIA_EVENT");
  std::vector<std::int8_t> kinds;
  for (const auto& m : marks) kinds.push_back(m.mark);
  // dwell ran (its rate 0 was already held), the rotation never started: failed, then the abort.
  EXPECT_EQ(kinds, (std::vector<std::int8_t>{plan_event_t::MARK_CASE_START, plan_event_t::MARK_PHASE_START, plan_event_t::MARK_PHASE_END,
                                             plan_event_t::MARK_PHASE_FAILED, plan_event_t::MARK_ABORT}));
  ASSERT_EQ(marks.size(), 5u);
  EXPECT_EQ(marks[3].phase_index, 1);
  EXPECT_EQ(marks[3].phase, "rotation");
  EXPECT_EQ(marks[4].case_name, "table");
  for (const auto& m : marks) EXPECT_NE(m.case_name, "shake") << "the plan stopped at the failure";
  // Stopped safely: the safe state went out (the thermal setpoint the plan never touched too).
  const BenchControllerState after = controllers_->state();
  EXPECT_FALSE(after.shaker_enable);
  EXPECT_DOUBLE_EQ(after.temperature_setpoint_degC, 25.0);
  EXPECT_NE(out.find("plan: abort (phase failed: table.rate_setpoint"), std::string::npos) << out;
}

TEST_F(Executive, AControllerThatNeverSettlesFailsThePhaseAtItsTimeout) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // The fixture takes the setpoint but its temperature hardly moves: never within tolerance.
  controllers_->update([](BenchControllerState& s) { s.thermal_time_constant_s = 1e6; });
  std::string devices = controllers(controllers_->port());
  const std::string thermal_timeout = "settle_timeout_s = 5.0\n[[modbus_device.register]]\nname = \"temperature\"";
  devices.replace(devices.find(thermal_timeout), 23, "settle_timeout_s = 0.5\n");
  const fs::path bench = write(bench_head("plan") + devices + kThermalCase + kTableCase);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "60", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: abort (phase failed", 30)) << daqd.output();
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("plan: phase failed: case warm phase 0 (thermal_step): thermal.setpoint = 27 degC confirmed, but not settled "
                     "(temperature within 0.1 degC of 27 degC for 0.10 s) within settle_timeout_s = 0.5 s; last reading of "
                     "temperature: 25 degC; the plan stops"),
            std::string::npos)
      << out;
  const auto marks = decode_all<plan_event_t>(read_log_dir(tmp.path / "log"), "INERTIA_EVENT");
  ASSERT_EQ(marks.size(), 3u);
  EXPECT_EQ(marks[0].mark, plan_event_t::MARK_CASE_START);
  EXPECT_EQ(marks[1].mark, plan_event_t::MARK_PHASE_FAILED);
  EXPECT_GE(marks[1].end_mono_ns - marks[1].start_mono_ns, 500'000'000) << "given up at the timeout, not before";
  EXPECT_EQ(marks[2].mark, plan_event_t::MARK_ABORT);
  EXPECT_DOUBLE_EQ(controllers_->state().temperature_setpoint_degC, 25.0);
}

TEST_F(Executive, AControllerFaultMidPhaseAbortsThePlan) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const std::string long_turn =
      "\n[[case]]\nname = \"table\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
      "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nrate_deg_s = 30.0\nduration_s = 60.0\n";
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + long_turn);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "90", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();
  const std::int64_t raised = mono_now_ns();
  controllers_->update([](BenchControllerState& s) { s.shaker_status |= reg::kShakerFault; });  // e.g. over-current
  ASSERT_TRUE(wait_for(daqd, "plan: abort (device fault: shaker.status = 0x2 (fault bits 0x2)) during case table phase 0 (rotation)", 10))
      << daqd.output();
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const auto marks = decode_all<plan_event_t>(read_log_dir(tmp.path / "log"), "INERTIA_EVENT");
  ASSERT_FALSE(marks.empty());
  EXPECT_EQ(marks.back().mark, plan_event_t::MARK_ABORT);
  // Seen at the next poll (20 ms) and the executive's next turn (5 ms).
  EXPECT_LT(marks.back().mono_ns - raised, 100'000'000);
  EXPECT_DOUBLE_EQ(controllers_->state().table_rate_setpoint_rad_s, 0.0);
}

TEST_F(Executive, APlanBeyondAControllersLimitsIsRefusedAtLoadWithFileAndLine) {
  const std::string text = bench_head("plan") + controllers(controllers_->port()) +
                           [] {
                             std::string c = kTableCase;
                             return c.replace(c.find("rate_deg_s = 45.0"), 17, "rate_deg_s = 250.0");
                           }();
  const fs::path bench = write(text);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "5", "--lcm-url", private_lcm_url()}, {}, tmp.path / "stderr.txt");
  EXPECT_EQ(daqd.wait(30), 2);
  const std::string out = daqd.output();
  EXPECT_NE(out.find(bench.string() + ":" + std::to_string(line_of(text, "rate_deg_s = 250.0")) +
                     ":14: case 'table': rate_deg_s = 250 asks the table_rate register to 4.36332 rad/s, beyond its limits [-3, 3 rad/s]"),
            std::string::npos)
      << out;
  EXPECT_EQ(controllers_->state().written_ns[reg::kTableRateSetpoint - reg::kHoldingStart], 0) << "nothing was written";
}

TEST_F(Executive, OperatorMarksBecomeMarkersAndAnOperatorStopPutsTheControllersInTheirSafeState) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // A bench whose motion the operator makes: only the thermal controller, its safe state enabled.
  controllers_->update([](BenchControllerState& s) { s.temperature_setpoint_degC = 35.0; });
  const std::string text = bench_head("operator") + controllers(controllers_->port()) + kTableCase + kThermalCase;
  const fs::path bench = write(text);
  const std::string url = private_lcm_url();
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--log", (tmp.path / "log").string(), "--lcm-url", url}, {},
                   tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases marked by the operator", 30)) << daqd.output();
  struct Mark {
    int status;
    std::string out;
    std::int64_t before_ns, after_ns;
  };
  int n = 0;
  auto mark = [&](std::vector<std::string> args) {
    args.insert(args.begin(), "mark");
    args.insert(args.end(), {"--socket", socket_path()});
    Mark m{};
    m.before_ns = mono_now_ns();
    DaqdProcess p(args, {}, tmp.path / ("mark" + std::to_string(n++) + ".txt"));
    m.status = p.wait(20);
    m.after_ns = mono_now_ns();
    m.out = p.output();
    return m;
  };
  const Mark dwell = mark({"--case", "table", "--phase", "dwell"});
  EXPECT_EQ(dwell.status, 0) << dwell.out;
  EXPECT_NE(dwell.out.find("inertia-daqd mark: case table started; case table phase 0 (dwell) started"), std::string::npos) << dwell.out;
  const Mark rotation = mark({"--case", "table", "--phase", "rotation"});
  EXPECT_EQ(rotation.status, 0) << rotation.out;
  const Mark unknown = mark({"--case", "nosuch"});
  EXPECT_EQ(unknown.status, 2) << unknown.out;
  EXPECT_NE(unknown.out.find("refused: no case 'nosuch' in the plan of bench exec-bench (cases: table, warm)"), std::string::npos)
      << unknown.out;
  const Mark warm = mark({"--case", "warm", "--phase", "thermal_step"});
  EXPECT_EQ(warm.status, 0) << warm.out;
  EXPECT_NE(warm.out.find("case table ended; case warm started; case warm phase 0 (thermal_step) started"), std::string::npos) << warm.out;
  const Mark stop = mark({"--stop"});
  EXPECT_EQ(stop.status, 0) << stop.out;
  EXPECT_NE(stop.out.find("inertia-daqd mark: stop received: every controller commanded to its safe state"), std::string::npos)
      << stop.out;
  EXPECT_NE(stop.out.find("inertia-daqd mark: controllers in their safe state"), std::string::npos) << stop.out;
  const Mark end = mark({"--end"});
  EXPECT_EQ(end.status, 2) << end.out;
  EXPECT_NE(end.out.find("refused: no case is running"), std::string::npos) << end.out;
  // The thermal controller went to its safe value on the stop.
  EXPECT_DOUBLE_EQ(controllers_->state().temperature_setpoint_degC, 25.0);
  EXPECT_GT(controllers_->state().written_ns[reg::kTemperatureSetpoint - reg::kHoldingStart], stop.before_ns);
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("plan: operator "), std::string::npos) << out;
  EXPECT_NE(out.find("command: mark from uid 0 (root), pid "), std::string::npos) << out;
  EXPECT_NE(out.find(": refused: no case 'nosuch' in the plan"), std::string::npos) << out;
  EXPECT_NE(out.find("plan: abort (operator stop by "), std::string::npos) << out;

  // The markers, stamped by the daemon when each request arrived.
  const auto marks = decode_all<plan_event_t>(read_log_dir(tmp.path / "log"), "INERTIA_EVENT");
  struct Expected { std::int8_t kind; std::string case_name; std::int32_t phase; const Mark* during; };
  const std::vector<Expected> expected{
      {plan_event_t::MARK_CASE_START, "table", -1, &dwell},  {plan_event_t::MARK_PHASE_START, "table", 0, &dwell},
      {plan_event_t::MARK_PHASE_END, "table", 0, &rotation}, {plan_event_t::MARK_PHASE_START, "table", 1, &rotation},
      {plan_event_t::MARK_PHASE_END, "table", 1, &warm},     {plan_event_t::MARK_CASE_END, "table", -1, &warm},
      {plan_event_t::MARK_CASE_START, "warm", -1, &warm},    {plan_event_t::MARK_PHASE_START, "warm", 0, &warm},
      {plan_event_t::MARK_ABORT, "warm", 0, &stop}};
  ASSERT_EQ(marks.size(), expected.size());
  for (std::size_t i = 0; i < marks.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(marks[i].mark, expected[i].kind);
    EXPECT_EQ(marks[i].case_name, expected[i].case_name);
    EXPECT_EQ(marks[i].phase_index, expected[i].phase);
    EXPECT_GE(marks[i].mono_ns, expected[i].during->before_ns);
    EXPECT_LE(marks[i].mono_ns, expected[i].during->after_ns);
  }
  EXPECT_EQ(marks[1].phase, "static");
  EXPECT_EQ(marks[3].phase, "rotation");
}

}  // namespace
}  // namespace inertia::daq::testing
