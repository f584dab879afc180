#pragma once
// Whether the lines an encoder is wired to can be had: the chip opens, each line exists, no one
// else holds it, and it accepts a both-edge event request (then released again). What
// GpiodEdgeSource::open() needs, asked line by line so that a failure names its line, for
// inertia-daqd --check and for the daemon's start-up message. Not real-time.
#include <string>
#include <vector>

namespace inertia::hal::gpiod {

struct LineProbe {
  unsigned offset = 0;
  bool exists = false;          // offset < the chip's line count
  bool used = false;            // held by a consumer (the kernel, a driver, another program)
  std::string consumer;         // who holds it, as gpioinfo prints it
  bool requestable = false;     // a both-edge event request succeeded (released at once)
  int request_errno = 0;        // why the request failed (EBUSY, EPERM, EIO ...)
};

struct ChipProbe {
  bool opened = false;
  int open_errno = 0;           // ENOENT: no such chip; EACCES: not in the chip's group
  bool any_chip = false;        // whether /dev/gpiochip* exists at all on this machine
  std::string name, label;      // "gpiochip0", "pinctrl-bcm2711" (set when opened)
  unsigned lines = 0;
  std::vector<LineProbe> probes;  // one per offset asked, in order
};

/// Opens `chip` (gpiod_chip_open_lookup(): name, path, label or number) and probes `offsets`.
/// `consumer` is the name the short request carries ("inertia-daqd --check").
ChipProbe probe_lines(const std::string& chip, const std::vector<unsigned>& offsets, const std::string& consumer);

}  // namespace inertia::hal::gpiod
