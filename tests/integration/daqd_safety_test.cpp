// Safety around real machinery, on the wire simulators (the real inertia-daqd, the simulated
// controllers behind a real Modbus TCP server on loopback, real processes and signals):
// - nothing moves until an operator arms the plan, and an arm is refused while a controller is
//   faulted;
// - a daemon killed mid-rotation leaves the table at rest within the controller's heartbeat
//   timeout plus its deceleration, and the restarted daemon says how the last run ended and
//   commands nothing until armed;
// - a safe state that cannot be written is retried until the link returns, a fault for as long
//   as it lasts; an operator stop is acknowledged at once and confirmed after;
// - a slow controller is its device's fault, never a reason for the watchdog to restart the daemon.
#include <gtest/gtest.h>

#include <lcm/lcm-cpp.hpp>

#include <cmath>
#include <fstream>
#include <iostream>
#include <regex>

#include "inertia/daq_status_t.hpp"
#include "inertia/plan_command_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "daq/command_socket.hpp"
#include "tests/integration/executive_bench.hpp"

namespace inertia::daq::testing {
namespace {

/// A rotation long enough to be interrupted: 90 deg/s for a minute.
const std::string kLongTurn =
    "\n[[case]]\nname = \"table\"\nkind = \"rotation_table\"\nm_ec = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
    "[[case.phase]]\nkind = \"rotation\"\naxis = [0.0, 0.0, 1.0]\nrate_deg_s = 90.0\nduration_s = 60.0\n";

class Safety : public RealBenchTest {
 protected:
  /// `inertia-daqd VERB ARGS... --socket PATH`: its exit status and output.
  std::pair<int, std::string> command(std::vector<std::string> args) {
    args.insert(args.end(), {"--socket", socket_path()});
    DaqdProcess p(args, {}, dir_.path / ("command" + std::to_string(commands_++) + ".txt"));
    const int status = p.wait(30);
    return {status, p.output()};
  }
  /// The INERTIA_STATUS messages received, with their receipt time.
  static std::vector<std::pair<std::int64_t, daq_status_t>> statuses(LcmCollector& live) {
    std::vector<std::pair<std::int64_t, daq_status_t>> out;
    for (const auto& r : live.take()) {
      if (r.channel != "INERTIA_STATUS") continue;
      daq_status_t st;
      if (st.decode(r.data.data(), 0, static_cast<int>(r.data.size())) >= 0) out.emplace_back(r.mono_ns, st);
    }
    return out;
  }
  static bool has_fault(const daq_status_t& st, const std::string& fault) {
    return std::find(st.faults.begin(), st.faults.end(), fault) != st.faults.end();
  }
  static std::size_t markers(LcmCollector& live, std::int8_t kind) {
    std::size_t n = 0;
    for (const auto& r : live.take()) {
      if (r.channel != "INERTIA_EVENT") continue;
      plan_event_t m;
      if (m.decode(r.data.data(), 0, static_cast<int>(r.data.size())) >= 0 && m.mark == kind) ++n;
    }
    return n;
  }

  int commands_ = 0;
};

TEST_F(Safety, NothingMovesUntilAnOperatorArmsAndTheArmRunsThePlanOnce) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kTableCase);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--state-dir", tmp.path.string(), "--lcm-url", url}, {},
                   tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "the plan waits for an operator's arm (inertia-daqd arm)", 20)) << daqd.output();
  // Started, and for a while: every controller held at its safe value, nothing commanded, no case.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const BenchControllerState idle = controllers_->state();
  EXPECT_DOUBLE_EQ(idle.table_rate_setpoint_rad_s, 0.0);
  EXPECT_DOUBLE_EQ(idle.table_rate_rad_s, 0.0);
  EXPECT_FALSE(idle.table_position_mode);
  EXPECT_FALSE(idle.shaker_enable);
  EXPECT_DOUBLE_EQ(idle.temperature_setpoint_degC, 25.0);
  EXPECT_EQ(idle.written_ns[reg::kTableAngleSetpoint - reg::kHoldingStart], 0) << "no angle was commanded";
  EXPECT_EQ(idle.written_ns[reg::kShakerProfile - reg::kHoldingStart], 0) << "no profile was loaded";
  EXPECT_EQ(markers(live, plan_event_t::MARK_CASE_START), 0u);
  EXPECT_GT(idle.heartbeat_ns, 0) << "the daemon's heartbeat reaches the controllers";
  EXPECT_FALSE(idle.comm_lost);

  const auto [status, out] = command({"arm"});
  EXPECT_EQ(status, 0) << out;
  EXPECT_NE(out.find("inertia-daqd arm: armed by "), std::string::npos) << out;
  EXPECT_NE(out.find(": the plan of bench exec-bench starts now (1 cases)"), std::string::npos) << out;
  ASSERT_TRUE(wait_for(daqd, "plan: finished: every case ran; disarmed: controllers in their safe state", 30)) << daqd.output();
  EXPECT_EQ(markers(live, plan_event_t::MARK_CASE_START), 1u);
  EXPECT_EQ(markers(live, plan_event_t::MARK_CASE_END), 1u);
  // Once: the plan does not start again by itself.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(markers(live, plan_event_t::MARK_CASE_START), 1u);
  const std::int64_t before_stop = mono_now_ns();
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  EXPECT_NE(daqd.output().find("plan: started disarmed; found table.rate = 0 rad/s"), std::string::npos) << daqd.output();
  (void)before_stop;
  // The run record says this run ended by itself.
  std::ifstream record(tmp.path / "inertia-daqd.run");
  std::stringstream text;
  text << record.rdbuf();
  EXPECT_NE(text.str().find("ended = true"), std::string::npos) << text.str();
}

