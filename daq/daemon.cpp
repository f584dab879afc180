#include "daq/daemon.hpp"

#include <pthread.h>
#include <pwd.h>
#include <signal.h>
#include <sys/mman.h>
#include <systemd/sd-daemon.h>
#include <time.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <lcm/lcm-cpp.hpp>
#include <sstream>

#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"
#include "common/lcm/channels.hpp"
#include "daq/command_auth.hpp"
#include "daq/command_socket.hpp"
#include "daq/journal.hpp"
#include "daq/log_writer.hpp"
#include "daq/publisher.hpp"
#include "daq/plan_mark.hpp"
#include "daq/real_bench.hpp"
#include "daq/run_record.hpp"
#include "daq/test_executive.hpp"
#include "hal/device.hpp"
#include "inertia/bench_config_t.hpp"

namespace inertia::daq {
namespace {

using Limits = config::DaemonLimits;

double to_number(const std::string& option, const std::string& text) {
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {
  }
  throw InputError("option " + option + ": '" + text + "' is not a number");
}

// A count or an index: a whole number within [low, high], so that no cast below is undefined.
long long to_integer(const std::string& option, const std::string& text, long long low, long long high) {
  const double v = to_number(option, text);
  if (!(v == std::floor(v)) || v < static_cast<double>(low) || v > static_cast<double>(high))
    throw InputError(fmt::format("option {}: '{}' is not a whole number in {}..{}", option, text, low, high));
  return static_cast<long long>(v);
}

// "AT+DUR" -> (AT, DUR)
std::pair<double, double> at_for(const std::string& option, const std::string& text) {
  const auto plus = text.find('+');
  if (plus == std::string::npos) throw InputError("option --fault " + option + ": expected AT+DURATION, got '" + text + "'");
  return {to_number("--fault " + option, text.substr(0, plus)), to_number("--fault " + option, text.substr(plus + 1))};
}

void parse_fault(const std::string& spec, DaemonOptions& o) {
  const auto at = spec.find('@');
  const std::string kind = spec.substr(0, at);
  const std::string arg = at == std::string::npos ? std::string() : spec.substr(at + 1);
  if (kind == "bus-off") {
    std::tie(o.faults.bus_off_at_s, o.faults.bus_off_s) = at_for(kind, arg);
  } else if (kind == "modbus-gone") {
    std::tie(o.faults.modbus_gone_at_s, o.faults.modbus_gone_s) = at_for(kind, arg);
  } else if (kind == "log-stall") {
    const auto [a, ms] = at_for(kind, arg);
    o.log_stall_after_s = a;
    o.log_stall_ms = static_cast<int>(ms);
  } else if (kind == "sampler-hang") {
    std::tie(o.faults.hang_at_s, o.faults.hang_s) = at_for(kind, arg);
  } else if (kind == "stuck") {
    std::tie(o.faults.stuck_at_s, o.faults.stuck_s) = at_for(kind, arg);
  } else if (kind == "nan") {
    std::tie(o.faults.nan_at_s, o.faults.nan_s) = at_for(kind, arg);
  } else if (kind == "encoder-glitch") {
    o.faults.glitch_every = static_cast<std::size_t>(to_number("--fault encoder-glitch", arg));
  } else if (kind == "can-reset") {
    std::tie(o.faults.can_reset_at_s, o.faults.can_reset_s) = at_for(kind, arg);
  } else if (kind == "short-frame") {
    o.faults.short_frame_at_s = to_number("--fault " + kind, arg);
  } else if (kind == "duplicate-frame") {
    o.faults.duplicate_frame_at_s = to_number("--fault " + kind, arg);
  } else if (kind == "swapped-frames") {
    o.faults.swapped_frames_at_s = to_number("--fault " + kind, arg);
  } else if (kind == "gpio-overflow") {
    const auto plus = arg.find('+');
    if (plus == std::string::npos) throw InputError("option --fault gpio-overflow: expected AT+EDGES, got '" + arg + "'");
    o.faults.gpio_overflow_at_s = to_number("--fault " + kind, arg.substr(0, plus));
    o.faults.gpio_overflow_edges = static_cast<std::size_t>(to_integer("--fault " + kind, arg.substr(plus + 1), 1, 1'000'000));
  } else {
    throw InputError("option --fault: unknown fault '" + kind +
                     "' (known: bus-off@AT+S, modbus-gone@AT+S, stuck@AT+S, nan@AT+S, sampler-hang@AT+S, log-stall@AT+MS, "
                     "encoder-glitch@N, can-reset@AT+S, short-frame@AT, duplicate-frame@AT, swapped-frames@AT, "
                     "gpio-overflow@AT+N)");
  }
}

volatile sig_atomic_t g_unused = 0;

// The controllers' heartbeat lease: renewed while every watched thread moved within it.
constexpr std::int64_t kLifeLeaseNs = 500'000'000;

std::string user_name(uid_t uid) {
  const passwd* pw = ::getpwuid(uid);
  return pw != nullptr ? pw->pw_name : "uid " + std::to_string(uid);
}

// --state-dir, else systemd's StateDirectory= (the first of $STATE_DIRECTORY's colon-separated
// paths), else the log's directory; empty: none.
std::filesystem::path run_record_dir(const DaemonOptions& o) {
  if (!o.state_dir.empty()) return o.state_dir;
  if (const char* state = std::getenv("STATE_DIRECTORY"); state != nullptr && *state != '\0') {
    const std::string first(state, std::strcspn(state, ":"));
    return first;
  }
  return o.log_dir;
}

}  // namespace

const char* usage() {
  return "usage: inertia-daqd --config FILE [--duration S] [--log DIR] [options]\n"
         "       inertia-daqd --check --config FILE\n"
         "       inertia-daqd mark --case NAME [--phase KIND] | --end | --stop [--socket PATH | --key FILE]  (mark --help)\n"
         "       inertia-daqd arm [--socket PATH]   start the plan on a daemon that runs it (arm --help)\n"
         "  --arm                real bench, executive = \"plan\": an attended start, the plan armed at\n"
         "                       once (otherwise the daemon starts disarmed, the controllers held in\n"
         "                       their safe state, until an operator runs inertia-daqd arm)\n"
         "  --state-dir DIR      where the run record is kept, which the next start reads to say how\n"
         "                       this run ended (default: $STATE_DIRECTORY, else the --log DIR)\n"
         "  --command-socket P   real bench: the operators' requests on this machine (inertia-daqd mark,\n"
         "                       arm) arrive on this Unix socket (default: $RUNTIME_DIRECTORY/command.sock,\n"
         "                       else /run/inertia/command.sock); who sent each is the kernel's word\n"
         "  --command-key FILE   the operators' keys: requests from other machines are taken only when\n"
         "                       signed with one (the file readable by owner and group only)\n"
         "  --operator-group G   who is an operator on this machine besides root and the daemon's user\n"
         "                       (default inertia-operators)\n"
         "  --check              open every device of the bench file without sampling and print one\n"
         "                       table: CAN interface up at the bench's bit rates, GPIO lines free,\n"
         "                       Modbus registers readable and in range; each failure with its\n"
         "                       bench-file line and the command that fixes it. Exit 0 when every\n"
         "                       required device is ready, 2 otherwise (optional = true devices are\n"
         "                       marked and do not count)\n"
         "  --config FILE        bench file (config/*.toml); its [daemon] table sets defaults for\n"
         "                       --log, --lcm-url, --block-ms, --rotate-mb, --fsync-ms, --log-queue,\n"
         "                       --ring, --fifo-priority, --cpu, --mlock (the command line wins)\n"
         "  --duration S         stop after S seconds (simulated seconds on a sim bench; default: the\n"
         "                       plan once on a sim bench, until SIGTERM on a real one)\n"
         "  --log DIR            durable event log (LCM log format) in DIR; SIGHUP starts a new file\n"
         "  --fast               sim bench: as fast as possible instead of paced in real time\n"
         "  --lcm-url URL        LCM provider (default: $LCM_DEFAULT_URL or LCM's default)\n"
         "  --block-ms MS        sample block length (default 10)\n"
         "  --rotate-mb MB       start a new log file past MB megabytes (default 256)\n"
         "  --fsync-ms MS        fflush + fsync the log at least every MS (default 1000)\n"
         "  --log-queue N        messages buffered for the log writer (default 512)\n"
         "  --ring N             samples buffered per device (default 131072)\n"
         "  --fifo-priority P    SCHED_FIFO priority of the sampling threads (default: off)\n"
         "  --cpu N              pin the sampling threads to CPU N\n"
         "  --mlock              mlockall(MCL_CURRENT | MCL_FUTURE)\n"
         "  --fault SPEC         sim bench fault: bus-off@AT+S, modbus-gone@AT+S, stuck@AT+S (first\n"
         "                       sensor frozen), nan@AT+S (first sensor reports no valid reading),\n"
         "                       sampler-hang@AT+S (CAN sampling thread sleeps; the\n"
         "                       watchdog must stop), log-stall@AT+MS, encoder-glitch@N (simulated s);\n"
         "                       with [bench.sim_timing]: can-reset@AT+S (the CAN adapter reboots, its\n"
         "                       counter restarts at 0), short-frame@AT, duplicate-frame@AT,\n"
         "                       swapped-frames@AT; gpio-overflow@AT+N (N edges of a GPIO\n"
         "                       encoder's line A lost from AT on)\n";
}

DaemonOptions parse_options(const std::vector<std::string>& args, bool* help) {
  DaemonOptions o;
  *help = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw InputError("option " + a + " needs a value");
      o.given.insert(a);
      return args[++i];
    };
    if (a == "--help" || a == "-h") *help = true;
    else if (a == "--check") o.check = true;
    else if (a == "--arm") {
      o.arm = true;
      o.given.insert(a);
    }
    else if (a == "--state-dir") o.state_dir = value();
    else if (a == "--command-socket") o.command_socket = value();
    else if (a == "--command-key") o.command_key = value();
    else if (a == "--operator-group") o.operator_group = value();
    else if (a == "--config") o.config = value();
    else if (a == "--duration") o.duration_s = to_number(a, value());
    else if (a == "--log") o.log_dir = value();
    else if (a == "--lcm-url") o.lcm_url = value();
    else if (a == "--fast") o.fast = true;
    else if (a == "--block-ms") o.block_ms = to_number(a, value());
    else if (a == "--rotate-mb") o.rotate_mb = to_number(a, value());
    else if (a == "--fsync-ms") o.fsync_ms = static_cast<int>(to_integer(a, value(), 1, Limits::kMaxFsyncMs));
    else if (a == "--log-queue") o.log_queue = static_cast<std::size_t>(to_integer(a, value(), 4, Limits::kMaxLogQueue));
    else if (a == "--ring") o.ring = static_cast<std::size_t>(to_integer(a, value(), 1024, Limits::kMaxRingSamples));
    else if (a == "--fifo-priority") o.fifo_priority = static_cast<int>(to_integer(a, value(), 0, Limits::kMaxFifoPriority));
    else if (a == "--cpu") o.cpu = static_cast<int>(to_integer(a, value(), -1, Limits::kMaxCpu));
    else if (a == "--mlock") {
      o.mlock = true;
      o.given.insert(a);
    }
    else if (a == "--fault") parse_fault(value(), o);
    else throw InputError("unknown option '" + a + "'\n" + usage());
  }
  if (*help) return o;
  if (o.config.empty()) throw InputError(std::string("--config FILE is required\n") + usage());
  if (o.check) {
    // --check opens the devices and samples nothing: a sampling option beside it would be ignored.
    for (const std::string& given : o.given)
      if (given != "--config") throw InputError("option " + given + ": --check samples nothing; give it --config FILE only");
    if (o.fast) throw InputError("option --fast: --check samples nothing; give it --config FILE only");
  }
  if (!(o.duration_s >= 0) || !std::isfinite(o.duration_s)) throw InputError("option --duration: must be >= 0 and finite");
  if (!(o.block_ms > 0) || o.block_ms > Limits::kMaxBlockMs)
    throw InputError(fmt::format("option --block-ms: must be in (0, {}]", Limits::kMaxBlockMs));
  if (!(o.rotate_mb > 0) || !std::isfinite(o.rotate_mb)) throw InputError("option --rotate-mb: must be > 0 and finite");
  if (o.fsync_ms < 1) throw InputError("option --fsync-ms: must be >= 1");
  if (o.log_queue < 4) throw InputError("option --log-queue: must be >= 4");
  if (o.ring < 1024) throw InputError("option --ring: must be >= 1024");
  return o;
}

