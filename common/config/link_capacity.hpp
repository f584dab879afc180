#pragma once
// Whether a real bench's links can carry the rates its bench file asks of them, checked
// once at load so that a bench that would lose data silently is refused with the numbers instead:
//   - a CAN bus: the worst-case time of every frame the bench expects on it (bit stuffing at its
//     worst, CAN FD's two bit rates) against the bus's bit rate;
//   - a quadrature encoder on GPIO lines: the edge rate the plan's fastest motion produces on one
//     line against what gpiolib's per-line event queue holds while the reader is away.
// Not real-time: used once, at load.
#include <cstddef>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"

namespace inertia::config {

/// Bus load above which a CAN bus is refused: error frames, retransmissions and other nodes need
/// the rest, and worst-case stuffing is already assumed (a common design ceiling for CAN).
inline constexpr double kMaxCanBusLoad = 0.8;
/// gpiolib's character device (v1 line events, which libgpiod 1.6 uses) queues 16 events per
/// line (drivers/gpio/gpiolib-cdev.c, the lineevent kfifo); the 17th edge before the reader
/// drains the queue is dropped without a word.
inline constexpr std::size_t kGpioLineEventQueue = 16;
/// The fastest bit rates the two CAN kinds allow (ISO 11898-1): the assumption when the bench
/// file gives none, so that only a bench no bus could carry is refused.
inline constexpr double kClassicCanMaxBitRate = 1.0e6;
inline constexpr double kCanFdMaxDataBitRate = 8.0e6;

/// Worst-case duration (s) of one data frame with `payload_bytes` of data: classic CAN after
/// Davis et al. (2007), eq. (1); CAN FD with its arbitration at `nominal_bps` and its data phase
/// at `data_bps` (bit-rate switch), the stuff count and fixed CRC stuff bits of ISO 11898-1:2015.
/// A CAN FD payload is rounded up to the next length a DLC can code (12, 16, 20, 24, 32, 48, 64).
double can_frame_time_s(std::size_t payload_bytes, bool extended_id, bool fd, double nominal_bps, double data_bps);

/// Worst-case load of one CAN interface's frames, summed over every [[can_device]] on it.
struct CanBusLoad {
  std::string interface;
  double load = 0.0;                // fraction of the bus's time, worst case
  double frames_per_s = 0.0;
  double nominal_bps = 0.0;         // as used (the file's, or the kind's maximum when it gives none)
  double data_bps = 0.0;            // CAN FD; equal to nominal_bps on classic CAN
  bool fd = false;
  bool rates_assumed = false;       // the file gives no bitrate: the kind's maximum was assumed
};
std::vector<CanBusLoad> can_bus_loads(const BenchConfig& bench);

/// Peak speed (m/s or rad/s) the plan's motion gives encoder `e` (0 when the encoder is neither
/// the table's nor the shaker armature's, or the plan never moves it): the table from its rotation
/// phases' rate (an angle move's (1 - cos) profile peaks at 2 angle / duration); the armature from
/// sine (A / 2 pi f), random (4 sd of the velocity of a flat acceleration PSD: a_rms / (2 pi
/// sqrt(f1 f2))) and shock (the pulse's whole velocity change, 2 peak pulse / pi) phases.
double encoder_peak_speed(const BenchConfig& bench, const GpiodEncoder& e);
/// The same for the table's motion (`table`) or the shaker armature's, whichever device reads it.
double motion_peak_speed(const BenchConfig& bench, bool table);

/// Edges per second on each line of an x4 quadrature encoder of `resolution` (SI per count) at
/// `speed`: every edge of A and of B is a count.
inline double quadrature_edges_per_line(double speed, double resolution) { return speed / resolution / 2.0; }

/// Edges per second one line of the encoder can carry: kGpioLineEventQueue edges in the time the
/// reader may be away (the encoder's edge_latency_ns).
double gpio_line_edge_capacity(const GpiodEncoder& e);

/// Throws InputError at the device's table, with the numbers and what to change, when a CAN bus
/// would be loaded above kMaxCanBusLoad or an encoder line would see more edges per second than
/// gpio_line_edge_capacity. Called by the loader on real benches.
void check_link_capacity(const BenchConfig& bench);

}  // namespace inertia::config