TEST_F(Safety, AnArmIsRefusedWithTheReasonWhileAControllerIsFaultedAndOnABenchTheOperatorMoves) {
  INERTIA_REQUIRE_LCM_ROUTE();
  controllers_->update([](BenchControllerState& s) { s.shaker_status |= reg::kShakerFault; });
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kTableCase);
  const std::string url = private_lcm_url();
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--lcm-url", url}, {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "the plan waits for an operator's arm", 20)) << daqd.output();
  auto [status, out] = command({"arm"});
  EXPECT_EQ(status, 2) << out;
  EXPECT_NE(out.find("inertia-daqd arm: refused: arm refused: device fault: shaker.status = 0x2 (fault bits 0x2)"), std::string::npos)
      << out;
  // The fault cleared, the arm goes through.
  controllers_->update([](BenchControllerState& s) { s.shaker_status = 0; });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::tie(status, out) = command({"arm"});
  EXPECT_EQ(status, 0) << out;
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  EXPECT_NE(daqd.output().find("command: arm from uid 0 (root), pid "), std::string::npos) << daqd.output();

  // A bench its operator moves has nothing to arm, and says why.
  const fs::path operated = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  DaqdProcess manual({"--config", operated.string(), "--command-socket", socket_path(), "--duration", "60", "--lcm-url", url}, {}, tmp.path / "manual.txt");
  ASSERT_TRUE(wait_for(manual, "phases are marked by the operator", 20)) << manual.output();
  std::tie(status, out) = command({"arm"});
  EXPECT_EQ(status, 2) << out;
  EXPECT_NE(out.find("is moved by its operator (executive = \"operator\"): the daemon commands no motion, so there is nothing to arm"),
            std::string::npos)
      << out;
  manual.signal(SIGTERM);
  ASSERT_EQ(manual.wait(20), 0) << manual.output();
  // --arm on such a bench is bad input.
  DaqdProcess refused({"--config", operated.string(), "--command-socket", socket_path(), "--arm", "--duration", "5", "--lcm-url", url}, {}, tmp.path / "refused.txt");
  EXPECT_EQ(refused.wait(20), 2);
  EXPECT_NE(refused.output().find("option --arm: bench exec-bench is moved by its operator"), std::string::npos) << refused.output();
}

