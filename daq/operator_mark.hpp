#pragma once
// `inertia-daqd mark` and `inertia-daqd arm`: the operator's marks for a bench whose motion the
// daemon does not command, the operator stop, and the arm of a plan the daemon runs. Sends a plan_command_t on INERTIA_COMMAND to the running daemon and waits for its
// answer on INERTIA_COMMAND_REPLY, repeating the request until answered (LCM is UDP: a request
// can be lost; the daemon acts on a repeated request once). The daemon stamps the markers itself.
//   inertia-daqd mark --case NAME [--phase KIND|INDEX]   start a case (if not running) and a phase
//   inertia-daqd mark --end                              end the running case
//   inertia-daqd mark --stop                             operator stop: abort, controllers to safe state
// Options: --lcm-url URL (default: the bench's [daemon] lcm_url with --config FILE, else
// $LCM_DEFAULT_URL, else LCM's default), --timeout S (default 3).
// Exit status: 0 accepted, 2 refused or bad options (the answer says why), 1 no answer.
#include <string>
#include <vector>

namespace inertia::daq {

/// `args` after "mark". Prints the daemon's answer (stdout) or the failure (stderr).
int run_mark(const std::vector<std::string>& args);
const char* mark_usage();
/// `args` after "arm": the operator arms the plan (plan_command_t::COMMAND_ARM), as `mark`.
int run_arm(const std::vector<std::string>& args);
const char* arm_usage();

}  // namespace inertia::daq
