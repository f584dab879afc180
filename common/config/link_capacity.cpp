#include "common/config/link_capacity.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <map>
#include <numbers>
#include <sstream>
#include <utility>

#include "common/input_error.hpp"

namespace inertia::config {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// The peak of a Gaussian velocity, in sd: exceeded once in ~16000 samples, so a random phase of
// a few seconds at kHz reaches it.
constexpr double kRandomPeakSd = 4.0;

std::size_t fd_payload_length(std::size_t bytes) {
  constexpr std::array<std::size_t, 7> kLong{12, 16, 20, 24, 32, 48, 64};
  if (bytes <= 8) return bytes;
  for (std::size_t n : kLong)
    if (bytes <= n) return n;
  return 64;
}

std::size_t stuff_bits(std::size_t bits) { return bits == 0 ? 0 : (bits - 1) / 4; }

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

// The device a channel "device.signal" belongs to.
std::string device_of(const std::string& channel) { return channel.substr(0, channel.find('.')); }

struct Frame {
  std::size_t payload = 0;
  bool extended = false;
};

}  // namespace

double can_frame_time_s(std::size_t payload_bytes, bool extended_id, bool fd, double nominal_bps, double data_bps) {
  if (!fd) {
    // Davis et al. (2007) eq. (1): g = 34 (standard) or 54 (extended) bits are open to stuffing
    // besides the data; 13 more (CRC delimiter, ACK, EOF, intermission) are not.
    const std::size_t g = extended_id ? 54 : 34;
    const std::size_t stuffable = g + 8 * payload_bytes;
    return static_cast<double>(stuffable + 13 + stuff_bits(stuffable)) / nominal_bps;
  }
  const std::size_t n = fd_payload_length(payload_bytes);
  // At the nominal rate: SOF, identifier, RRS/SRR, IDE, FDF, res, BRS (dynamic stuffing), then
  // CRC delimiter, ACK, ACK delimiter, EOF and intermission (13, not stuffed).
  const std::size_t arbitration = extended_id ? 36 : 17;
  const double nominal_bits = static_cast<double>(arbitration + stuff_bits(arbitration) + 13);
  // At the data rate: ESI, DLC and data (dynamic stuffing), the stuff count (4) and CRC (17 up to
  // 16 bytes, else 21) with a fixed stuff bit before every 4 bits of them.
  const std::size_t crc = n <= 16 ? 17 : 21;
  const std::size_t dynamic = 5 + 8 * n;
  const std::size_t data_bits = dynamic + stuff_bits(dynamic) + 4 + crc + 1 + (4 + crc - 1) / 4;
  return nominal_bits / nominal_bps + static_cast<double>(data_bits) / data_bps;
}

std::vector<CanBusLoad> can_bus_loads(const BenchConfig& bench) {
  std::vector<CanBusLoad> buses;
  for (const CanDevice& d : bench.can_devices) {
    if (d.sample_rate_hz <= 0.0) continue;   // no expected rate: nothing to check against
    auto it = std::find_if(buses.begin(), buses.end(), [&](const CanBusLoad& b) { return b.interface == d.interface; });
    if (it == buses.end()) {
      CanBusLoad b;
      b.interface = d.interface;
      b.fd = d.fd;
      b.rates_assumed = d.bitrate == 0;
      b.nominal_bps = d.bitrate != 0 ? d.bitrate : kClassicCanMaxBitRate;
      b.data_bps = !d.fd ? b.nominal_bps : (d.dbitrate != 0 ? d.dbitrate : kCanFdMaxDataBitRate);
      buses.push_back(b);
      it = std::prev(buses.end());
    }
    // One frame per identifier per sample period, as long as its furthest signal reaches.
    std::map<std::pair<std::uint32_t, bool>, Frame> frames;
    for (const CanSignal& s : d.signals) {
      Frame& f = frames[{s.id, s.extended}];
      f.extended = s.extended;
      f.payload = std::max<std::size_t>(f.payload, (8 * s.byte_offset + s.bit_offset + s.bit_length + 7) / 8);
    }
    for (const auto& [key, f] : frames) {
      it->load += d.sample_rate_hz * can_frame_time_s(f.payload, f.extended, it->fd, it->nominal_bps, it->data_bps);
      it->frames_per_s += d.sample_rate_hz;
    }
  }
  return buses;
}

