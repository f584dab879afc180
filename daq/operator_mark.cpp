#include "daq/operator_mark.hpp"

#include <pwd.h>
#include <sys/random.h>
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
#include "daq/command_auth.hpp"
#include "daq/command_socket.hpp"
#include "inertia/plan_command_t.hpp"
#include "inertia/signed_command_t.hpp"

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

/// The answers to one request, in the order heard, repeats of one status dropped.
struct Answers {
  const plan_command_t* request;
  std::vector<plan_command_t> replies;
  void add(const plan_command_t& m) {
    if (m.sender != request->sender || m.id != request->id || m.status == plan_command_t::STATUS_REQUEST) return;
    for (const plan_command_t& r : replies)
      if (r.status == m.status) return;
    replies.push_back(m);
  }
  void on_reply(const lcm::ReceiveBuffer*, const std::string&, const plan_command_t* m) { add(*m); }
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

/// Where and how a request goes: the daemon's command socket on this machine (the default), or
/// LCM to a daemon on another machine, signed with a key.
struct Route {
  std::filesystem::path socket;
  std::string lcm_url;
  bool lcm = false;
  std::optional<CommandKey> key;
};

/// Prints the exchange's outcome; the exit status.
int finish(const Answers& answers, const plan_command_t& request, bool acknowledged, double timeout_s, const std::string& where,
           const char* verb) {
  const plan_command_t* answer = answers.final_answer();
  if (answer == nullptr) {
    if (acknowledged) {
      std::cerr << "inertia-daqd " << verb << ": the stop was acknowledged, but its confirmation was not heard in " << timeout_s
                << " s: check the bench and the journal (journalctl -u inertia-daqd PLAN_EVENT=safe-state)\n";
      return 1;
    }
    std::cerr << "inertia-daqd " << verb << ": no answer from inertia-daqd in " << timeout_s << " s on " << where
              << " (is the daemon running there?)\n";
    return 1;
  }
  if (answer->status == plan_command_t::STATUS_ACCEPTED || answer->status == plan_command_t::STATUS_DONE) {
    std::cout << "inertia-daqd " << verb << ": " << answer->detail << "\n";
    return 0;
  }
  if (request.command == plan_command_t::COMMAND_STOP && acknowledged) {
    std::cerr << "inertia-daqd " << verb << ": " << answer->detail << "\n";
    return 1;
  }
  std::cerr << "inertia-daqd " << verb << ": refused: " << answer->detail << "\n";
  return 2;
}

void print_acknowledgement(const Answers& answers, const plan_command_t& request, bool& acknowledged, const char* verb) {
  if (acknowledged || request.command != plan_command_t::COMMAND_STOP || answers.acknowledgement() == nullptr) return;
  acknowledged = true;
  std::cout << "inertia-daqd " << verb << ": " << answers.acknowledgement()->detail << std::endl;
}

int exchange_on_socket(const plan_command_t& request, const std::filesystem::path& path, double timeout_s, const char* verb) {
  std::string why;
  auto client = CommandClient::connect(path, &why);
  if (!client) {
    std::cerr << "inertia-daqd " << verb << ": " << why << "\n";
    return 1;
  }
  if (!client->send(request, &why)) {
    std::cerr << "inertia-daqd " << verb << ": " << why << "\n";
    return 1;
  }
  Answers answers{&request, {}};
  bool acknowledged = false;
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  while (answers.final_answer() == nullptr && Clock::now() < deadline) {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    const auto answer = client->receive(std::max(left, 0.001), &why);
    if (!answer) break;
    answers.add(*answer);
    print_acknowledgement(answers, request, acknowledged, verb);
  }
  return finish(answers, request, acknowledged, timeout_s, path.string(), verb);
}

int exchange_on_lcm(plan_command_t request, const Route& route, double timeout_s, const char* verb) {
  const std::string& url = route.lcm_url;
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
  std::int64_t nonce = 0;
  if (::getrandom(&nonce, sizeof nonce, 0) != sizeof nonce) nonce = wall_us() ^ ::getpid();
  // Signed once: a repeat (UDP may lose one) is the same request, which the daemon acts on once.
  const signed_command_t signed_request = sign_command(*route.key, request, wall_us(), nonce);
  Answers answers{&request, {}};
  lcm.subscribe(std::string(channels::kCommandReply), &Answers::on_reply, &answers);
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  auto next_send = Clock::now();
  bool acknowledged = false;
  while (answers.final_answer() == nullptr && Clock::now() < deadline) {
    if (answers.replies.empty() && Clock::now() >= next_send) {
      lcm.publish(std::string(channels::kCommandSigned), &signed_request);
      next_send += std::chrono::milliseconds(250);
    }
    (void)lcm.handleTimeout(5);
    print_acknowledgement(answers, request, acknowledged, verb);
  }
  return finish(answers, request, acknowledged, timeout_s, url.empty() ? "LCM's default URL" : url, verb);
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

/// The options every verb shares: --socket, --lcm-url, --key, --key-id, --config, --timeout.
struct Common {
  std::string socket, lcm_url, key_file, key_id, config;
  bool lcm_given = false;
  double timeout_s = 3.0;
  bool timeout_given = false;
  /// Takes args[i] (and its value) when it is one of them.
  bool take(const std::vector<std::string>& args, std::size_t& i, const char* verb) {
    const std::string& a = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw InputError(std::string(verb) + ": option " + a + " needs a value");
      return args[++i];
    };
    if (a == "--socket") socket = value();
    else if (a == "--lcm-url") {
      lcm_url = value();
      lcm_given = true;
    } else if (a == "--key") key_file = value();
    else if (a == "--key-id") key_id = value();
    else if (a == "--config") config = value();
    else if (a == "--timeout") {
      timeout_s = timeout_value(value(), verb);
      timeout_given = true;
    } else return false;
    return true;
  }
  /// The route: LCM when a key is given (--lcm-url, else the bench's [daemon] lcm_url, else
  /// $LCM_DEFAULT_URL), the command socket otherwise (--socket, else the bench's [daemon]
  /// command_socket, else the default).
  Route route(const char* verb) const {
    std::optional<config::BenchConfig> bench;
    if (!config.empty()) bench = config::load_bench_config(config);   // InputError -> exit 2
    Route r;
    if (key_file.empty()) {
      if (lcm_given)
        throw InputError(std::string(verb) + ": --lcm-url sends over the network, where a request is taken only when signed: "
                                             "give --key FILE (the operators' command key), or leave --lcm-url out on the bench PC");
      r.socket = !socket.empty() ? std::filesystem::path(socket)
                 : bench && bench->daemon.command_socket ? std::filesystem::path(*bench->daemon.command_socket)
                                                         : default_command_socket();
      return r;
    }
    if (!socket.empty()) throw InputError(std::string(verb) + ": --socket and --key are two routes: give one");
    const std::vector<CommandKey> keys = load_command_keys(key_file);   // InputError -> exit 2
    const auto k = key_id.empty() ? keys.begin()
                                  : std::find_if(keys.begin(), keys.end(), [&](const CommandKey& c) { return c.id == key_id; });
    if (k == keys.end()) throw InputError(std::string(verb) + ": no key '" + key_id + "' in " + key_file);
    r.lcm = true;
    r.key = *k;
    r.lcm_url = lcm_url;
    if (!lcm_given && bench && bench->daemon.lcm_url) r.lcm_url = *bench->daemon.lcm_url;
    if (r.lcm_url.empty() && std::getenv("LCM_DEFAULT_URL") != nullptr) r.lcm_url = std::getenv("LCM_DEFAULT_URL");
    return r;
  }
};

int exchange(plan_command_t request, const Common& common, double timeout_s, const char* verb) {
  request.status = plan_command_t::STATUS_REQUEST;
  request.sender = sender_name();
  request.id = wall_us();
  request.utime = request.id;
  const Route route = common.route(verb);
  return route.lcm ? exchange_on_lcm(request, route, timeout_s, verb) : exchange_on_socket(request, route.socket, timeout_s, verb);
}

constexpr const char* kRouteHelp =
    "  --socket PATH   the daemon's command socket on this machine (default: [daemon] command_socket\n"
    "                  of --config FILE, else /run/inertia/command.sock); the daemon knows who you are\n"
    "                  from the kernel: marks and arm need an operator (root, or group inertia-operators),\n"
    "                  a stop is taken from anyone on this machine\n"
    "  --key FILE      from another machine: sign the request with the operators' command key (the\n"
    "                  daemon's --command-key holds the same); sent on LCM (--lcm-url URL, else\n"
    "                  [daemon] lcm_url of --config FILE, else $LCM_DEFAULT_URL); --key-id ID picks a\n"
    "                  key of FILE (default its first). An arm is never taken this way\n"
    "  --timeout S     give up when the daemon has not answered in S seconds (default 3; 10 for\n"
    "                  --stop, whose second answer waits for the controllers)\n";

}  // namespace

