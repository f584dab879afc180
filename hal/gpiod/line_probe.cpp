#include "hal/gpiod/line_probe.hpp"

#include <glob.h>
#include <gpiod.h>

#include <cerrno>

namespace inertia::hal::gpiod {

ChipProbe probe_lines(const std::string& chip, const std::vector<unsigned>& offsets, const std::string& consumer) {
  ChipProbe out;
  glob_t g{};
  out.any_chip = ::glob("/dev/gpiochip*", 0, nullptr, &g) == 0 && g.gl_pathc > 0;
  ::globfree(&g);
  gpiod_chip* handle = ::gpiod_chip_open_lookup(chip.c_str());
  if (handle == nullptr) {
    out.open_errno = errno;
    return out;
  }
  out.opened = true;
  out.name = ::gpiod_chip_name(handle);
  out.label = ::gpiod_chip_label(handle);
  out.lines = ::gpiod_chip_num_lines(handle);
  for (const unsigned offset : offsets) {
    LineProbe p;
    p.offset = offset;
    p.exists = offset < out.lines;
    gpiod_line* line = p.exists ? ::gpiod_chip_get_line(handle, offset) : nullptr;
    if (line != nullptr) {
      p.used = ::gpiod_line_is_used(line);
      if (const char* c = ::gpiod_line_consumer(line)) p.consumer = c;
      if (::gpiod_line_request_both_edges_events(line, consumer.c_str()) == 0) {
        p.requestable = true;
        ::gpiod_line_release(line);
      } else {
        p.request_errno = errno;
      }
    }
    out.probes.push_back(std::move(p));
  }
  ::gpiod_chip_close(handle);
  return out;
}

}  // namespace inertia::hal::gpiod
