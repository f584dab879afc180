// Who may command the bench, on the real daemon and real processes: requests on this machine go
// through the daemon's command socket, whose peer the kernel names (run here as another user with
// setpriv); requests from another machine are signed with the operators' key (sent here from
// this process over LCM, as `inertia-daqd mark --key` sends them). Unprivileged users may stop,
// not mark or arm; an operator's requests are accepted and logged with who sent them; forged,
// replayed, stale and unsigned requests are refused and counted; bad bytes change nothing.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>

#include <lcm/lcm-cpp.hpp>

#include <fstream>
#include <random>

#include "daq/command_auth.hpp"
#include "daq/command_socket.hpp"
#include "inertia/daq_status_t.hpp"
#include "inertia/plan_command_t.hpp"
#include "inertia/plan_event_t.hpp"
#include "inertia/signed_command_t.hpp"
#include "tests/integration/executive_bench.hpp"

namespace inertia::daq::testing {
namespace {

constexpr const char* kNobody = "65534";
constexpr const char* kOperatorGid = "4242";   // a group no account has: the test's operator group

std::int64_t wall_us() {
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
}

class Authority : public RealBenchTest {
 protected:
  void SetUp() override {
    RealBenchTest::SetUp();
    // Another user must reach the socket in this directory.
    fs::permissions(dir_.path, fs::perms(0755));
  }
  /// `inertia-daqd ARGS... --socket PATH` as uid 65534 with the given supplementary groups.
  std::pair<int, std::string> as_nobody(std::vector<std::string> args, const std::string& groups = "") {
    std::vector<std::string> argv{std::string("--reuid=") + kNobody, std::string("--regid=") + kNobody,
                                  groups.empty() ? "--clear-groups" : "--groups=" + groups, daqd_binary()};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--socket", socket_path()});
    DaqdProcess p(argv, {}, dir_.path / ("nobody" + std::to_string(n_++) + ".txt"), "/usr/bin/setpriv");
    const int status = p.wait(30);
    return {status, p.output()};
  }
  static std::vector<daq_status_t> statuses(LcmCollector& live) {
    std::vector<daq_status_t> out;
    for (const auto& r : live.take()) {
      if (r.channel != "INERTIA_STATUS") continue;
      daq_status_t st;
      if (st.decode(r.data.data(), 0, static_cast<int>(r.data.size())) >= 0) out.push_back(st);
    }
    return out;
  }