const char* mark_usage() {
  static const std::string text =
      std::string("usage: inertia-daqd mark --case NAME [--phase KIND|INDEX] [--socket PATH | --key FILE [--lcm-url URL]]\n"
                  "       inertia-daqd mark --end | --stop [--socket PATH | --key FILE [--lcm-url URL]]\n"
                  "  Marks the running daemon's plan by hand (bench file: [bench] executive = \"operator\"): the\n"
                  "  daemon publishes the INERTIA_EVENT markers, stamped when it receives the request, and logs\n"
                  "  who sent it (INERTIA_OPERATOR).\n"
                  "  --case NAME     a [[case]] of the daemon's bench: it starts now (the running case ends)\n"
                  "  --phase KIND    and its next phase of this kind (dwell, rotation, sine, random, shock,\n"
                  "                  thermal_step) or index (0-based) starts now (the running phase ends)\n"
                  "  --end           the running case ends now\n"
                  "  --stop          operator stop: every controller is commanded to its safe state at once (the\n"
                  "                  first answer), the running case is aborted (MARK_ABORT), and the second\n"
                  "                  answer says whether every controller read its safe state back; also\n"
                  "                  aborts a plan the daemon runs itself, which disarms it\n") +
      kRouteHelp +
      "  Exit status: 0 accepted (--stop: safe state confirmed), 2 refused (the answer says why, e.g.\n"
      "  \"not authorized\") or bad options, 1 no answer (--stop: no confirmation, or the safe state not\n"
      "  confirmed).\n";
  return text.c_str();
}

