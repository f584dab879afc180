#pragma once
// `inertia-daqd mark` and `inertia-daqd arm`: the operator's marks for a bench whose motion the
// daemon does not command, the operator stop, and the arm of a plan the daemon runs. On the bench
// PC a request goes through the daemon's command socket, which knows the caller from the kernel
// (daq/command_socket.hpp); from another machine it goes on LCM signed with the operators'
// command key (--key FILE; daq/command_auth.hpp), repeated until answered (UDP can lose it; the
// daemon acts on one request once). The daemon stamps the markers itself.
//   inertia-daqd mark --case NAME [--phase KIND|INDEX]   start a case (if not running) and a phase
//   inertia-daqd mark --end                              end the running case
//   inertia-daqd mark --stop                             operator stop: controllers to their safe state
//   inertia-daqd arm                                     run the plan (executive = "plan")
// Exit status: 0 accepted, 2 refused ("not authorized: ...") or bad options, 1 no answer.
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
