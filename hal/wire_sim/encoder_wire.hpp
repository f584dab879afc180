#pragma once
// The encoder's wire as this machine allows it (a kernel without GPIO chips): one pipe per line
// carrying the kernel's struct gpioevent_data records (16 bytes, <linux/gpio.h>), which is
// exactly what libgpiod's gpiod_line_event_read_fd_multiple() reads from a line event fd.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "hal/gpiod/encoder_device.hpp"
#include "hal/unique_fd.hpp"

namespace inertia::hal::wire_sim {

/// Writer side. Thread: one writer thread (the simulator or a test).
class EncoderWire {
 public:
  struct Lines {
    bool marker = false, trigger = false;
    bool a0 = false, b0 = false;        // levels at the start
  };
  /// The edge source for GpiodEncoderDevice::from_source() and the writer, or nullptr + why.
  static std::unique_ptr<EncoderWire> create(const Lines& lines, std::string* why);

  /// Hands out the read side (once). It reports the levels last written here.
  std::unique_ptr<gpiod::EdgeSource> take_source();

  /// Writes one record; false when the pipe is full (EAGAIN) or the line does not exist. The
  /// levels the source reports (EdgeSource::levels()) are then those after it, at its time.
  bool write(const gpiod::EdgeEvent& event);
  /// The levels of A and B at t_ns (>= 0), for a writer of raw records (write_raw): what a chip
  /// would read on the lines then, whatever records reached (or were lost from) the pipes.
  void set_levels(bool a, bool b, std::int64_t t_ns);
  /// The wire's clock, as a kernel's: every edge of `line` stamped at or before t_ns has been
  /// written (the reader's EdgeSource::complete_through_ns()). Call it after the writes, never
  /// before: a reader trusting it too early merges edges out of order. Starts at "never".
  void advance(gpiod::EdgeLine line, std::int64_t t_ns);
  void advance_all(std::int64_t t_ns);
  /// Raw bytes on a line's pipe (partial records for fault tests).
  bool write_raw(gpiod::EdgeLine line, const void* bytes, std::size_t size);

 private:
  EncoderWire() = default;
  struct Shared {
    std::array<std::atomic<bool>, gpiod::kEdgeLineCount> level{};
    // A's level in bit 0, B's in bit 1, their time above (one word: read together). ~0: none yet.
    std::atomic<std::uint64_t> levels{~std::uint64_t{0}};
    std::array<std::atomic<std::int64_t>, gpiod::kEdgeLineCount> through{};
    std::array<UniqueFd, gpiod::kEdgeLineCount> read_end;
  };
  std::shared_ptr<Shared> shared_;
  std::array<UniqueFd, gpiod::kEdgeLineCount> write_end_;
  bool taken_ = false;
};

}  // namespace inertia::hal::wire_sim