const char* arm_usage() {
  static const std::string text =
      std::string("usage: inertia-daqd arm [--socket PATH] [--config FILE] [--timeout S]\n"
                  "  Arms the running daemon's plan (bench file: [bench] executive = \"plan\"): the daemon starts\n"
                  "  disarmed, holding every controller in its safe state; an arm runs the plan once, from its\n"
                  "  first case, and its end or any abort disarms it again. Refused, with the reason, while a\n"
                  "  controller the plan commands is faulted or has not confirmed its safe state, and unless it\n"
                  "  comes from an operator on this machine (never over the network).\n") +
      kRouteHelp + "  Exit status as inertia-daqd mark.\n";
  return text.c_str();
}

int run_mark(const std::vector<std::string>& args) {
  plan_command_t request{};
  Common common;
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
    } else if (!common.take(args, i, "mark")) {
      throw InputError("mark: unknown option '" + a + "'\n" + mark_usage());
    }
  }
  const int modes = (request.command == plan_command_t::COMMAND_MARK) + (std::find(args.begin(), args.end(), "--end") != args.end()) +
                    (std::find(args.begin(), args.end(), "--stop") != args.end());
  if (modes != 1) throw InputError(std::string("mark: give exactly one of --case NAME, --end, --stop\n") + mark_usage());
  if (!request.phase.empty() && request.command != plan_command_t::COMMAND_MARK)
    throw InputError("mark: --phase goes with --case NAME");
  // A stop's second answer waits for the controllers' read back, up to their response timeouts.
  const double timeout_s = request.command == plan_command_t::COMMAND_STOP && !common.timeout_given ? 10.0 : common.timeout_s;
  return exchange(request, common, timeout_s, "mark");
}

int run_arm(const std::vector<std::string>& args) {
  plan_command_t request{};
  request.command = plan_command_t::COMMAND_ARM;
  Common common;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      std::cout << arm_usage();
      return 0;
    }
    if (!common.take(args, i, "arm")) throw InputError("arm: unknown option '" + a + "'\n" + arm_usage());
  }
  return exchange(request, common, common.timeout_s, "arm");
}

}  // namespace inertia::daq