double encoder_peak_speed(const BenchConfig& bench, const GpiodEncoder& e) {
  if (bench.table_encoder.present && device_of(bench.table_encoder.channel) == e.name) return motion_peak_speed(bench, true);
  if (bench.linear_encoder.present && device_of(bench.linear_encoder.channel) == e.name) return motion_peak_speed(bench, false);
  return 0.0;
}

double motion_peak_speed(const BenchConfig& bench, bool table) {
  const bool armature = !table;
  double peak = 0.0;
  for (const TestCase& c : bench.cases) {
    for (const Phase& p : c.phases) {
      double v = 0.0;
      if (table && p.kind == PhaseKind::Rotation) {
        if (p.rate_rad_s) v = std::abs(*p.rate_rad_s);
        else if (p.angle_rad && p.duration_s > 0.0) v = 2.0 * std::abs(*p.angle_rad) / p.duration_s;
      } else if (armature && p.kind == PhaseKind::Sine && p.frequency_hz > 0.0) {
        v = std::abs(p.amplitude_mps2) / (kTwoPi * p.frequency_hz);
      } else if (armature && p.kind == PhaseKind::Random && p.f1_hz > 0.0) {
        v = kRandomPeakSd * p.rms_mps2 / (kTwoPi * std::sqrt(p.f1_hz * p.f2_hz));
      } else if (armature && p.kind == PhaseKind::Shock) {
        v = 2.0 * std::abs(p.peak_mps2) * p.pulse_s / std::numbers::pi;
      }
      peak = std::max(peak, v);
    }
  }
  return peak;
}

double gpio_line_edge_capacity(const GpiodEncoder& e) {
  return static_cast<double>(kGpioLineEventQueue) / (static_cast<double>(e.edge_latency_ns) * 1e-9);
}

void check_link_capacity(const BenchConfig& bench) {
  for (const CanBusLoad& b : can_bus_loads(bench)) {
    if (b.load <= kMaxCanBusLoad) continue;
    const auto d = std::find_if(bench.can_devices.begin(), bench.can_devices.end(),
                                [&](const CanDevice& x) { return x.interface == b.interface; });
    std::string rates = b.fd ? "CAN FD at " + fixed(b.nominal_bps / 1e6, 2) + "/" + fixed(b.data_bps / 1e6, 2) + " Mbit/s"
                             : "classic CAN at " + fixed(b.nominal_bps / 1e6, 2) + " Mbit/s";
    if (b.rates_assumed) rates += " (no bitrate given: the fastest " + std::string(b.fd ? "CAN FD" : "classic CAN") + " allows)";
    throw InputError(d->availability.where,
                     "interface '" + b.interface + "' cannot carry its devices' frames: " + fixed(b.frames_per_s, 0) +
                         " frames/s take " + fixed(100.0 * b.load, 0) + " % of the bus at worst-case bit stuffing on " +
                         rates + ", above the " + fixed(100.0 * kMaxCanBusLoad, 0) +
                         " % a bus can be planned for. Use CAN FD (fd = true) with a data-phase rate (dbitrate) that "
                         "carries them, pack more signals per frame, or split the devices over more interfaces");
  }
  for (const GpiodEncoder& e : bench.gpiod_encoders) {
    const double edges_per_line = quadrature_edges_per_line(encoder_peak_speed(bench, e), e.resolution);
    const double capacity = gpio_line_edge_capacity(e);
    if (edges_per_line <= capacity) continue;
    throw InputError(e.availability.where,
                     "encoder '" + e.name + "' on GPIO lines cannot follow the plan's fastest motion: " +
                         fixed(edges_per_line, 0) + " edges/s per line at resolution " + fixed(e.resolution * 1e6, 3) +
                         " (micro-units per count), while gpiolib queues " + std::to_string(kGpioLineEventQueue) +
                         " events per line, which with edge_latency_ns = " + std::to_string(e.edge_latency_ns) +
                         " carries at most " + fixed(capacity, 0) +
                         " edges/s; beyond it edges are dropped without a word. Read this encoder through a counter "
                         "that reports counts (a counter card, or a microcontroller on CAN FD: config/bench-template.toml), "
                         "or give it a coarser resolution or the plan a slower motion");
  }
}

}  // namespace inertia::config
