#pragma once
// inertia-daqd: command line, start-up checks, the thread layout and the service protocol.
//
// Threads: one sampling thread per device (sampler.hpp), the simulator's driver on simulated
// benches (sim_bench.hpp), the test executive on real ones (test_executive.hpp: the plan on the
// controllers, or the operator's marks), the publisher (publisher.hpp), the log writer
// (log_writer.hpp), and the main thread as supervisor: signals (SIGTERM/SIGINT stop, SIGHUP rotates the log),
// sd_notify READY/STATUS/WATCHDOG/STOPPING. WATCHDOG=1 is sent only when every real-time sampling
// thread's heartbeat and the publisher's moved since the previous ping, so a hung sampler gets the
// daemon restarted; the same proof renews the controllers' heartbeat lease (life_sign.hpp).
#include <set>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/lcm/multicast_route.hpp"
#include "daq/sim_bench.hpp"

namespace inertia::daq {

struct DaemonOptions {
  std::string config;
  double duration_s = 0.0;      // <= 0: until SIGTERM (real) / the plan once (sim); sim: simulated seconds
  std::string log_dir;          // empty: no durable log (a warning, and "log-off" on INERTIA_STATUS)
  std::string lcm_url;          // empty: LCM_DEFAULT_URL or LCM's default
  bool fast = false;
  double block_ms = 10.0;
  double rotate_mb = 256.0;
  int fsync_ms = 1000;
  std::size_t log_queue = 512;
  std::size_t ring = 1 << 17;
  int fifo_priority = 0;
  int cpu = -1;
  bool mlock = false;
  bool check = false;           // --check: open every device without sampling, print the table, exit
  bool arm = false;             // --arm: an attended start, the plan armed at once (executive = "plan")
  std::string state_dir;        // --state-dir: the run record's directory (empty: $STATE_DIRECTORY, else the log's)
  std::string command_socket;   // --command-socket: empty: $RUNTIME_DIRECTORY/command.sock, else /run/inertia/command.sock
  std::string command_key;      // --command-key: the operators' key file (empty: no signed requests)
  std::string operator_group = "inertia-operators";   // --operator-group: name or gid
  double log_stall_after_s = -1.0;
  int log_stall_ms = 0;
  SimFaults faults;
  /// The options given on the command line ("--block-ms", ...): they win over the bench file.
  std::set<std::string> given;
};

/// Settings of the bench file's [daemon] table for every option the command line did not give.
void apply_bench_settings(DaemonOptions& options, const config::DaemonSettings& settings);

/// Parses argv. Throws InputError naming the option on bad input. `help` set for --help.
DaemonOptions parse_options(const std::vector<std::string>& args, bool* help);
const char* usage();

/// Whether the routing table covers 224.0.0.0/4 (common/lcm/multicast_route.hpp).
using inertia::has_multicast_route;

/// Runs the daemon; returns the exit status (0 ok, 1 failure, 2 bad input).
int run_daemon(const DaemonOptions& options);

}  // namespace inertia::daq
