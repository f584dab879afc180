#pragma once
// A test whose real part cannot run here (no multicast route for LCM, not root for a small tmpfs
// or a mount namespace, a tool missing) skips with the reason on a developer's machine, and fails
// under CI=true: CTest counts a skip as a pass, so a CI machine without the route
// would be green with the daemon untested. .ci/run (through inertia.sh) sets up what these tests
// need and runs as root. Tests of kernel features this machine's kernel lacks (vcan, gpio-sim)
// skip everywhere, with the reason: no script can give a kernel a module it does not have.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string_view>

namespace inertia::testing {

/// CI=true, as .ci/run runs (the same switch that makes warnings errors, CMakeLists.txt).
inline bool ci_requires_real_run() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string_view(ci) == "true";
}

}  // namespace inertia::testing

/// Skips the current test with `reason`, or fails it with `reason` under CI=true. A statement;
/// returns from the test body either way.
#define INERTIA_SKIP_OR_FAIL_IN_CI(reason)                                                  \
  do {                                                                                    \
    if (::inertia::testing::ci_requires_real_run()) {                                     \
      GTEST_FAIL() << "CI=true, so this test must run its real part, but: " << (reason);  \
    } else {                                                                              \
      GTEST_SKIP() << (reason);                                                           \
    }                                                                                     \
  } while (false)
