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
#include <vector>

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

struct Answers {
  const plan_command_t* request;
  std::vector<plan_command_t> replies;   // in the order heard, repeats of one status dropped
  void on_reply(const lcm::ReceiveBuffer*, const std::string&, const plan_command_t* m) {
    if (m->sender != request->sender || m->id != request->id || m->status == plan_command_t::STATUS_REQUEST) return;
    for (const plan_command_t& r : replies)
      if (r.status == m->status) return;
    replies.push_back(*m);
  }
  /// The answer that ends the exchange: the first one, or for a stop the one after its acknowledgement.
  [[nodiscard]] const plan_command_t* final_answer() const {
    for (const plan_command_t& r : replies) {
      if (request->command == plan_command_t::COMMAND_STOP && r.status == plan_command_t::STATUS_ACCEPTED) continue;
      return &r;
    }
    return nullptr;
  }
  [[nodiscard]] const plan_command_t* acknowledgement() const {
    for (const plan_command_t& r : replies)
      if (r.status == plan_command_t::STATUS_ACCEPTED) return &r;
    return nullptr;
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
         "  --stop          operator stop: every controller is commanded to its safe state at once (the\n"
         "                  first answer), the running case is aborted (MARK_ABORT), and the second\n"
         "                  answer says whether every controller read its safe state back; also\n"
         "                  aborts a plan the daemon runs itself, which disarms it\n"
         "  --lcm-url URL   the daemon's LCM URL (default: [daemon] lcm_url of --config FILE, else\n"
         "                  $LCM_DEFAULT_URL, else LCM's default)\n"
         "  --timeout S     give up when the daemon has not answered in S seconds (default 3; 10 for\n"
         "                  --stop, whose second answer waits for the controllers)\n"
         "  Exit status: 0 accepted (--stop: safe state confirmed), 2 refused (the answer says why) or\n"
         "  bad options, 1 no answer (--stop: no confirmation, or the safe state not confirmed).\n";
}

const char* arm_usage() {
  return "usage: inertia-daqd arm [--lcm-url URL] [--config FILE] [--timeout S]\n"
         "  Arms the running daemon's plan (bench file: [bench] executive = \"plan\"): the daemon starts\n"
         "  disarmed, holding every controller in its safe state; an arm runs the plan once, from its\n"
         "  first case, and its end or any abort disarms it again. Refused, with the reason, while a\n"
         "  controller the plan commands is faulted or has not confirmed its safe state.\n"
         "  Options and exit status as inertia-daqd mark (mark --help).\n";
}

namespace {

/// Sends `request` until the daemon answers (and, for a stop, until its second answer); prints it.
int exchange(plan_command_t request, const std::string& url, double timeout_s, const char* verb) {
  if ((url.empty() || url.rfind("udpm://", 0) == 0) && !has_multicast_route()) {
    std::cerr << "inertia-daqd " << verb << ": LCM needs a multicast route and this host has none.\n"
                 "  fix: ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo\n";
    return 1;
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::cerr << "inertia-daqd " << verb << ": LCM failed to start on '" << (url.empty() ? "default" : url) << "'\n";
    return 1;
  }
  request.sender = sender_name();
  request.id = wall_us();
  Answers answers{&request, {}};
  lcm.subscribe(std::string(channels::kCommandReply), &Answers::on_reply, &answers);
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  auto next_send = Clock::now();
  bool acknowledged = false;
  while (answers.final_answer() == nullptr && Clock::now() < deadline) {
    // Repeated until answered (UDP may lose it); a stop that was acknowledged is not sent again.
    if (answers.replies.empty() && Clock::now() >= next_send) {
      request.utime = wall_us();
      lcm.publish(std::string(channels::kCommand), &request);
      next_send += std::chrono::milliseconds(250);
    }
    (void)lcm.handleTimeout(5);
    if (!acknowledged && answers.acknowledgement() != nullptr && request.command == plan_command_t::COMMAND_STOP) {
      acknowledged = true;
      std::cout << "inertia-daqd " << verb << ": " << answers.acknowledgement()->detail << std::endl;
    }
  }
  const plan_command_t* answer = answers.final_answer();
  if (answer == nullptr) {
    if (acknowledged) {
      std::cerr << "inertia-daqd " << verb << ": the stop was acknowledged, but its confirmation was not heard in " << timeout_s
                << " s: check the bench and the journal (journalctl -u inertia-daqd PLAN_EVENT=safe-state)\n";
      return 1;
    }
    std::cerr << "inertia-daqd " << verb << ": no answer from inertia-daqd in " << timeout_s << " s on "
              << (url.empty() ? "LCM's default URL" : url) << " (is the daemon running, on this LCM URL?)\n";
    return 1;
  }
  if (answer->status == plan_command_t::STATUS_ACCEPTED || answer->status == plan_command_t::STATUS_DONE) {
    std::cout << "inertia-daqd " << verb << ": " << answer->detail << "\n";
    return 0;
  }
  if (request.command == plan_command_t::COMMAND_STOP) {
    std::cerr << "inertia-daqd " << verb << ": " << answer->detail << "\n";
    return 1;
  }
  std::cerr << "inertia-daqd " << verb << ": refused: " << answer->detail << "\n";
  return 2;
}

/// --lcm-url URL, else the bench's [daemon] lcm_url with --config FILE, else $LCM_DEFAULT_URL.
std::string daemon_url(const std::string& url, bool url_given, const std::string& config) {
  std::string out = url;
  if (!url_given && !config.empty()) {
    const config::BenchConfig bench = config::load_bench_config(config);  // InputError -> exit 2
    if (bench.daemon.lcm_url) out = *bench.daemon.lcm_url;
  }
  if (out.empty() && std::getenv("LCM_DEFAULT_URL") != nullptr) out = std::getenv("LCM_DEFAULT_URL");
  return out;
}

double timeout_value(const std::string& text, const char* verb) {
  double v = 0.0;
  try {
    v = std::stod(text);
  } catch (const std::exception&) {
    throw InputError(std::string(verb) + ": option --timeout: '" + text + "' is not a number");
  }
  if (!(v > 0)) throw InputError(std::string(verb) + ": option --timeout: must be > 0");
  return v;
}

}  // namespace

int run_mark(const std::vector<std::string>& args) {
  plan_command_t request{};
  request.command = 0;
  request.status = plan_command_t::STATUS_REQUEST;
  std::string url, config;
  bool url_given = false, timeout_given = false;
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
      timeout_s = timeout_value(value(), "mark");
      timeout_given = true;
    } else {
      throw InputError("mark: unknown option '" + a + "'\n" + mark_usage());
    }
  }
  const int modes = (request.command == plan_command_t::COMMAND_MARK) + (std::find(args.begin(), args.end(), "--end") != args.end()) +
                    (std::find(args.begin(), args.end(), "--stop") != args.end());
  if (modes != 1) throw InputError(std::string("mark: give exactly one of --case NAME, --end, --stop\n") + mark_usage());
  if (!request.phase.empty() && request.command != plan_command_t::COMMAND_MARK)
    throw InputError("mark: --phase goes with --case NAME");
  // A stop's second answer waits for the controllers' read back, up to their response timeouts.
  if (request.command == plan_command_t::COMMAND_STOP && !timeout_given) timeout_s = 10.0;
  return exchange(request, daemon_url(url, url_given, config), timeout_s, "mark");
}

int run_arm(const std::vector<std::string>& args) {
  plan_command_t request{};
  request.command = plan_command_t::COMMAND_ARM;
  request.status = plan_command_t::STATUS_REQUEST;
  std::string url, config;
  bool url_given = false;
  double timeout_s = 3.0;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw InputError("arm: option " + a + " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::cout << arm_usage();
      return 0;
    } else if (a == "--lcm-url") {
      url = value();
      url_given = true;
    } else if (a == "--config") {
      config = value();
    } else if (a == "--timeout") {
      timeout_s = timeout_value(value(), "arm");
    } else {
      throw InputError("arm: unknown option '" + a + "'\n" + arm_usage());
    }
  }
  return exchange(request, daemon_url(url, url_given, config), timeout_s, "arm");
}

}  // namespace inertia::daq
