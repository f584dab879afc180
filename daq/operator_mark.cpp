#include "daq/operator_mark.hpp"

#include <pwd.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <optional>

#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "common/lcm/channels.hpp"
#include "common/lcm/multicast_route.hpp"
#include "inertia/plan_command_t.hpp"

namespace inertia::daq {
namespace {

std::string sender_name() {
  const passwd* pw = ::getpwuid(::getuid());
  char host[256] = {};
  (void)::gethostname(host, sizeof host - 1);
  return std::string(pw != nullptr ? pw->pw_name : "uid" + std::to_string(::getuid())) + "@" + host + ":" +
         std::to_string(::getpid());
}

std::int64_t wall_us() {
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
}

struct Answer {
  const plan_command_t* request;
  std::optional<plan_command_t> reply;
  void on_reply(const lcm::ReceiveBuffer*, const std::string&, const plan_command_t* m) {
    if (m->sender == request->sender && m->id == request->id && m->status != plan_command_t::STATUS_REQUEST) reply = *m;
  }
};

}  // namespace

const char* mark_usage() {
  return "usage: inertia-daqd mark --case NAME [--phase KIND|INDEX] [--lcm-url URL] [--config FILE] [--timeout S]\n"
         "       inertia-daqd mark --end | --stop [--lcm-url URL] [--config FILE] [--timeout S]\n"
         "  Marks the running daemon's plan by hand (bench file: [bench] executive = \"operator\"): the\n"
         "  daemon publishes the INERTIA_EVENT markers, stamped when it receives the request.\n"
         "  --case NAME     a [[case]] of the daemon's bench: it starts now (the running case ends)\n"
         "  --phase KIND    and its next phase of this kind (dwell, rotation, sine, random, shock,\n"
         "                  thermal_step) or index (0-based) starts now (the running phase ends)\n"
         "  --end           the running case ends now\n"
         "  --stop          operator stop: the running case is aborted (MARK_ABORT) and every controller\n"
         "                  is put in its safe state; also aborts a plan the daemon runs itself\n"
         "  --lcm-url URL   the daemon's LCM URL (default: [daemon] lcm_url of --config FILE, else\n"
         "                  $LCM_DEFAULT_URL, else LCM's default)\n"
         "  --timeout S     give up when the daemon has not answered in S seconds (default 3)\n"
         "  Exit status: 0 accepted, 2 refused (the answer says why) or bad options, 1 no answer.\n";
}

int run_mark(const std::vector<std::string>& args) {
  plan_command_t request{};
  request.command = 0;
  request.status = plan_command_t::STATUS_REQUEST;
  std::string url, config;
  bool url_given = false;
  double timeout_s = 3.0;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw InputError("mark: option " + a + " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::cout << mark_usage();
      return 0;
    } else if (a == "--case") {
      request.case_name = value();
      request.command = plan_command_t::COMMAND_MARK;
    } else if (a == "--phase") {
      request.phase = value();
    } else if (a == "--end") {
      request.command = plan_command_t::COMMAND_END_CASE;
    } else if (a == "--stop") {
      request.command = plan_command_t::COMMAND_STOP;
    } else if (a == "--lcm-url") {
      url = value();
      url_given = true;
    } else if (a == "--config") {
      config = value();
    } else if (a == "--timeout") {
      try {
        timeout_s = std::stod(value());
      } catch (const std::exception&) {
        throw InputError("mark: option --timeout: '" + args[i] + "' is not a number");
      }
      if (!(timeout_s > 0)) throw InputError("mark: option --timeout: must be > 0");
    } else {
      throw InputError("mark: unknown option '" + a + "'\n" + mark_usage());
    }
  }
  const int modes = (request.command == plan_command_t::COMMAND_MARK) + (std::find(args.begin(), args.end(), "--end") != args.end()) +
                    (std::find(args.begin(), args.end(), "--stop") != args.end());
  if (modes != 1) throw InputError(std::string("mark: give exactly one of --case NAME, --end, --stop\n") + mark_usage());
  if (!request.phase.empty() && request.command != plan_command_t::COMMAND_MARK)
    throw InputError("mark: --phase goes with --case NAME");
  if (!url_given && !config.empty()) {
    const config::BenchConfig bench = config::load_bench_config(config);  // InputError -> exit 2
    if (bench.daemon.lcm_url) url = *bench.daemon.lcm_url;
  }
  if (url.empty() && std::getenv("LCM_DEFAULT_URL") != nullptr) url = std::getenv("LCM_DEFAULT_URL");
  if ((url.empty() || url.rfind("udpm://", 0) == 0) && !has_multicast_route()) {
    std::cerr << "inertia-daqd mark: LCM needs a multicast route and this host has none.\n"
                 "  fix: ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo\n";
    return 1;
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::cerr << "inertia-daqd mark: LCM failed to start on '" << (url.empty() ? "default" : url) << "'\n";
    return 1;
  }
  request.sender = sender_name();
  request.id = wall_us();
  Answer answer{&request, std::nullopt};
  lcm.subscribe(std::string(channels::kCommandReply), &Answer::on_reply, &answer);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  auto next_send = std::chrono::steady_clock::now();
  while (!answer.reply && std::chrono::steady_clock::now() < deadline) {
    if (std::chrono::steady_clock::now() >= next_send) {
      request.utime = wall_us();
      lcm.publish(std::string(channels::kCommand), &request);
      next_send += std::chrono::milliseconds(250);  // repeated until answered: UDP may lose it
    }
    (void)lcm.handleTimeout(20);
  }
  if (!answer.reply) {
    std::cerr << "inertia-daqd mark: no answer from inertia-daqd in " << timeout_s << " s on "
              << (url.empty() ? "LCM's default URL" : url) << " (is the daemon running, on this LCM URL?)\n";
    return 1;
  }
  if (answer.reply->status == plan_command_t::STATUS_ACCEPTED) {
    std::cout << "inertia-daqd mark: " << answer.reply->detail << "\n";
    return 0;
  }
  std::cerr << "inertia-daqd mark: refused: " << answer.reply->detail << "\n";
  return 2;
}

}  // namespace inertia::daq