void apply_bench_settings(DaemonOptions& o, const config::DaemonSettings& d) {
  auto take = [&o](const char* option, const auto& from_file, auto& target) {
    if (from_file && o.given.count(option) == 0) target = *from_file;
  };
  take("--log", d.log_dir, o.log_dir);
  take("--lcm-url", d.lcm_url, o.lcm_url);
  take("--state-dir", d.state_dir, o.state_dir);
  take("--command-socket", d.command_socket, o.command_socket);
  take("--command-key", d.command_key, o.command_key);
  take("--operator-group", d.operator_group, o.operator_group);
  take("--block-ms", d.block_ms, o.block_ms);
  take("--rotate-mb", d.rotate_mb, o.rotate_mb);
  take("--fsync-ms", d.fsync_ms, o.fsync_ms);
  take("--fifo-priority", d.fifo_priority, o.fifo_priority);
  take("--cpu", d.cpu_affinity, o.cpu);
  take("--mlock", d.mlock, o.mlock);
  if (d.log_queue && o.given.count("--log-queue") == 0) o.log_queue = static_cast<std::size_t>(*d.log_queue);
  if (d.ring_samples && o.given.count("--ring") == 0) o.ring = static_cast<std::size_t>(*d.ring_samples);
}

int run_daemon(const DaemonOptions& command_line) {
  const config::BenchConfig bench = config::load_bench_config(command_line.config);  // InputError -> exit 2
  DaemonOptions o = command_line;
  apply_bench_settings(o, bench.daemon);
  // What only a simulator can do is refused on a real bench rather than ignored.
  if (!bench.simulated && o.fast)
    throw InputError("option --fast: bench " + bench.name + " is real (backend = \"real\"): it samples in real time");
  if (!bench.simulated && o.given.count("--fault") != 0)
    throw InputError("option --fault: bench " + bench.name + " is real: faults are injected into the simulator only");
  if (o.arm && (bench.simulated || bench.executive != config::Executive::Plan))
    throw InputError("option --arm: bench " + bench.name +
                     (bench.simulated ? " is simulated: the simulator runs its plan by itself and commands no machinery"
                                      : " is moved by its operator (executive = \"operator\"): the daemon commands no motion to arm"));

  // Signals are taken synchronously by the supervisor: block them before any thread starts so
  // every thread inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  ::signal(SIGPIPE, SIG_IGN);
  (void)g_unused;

  const bool mlock_refused = o.mlock && ::mlockall(MCL_CURRENT | MCL_FUTURE) != 0;
  if (mlock_refused)
    std::cerr << "inertia-daqd: warning: mlockall: " << std::strerror(errno) << " (needs CAP_IPC_LOCK or LimitMEMLOCK); running without it\n";

  // LCM self-check: udpm needs a multicast route even on one host.
  const std::string url = !o.lcm_url.empty() ? o.lcm_url : (std::getenv("LCM_DEFAULT_URL") ? std::getenv("LCM_DEFAULT_URL") : "");
  const bool udpm = url.empty() || url.rfind("udpm://", 0) == 0;
  if (udpm && !has_multicast_route()) {
    std::cerr << "inertia-daqd: LCM needs a multicast route and this host has none (no 224.0.0.0/4 and no default route).\n"
                 "  fix: ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo\n";
    return kExitFailure;
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::cerr << "inertia-daqd: LCM failed to start on '" << (url.empty() ? "default" : url)
              << "'; if it reports no multicast route: ip route add 224.0.0.0/4 dev lo\n";
    return kExitFailure;
  }

  // Devices.
  std::unique_ptr<SimBench> sim;
  std::vector<std::unique_ptr<Sampler>> samplers;
  std::vector<std::string> absent;  // optional devices the bench runs without
  std::map<std::string, std::shared_ptr<ControllerPort>> controller_ports;  // real benches: for the test executive
  const auto life = std::make_shared<LifeSign>();   // renewed below while the daemon is healthy
  std::string why;
  if (bench.simulated) {
    // Threads the simulator starts here (its Modbus server) inherit this name, so CPU accounting
    // can tell the simulated bench from the daemon (tests/bench/daq_pipeline_benchmark.cpp).
    ::pthread_setname_np(::pthread_self(), "sim-setup");
    SimOptions so;
    so.fast = o.fast;
    so.fifo_priority = o.fifo_priority;
    so.duration_s = o.duration_s;
    so.faults = o.faults;
    sim = SimBench::create(bench, so, o.ring, &why);
    if (!sim) {
      std::cerr << "inertia-daqd: simulated bench " << bench.name << ": " << why << "\n";
      return kExitFailure;
    }
    samplers = sim->take_samplers();
    ::pthread_setname_np(::pthread_self(), "inertia-daqd");
  } else {
    life->renew(hal::monotonic_now_ns() + kLifeLeaseNs);   // the controllers' heartbeats start with the pollers
    RealBench real = open_real_bench(bench, o.ring, life, &why);
    if (real.samplers.empty()) {
      std::cerr << "inertia-daqd: " << why << "\n";
      return kExitBadInput;
    }
    samplers = std::move(real.samplers);
    controller_ports = std::move(real.ports);
    for (const LeftOutDevice& d : real.left_out) {
      absent.push_back(d.name);
      journal_fault({d.name, "absent", "absent", d.name + ": optional device left out, running degraded: " + d.why, 4,
                     std::nullopt, std::nullopt});
    }
  }
  for (auto& s : samplers) {
    if (!s->bring_up(&why)) {
      std::cerr << "inertia-daqd: " << why << "\n";
      return kExitBadInput;
    }
  }

  // The bench file travels with the data (INERTIA_BENCH): the log alone is enough to analyze.
  std::vector<std::uint8_t> bench_message;
  {
    bench_config_t msg{};
    timespec now{};
    ::clock_gettime(CLOCK_REALTIME, &now);
    msg.utime = static_cast<std::int64_t>(now.tv_sec) * 1'000'000 + now.tv_nsec / 1000;
    msg.bench_name = bench.name;
    for (const config::SourceFile& f : bench.sources) {
      msg.paths.push_back(f.path.string());
      msg.texts.push_back(f.text);
    }
    msg.num_files = static_cast<std::int32_t>(msg.paths.size());
    bench_message.resize(static_cast<std::size_t>(msg.getEncodedSize()));
    (void)msg.encode(bench_message.data(), 0, static_cast<int>(bench_message.size()));
    if (bench_message.size() > LogWriter::kMaxData) {
      std::cerr << "inertia-daqd: " << o.config << ": the bench file and its includes encode to " << bench_message.size()
                << " bytes on INERTIA_BENCH, more than one log slot holds (" << LogWriter::kMaxData << ")\n";
      return kExitBadInput;
    }
  }

  // Log writer.
  std::unique_ptr<LogWriter> log;
  if (!o.log_dir.empty()) {
    LogWriterOptions lo;
    lo.dir = o.log_dir;
    lo.base_name = bench.name;
    lo.rotate_bytes = static_cast<std::uint64_t>(o.rotate_mb * 1024 * 1024);
    lo.fsync_interval_ms = o.fsync_ms;
    lo.queue_slots = o.log_queue;
    lo.stall_after_s = o.log_stall_after_s;
    lo.stall_ms = o.log_stall_ms;
    log = std::make_unique<LogWriter>(lo);
    log->set_file_header(std::string(channels::kBench), bench_message);
    if (!log->open(&why)) {
      std::cerr << "inertia-daqd: " << why << "\n";
      return kExitBadInput;
    }
  } else {
    std::cerr << "inertia-daqd: warning: no --log DIR: nothing is recorded durably (live LCM only)\n";
  }

  // Publisher.
  std::vector<std::shared_ptr<DeviceSlot>> slots;
  for (auto& s : samplers) {
    // Samplers own their slot through a shared_ptr; hand the publisher the same objects.
    slots.push_back(std::shared_ptr<DeviceSlot>(std::shared_ptr<DeviceSlot>{}, &s->slot()));
  }
  PublisherOptions po;
  po.block_s = o.block_ms * 1e-3;
  po.bench_message = bench_message;
  po.log_backpressure = sim != nullptr && o.fast;
  timespec wall{}, mono{};
  ::clock_gettime(CLOCK_REALTIME, &wall);
  ::clock_gettime(CLOCK_MONOTONIC, &mono);
  po.mono_to_wall_ns = (static_cast<std::int64_t>(wall.tv_sec) - mono.tv_sec) * 1'000'000'000LL + (wall.tv_nsec - mono.tv_nsec);
  po.sim_t0_ns = hal::monotonic_now_ns() + 20'000'000;  // 20 ms for the threads to start
  // Markers come from the simulator on a sim bench and from the test executive on a real one;
  // either way their names and setpoints are the plan's.
  po.describe_mark = [&bench](const PlanMark& m, plan_event_t& e) { describe_plan_mark(bench, m, e); };
  LogWriter* log_ptr = log.get();
  std::unique_ptr<TestExecutive> executive;   // real benches: created below, before the publisher starts
  po.command_counts = [&executive] { return executive ? executive->command_counts() : std::array<std::int64_t, 3>{}; };
  po.daemon_faults = [log_ptr, absent, mlock_refused, &executive] {
    std::vector<std::string> f;
    if (executive) f = executive->faults();
    for (const std::string& name : absent) f.push_back("absent:" + name);
    if (mlock_refused) f.emplace_back("mlock-refused");
    if (log_ptr == nullptr) f.emplace_back("log-off");
    else if (log_ptr->disk_full()) f.emplace_back("disk-full");
    return f;
  };
  Publisher publisher(lcm, log.get(), slots, po);
  if (!publisher.configure(&why)) {
    std::cerr << "inertia-daqd: " << why << "\n";
    return kExitBadInput;
  }
  // A real bench's plan: run by the test executive on the controllers, or marked by the operator.
  // The run record tells the next start how this run ended.
  std::unique_ptr<RunRecorder> run_record;
  if (!sim) {
    const std::filesystem::path state_dir = run_record_dir(o);
    if (state_dir.empty())
      std::cerr << "inertia-daqd: warning: no --state-dir, $STATE_DIRECTORY or --log DIR: a crash leaves no run record for "
                   "the next start to report\n";
    run_record = std::make_unique<RunRecorder>(state_dir.empty() ? state_dir : state_dir / "inertia-daqd.run", bench.name);
    ExecutiveOptions eo;
    eo.lcm_url = url;
    // A socket asked for must open; the default one may be missing on a run by hand (no
    // /run/inertia): the daemon then takes no local request, and says so (nothing can arm it).
    const std::filesystem::path socket_path = o.command_socket.empty() ? default_command_socket() : std::filesystem::path(o.command_socket);
    std::error_code ec;
    if (!o.command_socket.empty() || std::filesystem::is_directory(socket_path.parent_path(), ec)) {
      eo.socket = CommandSocket::listen(socket_path, &why);
      if (!eo.socket) {
        std::cerr << "inertia-daqd: " << why << "\n";
        return kExitBadInput;
      }
    } else {
      std::cerr << "inertia-daqd: warning: " << socket_path.parent_path().string()
                << " does not exist: no command socket, so nothing on this machine can mark, stop or arm this daemon "
                   "(the service makes it; by hand, give --command-socket PATH)\n";
    }
    if (!o.command_key.empty()) eo.keys = load_command_keys(o.command_key);   // InputError -> exit 2
    eo.operator_group = o.operator_group;
    eo.operator_records = &publisher.operator_records();
    eo.arm_at_start = o.arm;
    eo.armed_by = "uid " + std::to_string(::getuid()) + " (" + user_name(::getuid()) + "), inertia-daqd --arm";
    eo.record = run_record.get();
    executive = std::make_unique<TestExecutive>(bench, controller_ports, publisher.plan_marks(), std::move(eo));
    if (!executive->ready(&why)) {
      std::cerr << "inertia-daqd: " << why << "\n";
      return kExitBadInput;
    }
  }

  if (log) log->start();
  const RealtimeOptions rt{o.fifo_priority, o.cpu};
  publisher.start(rt);
  for (auto& s : samplers) s->start(rt);
  if (sim) sim->start(po.sim_t0_ns, &publisher.plan_marks());
  if (executive) executive->start();

  std::ostringstream ready;
  ready << "READY=1\nSTATUS=sampling " << samplers.size() << " devices of bench " << bench.name
        << (bench.simulated ? (o.fast ? " (simulated, fast)" : " (simulated, paced)") : "");
  if (!absent.empty()) ready << " (degraded: " << absent.size() << " optional device" << (absent.size() > 1 ? "s" : "") << " absent)";
  if (executive)
    ready << (bench.executive == config::Executive::Plan
                  ? (o.arm ? "; the test executive runs the plan on the controllers (armed by --arm)"
                           : "; disarmed: the controllers are held in their safe state until an operator runs inertia-daqd arm")
                  : "; phases marked by the operator (inertia-daqd mark)");
  sd_notify(0, ready.str().c_str());
  std::cerr << "inertia-daqd: " << ready.str().substr(15) << "; log "
            << (log ? log->current_path() : std::string("off")) << "\n";

  // Supervisor.
  std::uint64_t watchdog_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &watchdog_usec) > 0 && watchdog_usec > 0;
  const std::int64_t watchdog_ns = static_cast<std::int64_t>(watchdog_usec) * 1000 / 2;
  // The threads whose stall the watchdog and the controllers' heartbeat lease follow: every
  // real-time sampler (Sampler::watched) and the publisher (the last entry).
  std::vector<std::uint64_t> beats(samplers.size() + 1, 0), lease_beats(samplers.size() + 1, 0);
  std::vector<std::int64_t> moved_ns(samplers.size() + 1, hal::monotonic_now_ns());
  auto beat_of = [&](std::size_t i) {
    return i < samplers.size() ? samplers[i]->slot().heartbeat.load(std::memory_order_relaxed) : publisher.heartbeat();
  };
  auto watched = [&](std::size_t i) { return i == samplers.size() || samplers[i]->watched(); };
  auto name_of = [&](std::size_t i) { return i < samplers.size() ? "sampling thread of " + samplers[i]->slot().name : std::string("publisher"); };
  std::vector<const DeviceSlot*> watched_slots;
  for (auto& s : samplers) watched_slots.push_back(&s->slot());
  FaultJournal fault_journal(std::move(watched_slots), hal::monotonic_now_ns());
  // invalid-samples: raised while a device pushed samples marked invalid within the last second.
  std::vector<std::uint64_t> invalid_seen(samplers.size(), 0);
  std::vector<std::int64_t> invalid_last_ns(samplers.size(), 0);
  std::int64_t last_ping = hal::monotonic_now_ns(), last_status = last_ping;
  const std::int64_t start = last_ping;
  bool stalled_reported = false;
  int exit_signal = 0;
  for (;;) {
    timespec timeout{0, 100'000'000};
    const int sig = sigtimedwait(&signals, nullptr, &timeout);
    if (sig == SIGHUP) {
      if (log) log->request_rotate();
      sd_notify(0, "STATUS=rotating the event log (SIGHUP)");
    } else if (sig == SIGTERM || sig == SIGINT) {
      exit_signal = sig;
      break;
    }
    const std::int64_t now = hal::monotonic_now_ns();
    for (std::size_t i = 0; i < samplers.size(); ++i) {
      DeviceSlot& slot = samplers[i]->slot();
      const std::uint64_t invalid = slot.invalid_samples.load(std::memory_order_relaxed);
      if (invalid != invalid_seen[i]) {
        invalid_seen[i] = invalid;
        invalid_last_ns[i] = now;
        slot.faults.fetch_or(kFaultInvalidSamples, std::memory_order_relaxed);
      } else if (invalid_last_ns[i] != 0 && now - invalid_last_ns[i] >= 1'000'000'000) {
        slot.faults.fetch_and(~kFaultInvalidSamples, std::memory_order_relaxed);
        invalid_last_ns[i] = 0;
      }
    }
    if (sim ? sim->finished() : (o.duration_s > 0 && now - start >= static_cast<std::int64_t>(o.duration_s * 1e9))) break;
    // The controllers' heartbeats go on while every watched thread moved within a lease.
    bool healthy = true;
    for (std::size_t i = 0; i < beats.size(); ++i) {
      if (!watched(i)) continue;
      const std::uint64_t b = beat_of(i);
      if (b != lease_beats[i]) moved_ns[i] = now;
      lease_beats[i] = b;
      healthy = healthy && now - moved_ns[i] < kLifeLeaseNs;
    }
    if (healthy) life->renew(now + kLifeLeaseNs);
    if (watchdog && now - last_ping >= watchdog_ns) {
      bool alive = true;
      for (std::size_t i = 0; i < beats.size(); ++i) {
        if (!watched(i)) continue;
        const std::uint64_t b = beat_of(i);
        if (b == beats[i]) {
          alive = false;
          if (!stalled_reported) std::cerr << "inertia-daqd: " << name_of(i) << " is not moving; withholding WATCHDOG=1\n";
          stalled_reported = true;
        }
        beats[i] = b;
      }
      if (alive) sd_notify(0, "WATCHDOG=1");
      last_ping = now;
    }
    if (now - last_status >= 1'000'000'000) {
      // Fault transitions go to the journal as structured entries as well as INERTIA_STATUS.
      fault_journal.update(now);
      std::uint64_t samples = 0, drops = 0;
      for (auto& s : samplers) {
        samples += s->slot().samples.load(std::memory_order_relaxed);
        drops += s->slot().ring_drops.load(std::memory_order_relaxed);
      }
      std::ostringstream st;
      st << "STATUS=" << samples << " samples, " << drops << " ring drops, " << publisher.messages() << " messages"
         << (log ? ", log lost " + std::to_string(log->messages_lost()) : std::string(", log off"));
      sd_notify(0, st.str().c_str());
      last_status = now;
    }
  }

  // Graceful stop: nothing that was sampled is lost. The simulator stops writing, each sampler
  // drains its wire into its ring, the publisher drains the rings, the writer drains its queue.
  // The controllers go to their safe state first, while their polling threads still run: a
  // running case is aborted (MARK_ABORT), and nothing is left moving after the daemon.
  if (executive) {
    sd_notify(0, "STATUS=stopping: controllers to their safe state");
    const std::string reason = exit_signal == SIGTERM ? "SIGTERM" : exit_signal == SIGINT ? "SIGINT" : "--duration reached";
    executive->stop(reason);
    if (!run_record->end("stopped (" + reason + "), safe state held", &why))
      std::cerr << "inertia-daqd: warning: the run record could not be written: " << why << "\n";
  }
  sd_notify(0, "STOPPING=1\nSTATUS=stopping: flushing rings and log");
  fault_journal.finish(hal::monotonic_now_ns());
  if (sim) {
    sim->stop();
    if (sim->real_timing())
      std::cerr << "inertia-daqd: simulated bench: " << sim->frames_lost() << " CAN frame(s) lost on purpose ([bench.sim_timing] frame_loss)\n";
    if (!command_line.fast) {
      const double behind_ms = sim->behind_schedule_s() * 1e3;
      std::cerr << fmt::format("inertia-daqd: simulated bench: at most {:.1f} ms behind its schedule\n", behind_ms);
      if (sim->real_timing() && sim->behind_schedule_s() > SimBench::kScheduleToleranceS)
        std::cerr << fmt::format(
            "inertia-daqd: warning: this host could not run the simulated devices on time (late by {:.1f} ms through a "
            "whole 0.1 s, more than {:.0f} ms): their receive stamps carry that delay as a slow sample clock's would, so "
            "this log's timing is the host's load, not [bench.sim_timing] (compare the clock drift below with clock_ppm); "
            "run it on a less loaded host\n",
            behind_ms, SimBench::kScheduleToleranceS * 1e3);
    }
  }
  for (auto& s : samplers) s->stop();
  if (sim) sim->stop_servers();
  publisher.stop();
  if (log) log->stop();

  const double run_s = static_cast<double>(hal::monotonic_now_ns() - start) * 1e-9;
  std::uint64_t channel_samples = 0;
  for (auto& s : samplers) channel_samples += s->slot().samples.load();
  std::cerr << "inertia-daqd: stopped" << (exit_signal ? (exit_signal == SIGTERM ? " (SIGTERM)" : " (SIGINT)") : "") << "\n";
  for (auto& s : samplers) {
    const DeviceSlot& d = s->slot();
    std::cerr << "  " << d.name << ": samples " << d.samples.load() << ", blocks " << d.blocks << ", ring drops "
              << d.ring_drops.load() << ", misaligned " << d.misaligned << ", ring high-water " << d.ring_high_water
              << "/" << d.ring.capacity() << ", decode errors " << d.decode_errors.load() << ", stuck "
              << d.stuck_invalid << ", invalid " << d.invalid_samples.load() << "\n";
  }
  std::cerr << "  run: seconds " << run_s << ", channel-samples " << channel_samples << ", per second "
            << static_cast<std::uint64_t>(static_cast<double>(channel_samples) / run_s) << "\n";
  std::cerr << "  lcm: messages " << publisher.messages() << ", publish failures " << publisher.publish_failures() << "\n";
  for (const std::string& line : publisher.clock_report()) std::cerr << "  " << line << "\n";
  if (log)
    std::cerr << "  log: messages " << log->messages_written() << ", lost " << log->messages_lost() << ", file headers "
              << log->headers_written() << ", bytes "
              << log->bytes_written() << ", files " << log->files().size() << ", queue high-water "
              << log->queue_high_water() << ", fsync max " << log->fsync_max_ms() << " ms, disk full lost "
              << log->disk_full_lost() << "\n";
  return kExitOk;
}

}  // namespace inertia::daq