  int n_ = 0;
};

TEST_F(Authority, AnUnprivilegedUsersMarkEndAndArmAreRefusedJournalledAndLeaveNoMarkerTheirStopIsTaken) {
  INERTIA_REQUIRE_LCM_ROUTE();
  if (::geteuid() != 0) INERTIA_SKIP_OR_FAIL_IN_CI("another user's requests need root to run them (setpriv)");
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--log",
                    (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases are marked by the operator", 20)) << daqd.output();
  for (const std::vector<std::string>& request : {std::vector<std::string>{"mark", "--case", "table", "--phase", "dwell"},
                                                 std::vector<std::string>{"mark", "--end"}, std::vector<std::string>{"arm"}}) {
    const auto [status, out] = as_nobody(request);
    EXPECT_EQ(status, 2) << request[0] << ": " << out;
    EXPECT_NE(out.find("refused: not authorized: uid 65534 (nobody), pid "), std::string::npos) << out;
    EXPECT_NE(out.find(" is not in group inertia-operators (an administrator adds a person with: usermod -aG "
                       "inertia-operators NAME)"),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find("no answer"), std::string::npos) << "a refusal is never a timeout";
  }
  // Stopping is the safe direction: any local user.
  const auto [stop_status, stop_out] = as_nobody({"mark", "--stop"});
  EXPECT_EQ(stop_status, 0) << stop_out;
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_EQ(count_of(out, ": refused: not authorized: uid 65534 (nobody)"), 3u) << out;
  EXPECT_NE(out.find("command: stop from uid 65534 (nobody), pid "), std::string::npos) << out;
  // The run unchanged: no case or phase began, and the log names only the stop's sender.
  const auto events = read_log_dir(tmp.path / "log");
  for (const plan_event_t& m : decode_all<plan_event_t>(events, "INERTIA_EVENT"))
    EXPECT_NE(m.mark, plan_event_t::MARK_CASE_START) << "a refused mark left a marker";
  const auto records = decode_all<plan_command_t>(events, "INERTIA_OPERATOR");
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].command, plan_command_t::COMMAND_STOP);
  EXPECT_NE(records[0].sender.find("uid 65534 (nobody)"), std::string::npos) << records[0].sender;
}

TEST_F(Authority, AnOperatorsMarksAreAcceptedAtOnceAndTheLogSaysWhoMarked) {
  INERTIA_REQUIRE_LCM_ROUTE();
  if (::geteuid() != 0) INERTIA_SKIP_OR_FAIL_IN_CI("another user's requests need root to run them (setpriv)");
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--operator-group", kOperatorGid, "--duration",
                    "60", "--log", (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases are marked by the operator", 20)) << daqd.output();
  const auto [status, out] = as_nobody({"mark", "--case", "table", "--phase", "dwell"}, kOperatorGid);
  EXPECT_EQ(status, 0) << out;
  EXPECT_NE(out.find("inertia-daqd mark: case table started; case table phase 0 (dwell) started"), std::string::npos) << out;

  // The acknowledgement's latency on the socket, from this process (root, an operator): 20 marks.
  std::vector<double> ms;
  for (int i = 0; i < 20; ++i) {
    std::string why;
    auto client = CommandClient::connect(socket_path(), &why);
    ASSERT_NE(client, nullptr) << why;
    plan_command_t mark{};
    mark.id = i + 1;
    mark.sender = "authority-test";
    mark.command = plan_command_t::COMMAND_MARK;
    mark.case_name = "table";
    mark.phase = i % 2 == 0 ? "rotation" : "dwell";
    const std::int64_t sent = mono_now_ns();
    ASSERT_TRUE(client->send(mark, &why)) << why;
    const auto answer = client->receive(5.0, &why);
    ms.push_back(static_cast<double>(mono_now_ns() - sent) * 1e-6);
    ASSERT_TRUE(answer) << why;
    EXPECT_EQ(answer->status, plan_command_t::STATUS_ACCEPTED) << answer->detail;
  }
  std::sort(ms.begin(), ms.end());
  std::cout << "operator mark on the command socket, to its answer: median " << ms[10] << " ms, max " << ms.back() << " ms (20)\n";
  EXPECT_LT(ms.back(), 50.0);
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  EXPECT_NE(daqd.output().find("command: mark from uid 65534 (nobody), pid "), std::string::npos) << daqd.output();

  // In the log, each accepted request right beside the markers it caused, with who sent it.
  const auto events = read_log_dir(tmp.path / "log");
  std::size_t first_mark = events.size(), first_record = events.size();
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (events[i].channel == "INERTIA_EVENT" && first_mark == events.size()) first_mark = i;
    if (events[i].channel == "INERTIA_OPERATOR" && first_record == events.size()) first_record = i;
  }
  ASSERT_LT(first_mark, events.size());
  ASSERT_LT(first_record, events.size());
  std::size_t between = 0;   // sample blocks and status between the record and its first marker
  for (std::size_t i = std::min(first_mark, first_record) + 1; i < std::max(first_mark, first_record); ++i) ++between;
  EXPECT_LE(between, 20u) << "the record and its markers a few log records apart";
  const auto records = decode_all<plan_command_t>(events, "INERTIA_OPERATOR");
  ASSERT_EQ(records.size(), 21u);
  EXPECT_NE(records[0].sender.find("uid 65534 (nobody), pid "), std::string::npos) << records[0].sender;
  EXPECT_NE(records[0].sender.find(" as nobody@"), std::string::npos) << records[0].sender;
  EXPECT_EQ(records[0].case_name, "table");
  EXPECT_NE(records[1].sender.find("uid 0 (root)"), std::string::npos) << records[1].sender;
}

TEST_F(Authority, SignedRequestsAreTakenForgedReplayedStaleAndUnsignedOnesRefusedAndCounted) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const std::string secret = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
  const fs::path key_file = write("# the operators' key\nlab-pc-2 " + secret + "\n", "command.key", fs::perms(0640));
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--command-key", key_file.string(), "--duration",
                    "60", "--log", (tmp.path / "log").string(), "--lcm-url", url},
                   {}, tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases are marked by the operator", 20)) << daqd.output();
  const std::vector<CommandKey> keys = load_command_keys(key_file);
  ASSERT_EQ(keys.size(), 1u);
  CommandKey wrong = keys[0];
  wrong.secret[0] ^= 1;

  lcm::LCM lcm(url);
  ASSERT_TRUE(lcm.good());
  struct Replies {
    std::vector<plan_command_t> heard;
    void on(const lcm::ReceiveBuffer*, const std::string&, const plan_command_t* m) { heard.push_back(*m); }
  } replies;
  lcm.subscribe("INERTIA_COMMAND_REPLY", &Replies::on, &replies);
  std::int64_t next_id = 1;
  auto request = [&](std::int8_t command, const std::string& phase = "") {
    plan_command_t c{};
    c.id = next_id++;
    c.sender = "pc2-operator";
    c.command = command;
    c.case_name = command == plan_command_t::COMMAND_MARK ? "table" : "";
    c.phase = phase;
    c.status = plan_command_t::STATUS_REQUEST;
    return c;
  };
  auto answer_to = [&](std::int64_t id) -> std::optional<plan_command_t> {
    const std::int64_t deadline = mono_now_ns() + 3'000'000'000;
    while (mono_now_ns() < deadline) {
      lcm.handleTimeout(10);
      for (const auto& r : replies.heard)
        if (r.id == id) return r;
    }
    return std::nullopt;
  };
  auto clear = [&] { replies.heard.clear(); };

  // A signed mark: taken.
  const plan_command_t mark = request(plan_command_t::COMMAND_MARK, "dwell");
  const signed_command_t good = sign_command(keys[0], mark, wall_us(), 7);
  lcm.publish("INERTIA_COMMAND_SIGNED", &good);
  auto a = answer_to(mark.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_ACCEPTED) << a->detail;
  // The very same bytes again (a sender that lost the answer): answered again, not acted on twice.
  clear();
  lcm.publish("INERTIA_COMMAND_SIGNED", &good);
  a = answer_to(mark.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_ACCEPTED) << a->detail;
  // The same bytes again, with its id forgotten by the daemon's repeat table: a replay. (A new id
  // under the same nonce is what an attacker who copied the request can send.)
  clear();
  plan_command_t copy = mark;
  copy.id = next_id++;
  signed_command_t replay = good;
  {
    signed_command_t forged_id = sign_command(keys[0], copy, good.utime, good.nonce);
    replay = forged_id;   // signed with the right key and the copied nonce: refused as a replay
  }
  lcm.publish("INERTIA_COMMAND_SIGNED", &replay);
  a = answer_to(copy.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_REFUSED);
  EXPECT_NE(a->detail.find("replayed: this request (key 'lab-pc-2', nonce 7) was already taken"), std::string::npos) << a->detail;
  // Signed with another secret: forged.
  clear();
  const plan_command_t end = request(plan_command_t::COMMAND_END_CASE);
  const signed_command_t forged = sign_command(wrong, end, wall_us(), 8);
  lcm.publish("INERTIA_COMMAND_SIGNED", &forged);
  a = answer_to(end.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_REFUSED);
  EXPECT_NE(a->detail.find("the signature does not match key 'lab-pc-2'"), std::string::npos) << a->detail;
  // A minute old: stale.
  clear();
  const plan_command_t late = request(plan_command_t::COMMAND_END_CASE);
  const signed_command_t stale = sign_command(keys[0], late, wall_us() - 60'000'000, 9);
  lcm.publish("INERTIA_COMMAND_SIGNED", &stale);
  a = answer_to(late.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_REFUSED);
  EXPECT_NE(a->detail.find("stale: signed 60"), std::string::npos) << a->detail;
  // Arming over the network, even signed: refused.
  clear();
  const plan_command_t arm = request(plan_command_t::COMMAND_ARM);
  const signed_command_t signed_arm = sign_command(keys[0], arm, wall_us(), 10);
  lcm.publish("INERTIA_COMMAND_SIGNED", &signed_arm);
  a = answer_to(arm.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_REFUSED);
  EXPECT_NE(a->detail.find("arming starts motion and is taken only on this machine"), std::string::npos) << a->detail;
  // Unsigned, on the old channel: not acted on.
  clear();
  const plan_command_t bare = request(plan_command_t::COMMAND_END_CASE);
  lcm.publish("INERTIA_COMMAND", &bare);
  a = answer_to(bare.id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->status, plan_command_t::STATUS_REFUSED);
  EXPECT_NE(a->detail.find("not authorized: an unsigned request on INERTIA_COMMAND carries no identity"), std::string::npos) << a->detail;

  // Bytes that are no request, on either channel: counted and dropped.
  const std::vector<std::uint8_t> junk(300, 0xA5);
  lcm.publish("INERTIA_COMMAND", junk.data(), static_cast<unsigned>(junk.size()));
  lcm.publish("INERTIA_COMMAND_SIGNED", junk.data(), static_cast<unsigned>(junk.size()));

  // The command line's signed route, end to end.
  DaqdProcess cli({"mark", "--end", "--key", key_file.string(), "--lcm-url", url}, {}, tmp.path / "cli.txt");
  EXPECT_EQ(cli.wait(20), 0) << cli.output();
  EXPECT_NE(cli.output().find("inertia-daqd mark: case table ended"), std::string::npos) << cli.output();

  std::this_thread::sleep_for(std::chrono::milliseconds(1200));   // a status after the last request
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const auto st = statuses(live);
  ASSERT_FALSE(st.empty());
  EXPECT_EQ(st.back().commands_accepted, 2);   // the signed mark, the command line's end
  EXPECT_EQ(st.back().commands_refused, 6);    // replayed, forged, stale, signed arm, two of junk
  EXPECT_EQ(st.back().commands_unsigned, 1);
  const std::string out = daqd.output();
  EXPECT_NE(out.find("command: mark from key lab-pc-2: accepted"), std::string::npos) << out;
  EXPECT_NE(out.find("command: end from key lab-pc-2 (not verified): refused: the signature does not match"), std::string::npos) << out;
  EXPECT_NE(out.find("command: end from unsigned request claiming to be pc2-operator: ignored"), std::string::npos) << out;
  const auto events = read_log_dir(tmp.path / "log");
  const auto records = decode_all<plan_command_t>(events, "INERTIA_OPERATOR");
  ASSERT_EQ(records.size(), 2u);
  EXPECT_EQ(records[0].sender, "key lab-pc-2 as pc2-operator");
  std::size_t case_starts = 0;
  for (const plan_event_t& m : decode_all<plan_event_t>(events, "INERTIA_EVENT")) case_starts += m.mark == plan_event_t::MARK_CASE_START;
  EXPECT_EQ(case_starts, 1u) << "the repeated request marked nothing twice";
}

