#pragma once
// The publisher's wake-up when a sampling thread has put samples in its ring (publisher.hpp): a
// block goes out as soon as its last sample is in, not at the publisher's next idle poll. That
// poll (1 ms) would be most of the daemon's sample-to-publish time (docs/validation.md, "Latency
// under load").
// An eventfd: ring() is one non-blocking write(2) that never waits and never allocates, fit for
// a sampling thread; wait() sleeps in poll(2) until a ring or the timeout, and clears the count.
// A ring between the publisher's drain and its wait leaves the count set, so no wake-up is lost.
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <system_error>

#include "hal/unique_fd.hpp"

namespace inertia::daq {

class Doorbell {
 public:
  Doorbell() : fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
    if (!fd_.valid()) throw std::system_error(errno, std::generic_category(), "eventfd for the publisher's wake-up");
  }

  void ring() noexcept {
    const std::uint64_t one = 1;
    // Fails only when the count would pass 2^64 - 2: a wake-up is pending then anyway.
    (void)!::write(fd_.get(), &one, sizeof one);
  }

  /// True when rung since the last wait (the count is cleared), false after timeout_ms.
  bool wait(int timeout_ms) noexcept {
    pollfd p{fd_.get(), POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    std::uint64_t count = 0;
    return ::read(fd_.get(), &count, sizeof count) == static_cast<ssize_t>(sizeof count);
  }

 private:
  hal::UniqueFd fd_;
};

}  // namespace inertia::daq