TEST_F(Safety, ADaemonKilledMidRotationLeavesTheTableAtRestAndTheRestartCommandsNothingUntilArmed) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kLongTurn);
  const std::string url = private_lcm_url();
  TempDir tmp;
  const std::vector<std::string> args{"--config", bench.string(), "--command-socket", socket_path(), "--duration", "90",
                                      "--state-dir", tmp.path.string(), "--lcm-url", url};
  std::vector<std::string> armed = args;
  armed.emplace_back("--arm");
  DaqdProcess daqd(armed, {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const BenchControllerState turning = controllers_->state();
  const double rate = M_PI / 2.0;
  ASSERT_NEAR(turning.table_rate_rad_s, rate, 1e-3);

  const std::int64_t killed = mono_now_ns();
  daqd.signal(SIGKILL);
  EXPECT_EQ(daqd.wait(10), 128 + SIGKILL);
  // The controller's communication-loss action, from its side: tripped within its timeout of the
  // last heartbeat (which came before the kill), then at rest after its deceleration.
  std::int64_t at_rest = 0;
  BenchControllerState s;
  while (mono_now_ns() - killed < 10'000'000'000) {
    s = controllers_->state();
    if (s.comm_lost && s.table_rate_rad_s == 0.0) {
      at_rest = mono_now_ns();
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_GT(at_rest, 0) << "the table never stopped";
  const double deceleration_s = rate / moving_controllers().table_max_accel_rad_s2;
  const double tick_s = 0.02;   // the simulated controllers' physics step (ModbusServerOptions::tick_ms)
  const double to_rest_s = static_cast<double>(at_rest - killed) * 1e-9;
  std::cout << "SIGKILL to the table at rest (controller side): " << to_rest_s << " s; timeout " << kHeartbeatTimeoutS
            << " s + deceleration " << deceleration_s << " s\n";
  EXPECT_LE(to_rest_s, kHeartbeatTimeoutS + deceleration_s + 2 * tick_s);
  EXPECT_GE(static_cast<double>(s.comm_lost_ns - killed) * 1e-9, kHeartbeatTimeoutS - 0.1 - tick_s)
      << "tripped by the silence, not before it";
  EXPECT_FALSE(s.shaker_enable);

  // The restart: disarmed, says how the previous run ended, commands nothing but the safe state.
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  DaqdProcess again(args, {}, tmp.path / "again.txt");
  ASSERT_TRUE(wait_for(again, "the plan waits for an operator's arm", 20)) << again.output();
  const std::string out = again.output();
  EXPECT_NE(out.find("did not end: it was killed or crashed after"), std::string::npos) << out;
  EXPECT_NE(out.find("when it was ARMED: case table, phase 0 (rotation) commanded; this run starts disarmed"), std::string::npos) << out;
  EXPECT_NE(out.find("found table.rate = 0 rad/s"), std::string::npos) << out;
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const BenchControllerState after = controllers_->state();
  EXPECT_DOUBLE_EQ(after.table_rate_setpoint_rad_s, 0.0);
  EXPECT_DOUBLE_EQ(after.table_rate_rad_s, 0.0);
  EXPECT_FALSE(after.table_position_mode);
  EXPECT_FALSE(after.shaker_enable);
  EXPECT_FALSE(after.comm_lost) << "the new daemon's heartbeat reaches the controllers";
  EXPECT_EQ(markers(live, plan_event_t::MARK_CASE_START), 0u);
  again.signal(SIGTERM);
  ASSERT_EQ(again.wait(20), 0) << again.output();
}

TEST_F(Safety, AHungDaemonsHeartbeatStopsTheTableAndOnWakingItAbortsThePlan) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kLongTurn);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "90", "--lcm-url", private_lcm_url()}, {},
                   tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();
  ASSERT_NEAR(controllers_->state().table_rate_rad_s, M_PI / 2.0, 1e-3);
  // Every thread of the daemon stops at once, as in a hang: its heartbeat stops with them.
  const std::int64_t hung = mono_now_ns();
  daqd.signal(SIGSTOP);
  BenchControllerState s;
  while (mono_now_ns() - hung < 5'000'000'000) {
    s = controllers_->state();
    if (s.comm_lost && s.table_rate_rad_s == 0.0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_TRUE(s.comm_lost);
  EXPECT_DOUBLE_EQ(s.table_rate_rad_s, 0.0);
  std::cout << "daemon stopped (SIGSTOP) to the controller's trip: " << static_cast<double>(s.comm_lost_ns - hung) * 1e-9 << " s\n";
  daqd.signal(SIGCONT);
  // Awake, it reads the controller's trip as a fault: the plan aborts and disarms, never carries on.
  ASSERT_TRUE(wait_for(daqd, "plan: abort (device fault: ", 10)) << daqd.output();
  // The reason names the trip; a write the trip cut off is named in it too ("(last write: ...)"),
  // which depends on where the daemon stopped, so the two halves are found on their own.
  const std::string out = daqd.output();
  const std::size_t reason = out.find("the controller has stopped its machine");
  ASSERT_NE(reason, std::string::npos) << out;
  EXPECT_NE(out.find(") during case table phase 0 (rotation); disarmed", reason), std::string::npos) << out;
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  EXPECT_DOUBLE_EQ(controllers_->state().table_rate_setpoint_rad_s, 0.0);
}

TEST_F(Safety, ASafeStateCutOffByTheLinkIsRetriedAndConfirmedWithinASecondOfItsReturnAFaultMeanwhile) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // The controllers' own watchdog off: what brings the table to rest here is the daemon's retry.
  controllers_->update([](BenchControllerState& s) { s.heartbeat_timeout_s = 0.0; });
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kLongTurn);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "90", "--lcm-url", url}, {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();
  constexpr double kCutS = 12.0;   // longer than the journal's repeat: the fault is said twice
  const std::int64_t cut = mono_now_ns();
  controllers_->stop();   // the link is gone: the plan aborts, its safe state cannot be written
  ASSERT_TRUE(wait_for(daqd, "plan: SAFE STATE NOT CONFIRMED on device 'table'", 5)) << daqd.output();
  std::this_thread::sleep_for(std::chrono::duration<double>(kCutS - static_cast<double>(mono_now_ns() - cut) * 1e-9));
  EXPECT_NEAR(controllers_->state().table_rate_setpoint_rad_s, M_PI / 2.0, 1e-6) << "the controller kept its rate meanwhile";
  std::string why;
  const std::int64_t back = mono_now_ns();
  ASSERT_TRUE(controllers_->restart(&why)) << why;
  ASSERT_TRUE(wait_for(daqd, "plan: safe state confirmed on device 'table'", 5)) << daqd.output();
  const BenchControllerState after = controllers_->state();
  EXPECT_DOUBLE_EQ(after.table_rate_setpoint_rad_s, 0.0);
  const double confirmed_s = static_cast<double>(after.written_ns[reg::kTableRateSetpoint - reg::kHoldingStart] - back) * 1e-9;
  std::cout << "link back to the safe state written (controller side): " << confirmed_s << " s\n";
  EXPECT_GT(confirmed_s, 0.0);
  EXPECT_LT(confirmed_s, 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  // The three devices share the server: whichever poll sees the cut first names its controller.
  EXPECT_TRUE(std::regex_search(out, std::regex(R"(plan: abort \(device fault: controller (table|shaker|thermal) link down\) during )"
                                                 R"(case table phase 0 \(rotation\))")))
      << out;
  EXPECT_GE(count_of(out, "plan: SAFE STATE NOT CONFIRMED on device 'table'"), 2u) << out;
  // INERTIA_STATUS: the fault on every status from a second after the cut to the link's return,
  // and gone a second after the confirmation.
  std::size_t during = 0, after_fault = 0;
  for (const auto& [t, st] : statuses(live)) {
    if (t > cut + 1'500'000'000 && t < back) {
      EXPECT_TRUE(has_fault(st, "safe-state-unconfirmed:table")) << "status at " << static_cast<double>(t - cut) * 1e-9 << " s";
      ++during;
    }
    if (t > back + 2'000'000'000) {
      EXPECT_FALSE(has_fault(st, "safe-state-unconfirmed:table"));
      ++after_fault;
    }
  }
  EXPECT_GE(during, 9u);
  EXPECT_GE(after_fault, 1u);
}

TEST_F(Safety, AnOperatorStopIsAcknowledgedAtOnceEveryControllerCommandedThenConfirmed) {
  INERTIA_REQUIRE_LCM_ROUTE();
  controllers_->update([](BenchControllerState& s) { s.temperature_setpoint_degC = 35.0; });
  const fs::path bench = write(bench_head("plan") + controllers(controllers_->port()) + kLongTurn);
  const std::string url = private_lcm_url();
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--arm", "--duration", "90", "--lcm-url", url}, {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: case table phase 0 (rotation) started", 30)) << daqd.output();

  // The operator's stop, from this process, as `inertia-daqd mark --stop` sends it.
  std::string why;
  auto client = CommandClient::connect(socket_path(), &why);
  ASSERT_NE(client, nullptr) << why;
  plan_command_t stop{};
  stop.id = 1;
  stop.sender = "safety-test";
  stop.command = plan_command_t::COMMAND_STOP;
  stop.status = plan_command_t::STATUS_REQUEST;
  const std::int64_t sent = mono_now_ns();
  ASSERT_TRUE(client->send(stop, &why)) << why;
  const auto ack = client->receive(5.0, &why);
  const std::int64_t acked_at = mono_now_ns();
  ASSERT_TRUE(ack) << why;
  const auto done = client->receive(10.0, &why);
  const std::int64_t done_at = mono_now_ns();
  ASSERT_TRUE(done) << why;
  EXPECT_EQ(ack->status, plan_command_t::STATUS_ACCEPTED);
  EXPECT_EQ(done->status, plan_command_t::STATUS_DONE);
  EXPECT_NE(done->detail.find("controllers in their safe state"), std::string::npos) << done->detail;
  const BenchControllerState after = controllers_->state();
  std::int64_t commanded = 0;
  for (int address : {reg::kTableRateSetpoint, reg::kShakerEnable, reg::kTemperatureSetpoint}) {
    const std::int64_t w = after.written_ns[static_cast<std::size_t>(address - reg::kHoldingStart)];
    EXPECT_GT(w, sent) << std::hex << address;
    commanded = std::max(commanded, w);
  }
  const double ack_ms = static_cast<double>(acked_at - sent) * 1e-6;
  const double commanded_ms = static_cast<double>(commanded - sent) * 1e-6;
  std::cout << "operator stop: acknowledged " << ack_ms << " ms, every controller commanded (controller side) " << commanded_ms
            << " ms, confirmed " << static_cast<double>(done_at - sent) * 1e-6 << " ms after it was sent\n";
  EXPECT_LT(ack_ms, 50.0);
  EXPECT_LT(commanded_ms, 100.0);
  EXPECT_DOUBLE_EQ(after.temperature_setpoint_degC, 25.0);
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
}

