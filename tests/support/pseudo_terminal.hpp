#pragma once
// Whether this machine can make a pseudo-terminal pair, which the Modbus RTU tests use as their
// serial line (hal/wire_sim/modbus_tcp_server.hpp, rtu_link). A container without /dev/pts (or
// /dev/ptmx) cannot: those tests then skip with the reason, and fail under CI=true, where the
// serial path must run (tests/support/skip_or_fail.hpp).
#include <pty.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <optional>
#include <string>

#include "tests/support/skip_or_fail.hpp"

namespace inertia::testing {

/// Empty when openpty() works here; otherwise why it does not, with what would fix it.
inline std::optional<std::string> pseudo_terminals_missing() {
  int master = -1, slave = -1;
  if (::openpty(&master, &slave, nullptr, nullptr, nullptr) == 0) {
    ::close(master);
    ::close(slave);
    return std::nullopt;
  }
  return std::string("this machine cannot make a pseudo-terminal pair (openpty: ") + std::strerror(errno) +
         "), which the Modbus RTU tests use as their serial line: mount devpts on /dev/pts "
         "(mount -t devpts devpts /dev/pts) or run in a container that has it";
}

}  // namespace inertia::testing

/// In a test body or SetUp(): skips (or fails under CI=true) when no pseudo-terminal can be made.
#define INERTIA_REQUIRE_PSEUDO_TERMINALS()                                                      \
  do {                                                                                          \
    if (const auto inertia_pty_missing = ::inertia::testing::pseudo_terminals_missing())        \
      INERTIA_SKIP_OR_FAIL_IN_CI(*inertia_pty_missing);                                         \
  } while (false)