TEST_F(Authority, AKeyFileOthersCanReadIsRefusedAtStartWithTheFix) {
  const fs::path key_file =
      write("lab-pc-2 00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n", "command.key", fs::perms(0644));
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--command-key", key_file.string(), "--duration",
                    "5", "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt");
  EXPECT_EQ(daqd.wait(20), 2);
  EXPECT_NE(daqd.output().find(key_file.string() + ": the command key file is open to every user (mode 644): anyone could sign "
                               "commands with it. Fix: chmod 640 " + key_file.string()),
            std::string::npos)
      << daqd.output();
}

TEST_F(Authority, MalformedAndOversizedRequestsOnTheSocketAreDroppedCountedAndTheDaemonGoesOn) {
  INERTIA_REQUIRE_LCM_ROUTE();
  const fs::path bench = write(bench_head("operator") + controllers(controllers_->port()) + kTableCase);
  const std::string url = private_lcm_url();
  LcmCollector live(url);
  ASSERT_TRUE(live.good());
  TempDir tmp;
  DaqdProcess daqd({"--config", bench.string(), "--command-socket", socket_path(), "--duration", "60", "--lcm-url", url}, {},
                   tmp.path / "stderr.txt");
  ASSERT_TRUE(wait_for(daqd, "phases are marked by the operator", 20)) << daqd.output();
  {
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", socket_path().c_str());
    ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
    std::mt19937 rng(5);
    std::vector<std::uint8_t> junk(100'000);
    for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
    EXPECT_EQ(::send(fd, junk.data(), junk.size(), 0), static_cast<ssize_t>(junk.size()));   // oversized
    EXPECT_EQ(::send(fd, junk.data(), 300, 0), 300);                                          // not a plan_command_t
    ::close(fd);
  }
  // Still serving: an operator's mark goes through.
  std::string why;
  auto client = CommandClient::connect(socket_path(), &why);
  ASSERT_NE(client, nullptr) << why;
  plan_command_t mark{};
  mark.id = 1;
  mark.sender = "authority-test";
  mark.command = plan_command_t::COMMAND_MARK;
  mark.case_name = "table";
  mark.status = plan_command_t::STATUS_REQUEST;
  ASSERT_TRUE(client->send(mark, &why)) << why;
  const auto answer = client->receive(5.0, &why);
  ASSERT_TRUE(answer) << why;
  EXPECT_EQ(answer->status, plan_command_t::STATUS_ACCEPTED) << answer->detail;
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const auto st = statuses(live);
  ASSERT_FALSE(st.empty());
  EXPECT_EQ(st.back().commands_refused, 2);
  EXPECT_EQ(st.back().commands_accepted, 1);
}

}  // namespace
}  // namespace inertia::daq::testing