TEST_F(Safety, ASafeStateTheControllerDoesNotTakeIsAFaultRepeatedAndTheStopSaysSo) {
  INERTIA_REQUIRE_LCM_ROUTE();
  // The chamber answers its setpoint writes but keeps 40 degC: its safe 25 degC is never read back.
  controllers_->update([](BenchControllerState& s) {
    s.temperature_setpoint_degC = 40.0;
    s.ignore_writes = 1u << (reg::kTemperatureSetpoint - reg::kHoldingStart);
  });
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kThermalCase);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--lcm-url", url}, {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "plan: SAFE STATE NOT CONFIRMED on device 'thermal': setpoint: not confirmed: the register read back holds another value (reads 40)", 20))
      << daqd.output();
  const auto [status, out] = command({"mark", "--stop"});
  EXPECT_EQ(status, 1) << out;
  EXPECT_NE(out.find("inertia-daqd mark: stop received: every controller commanded to its safe state"), std::string::npos) << out;
  EXPECT_NE(out.find("SAFE STATE NOT CONFIRMED on every controller"), std::string::npos) << out;
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  bool seen = false;
  for (const auto& [t, st] : statuses(live)) seen = seen || has_fault(st, "safe-state-unconfirmed:thermal");
  EXPECT_TRUE(seen);
  // The controller takes writes again: the next retry confirms it.
  const std::int64_t fixed = mono_now_ns();
  controllers_->update([](BenchControllerState& s) { s.ignore_writes = 0; });
  ASSERT_TRUE(wait_for(daqd, "plan: safe state confirmed on device 'thermal'", 5)) << daqd.output();
  EXPECT_DOUBLE_EQ(controllers_->state().temperature_setpoint_degC, 25.0);
  EXPECT_LT(controllers_->state().written_ns[reg::kTemperatureSetpoint - reg::kHoldingStart] - fixed,
            static_cast<std::int64_t>(2 * ControllerPort::kSafeRetryS * 1e9) + 100'000'000);
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
}

TEST_F(Safety, ASlowControllerIsItsDevicesFaultTheWatchdogGoesOn) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kThermalCase);
  TempDir tmp;
  NotifySocket notify(tmp.path / "notify.sock");
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--lcm-url", private_lcm_url()},
                   {"NOTIFY_SOCKET=" + notify.path().string(), "WATCHDOG_USEC=400000"}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases are marked by the operator", 20)) << daqd.output();
  controllers_->set_silent(true);   // every request times out: the pollers block 0.3 s per request
  int watchdogs = 0;
  const std::int64_t start = mono_now_ns();
  while (mono_now_ns() - start < 3'000'000'000) {
    const std::string msg = notify.receive(0.5);
    if (msg.find("WATCHDOG=1") != std::string::npos) ++watchdogs;
  }
  controllers_->set_silent(false);
  // Every 200 ms (half of WATCHDOG_USEC) for 3 s, while the controllers answered nothing.
  EXPECT_GE(watchdogs, 12);
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(30), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_EQ(out.find("withholding WATCHDOG=1"), std::string::npos) << out;
  EXPECT_NE(out.find("table: fault modbus-gone"), std::string::npos) << out;
}

}  // namespace
}  // namespace inertia::daq::testing
