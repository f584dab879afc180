// Whether a real bench's links carry its rates: CAN frame times against the published
// worst cases, bus loads summed per interface, encoder edge rates from the plan's fastest motion,
// and the loader refusing what a link cannot carry, at the device's table, with the numbers.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/config/link_capacity.hpp"
#include "common/input_error.hpp"

namespace {

using inertia::InputError;
using namespace inertia::config;
namespace fs = std::filesystem;

TEST(CanFrameTime, ClassicFramesMatchTheWorstCasesOfDavisEtAl) {
  // Davis, Burns, Bril, Lukkien (2007), section 3: 8 data bytes take at most 135 bits with an
  // 11-bit identifier and 160 with a 29-bit one; an empty frame 55 and 80.
  EXPECT_DOUBLE_EQ(can_frame_time_s(8, false, false, 1e6, 1e6), 135e-6);
  EXPECT_DOUBLE_EQ(can_frame_time_s(8, true, false, 1e6, 1e6), 160e-6);
  EXPECT_DOUBLE_EQ(can_frame_time_s(0, false, false, 1e6, 1e6), 47e-6 + 8e-6);
  EXPECT_DOUBLE_EQ(can_frame_time_s(0, true, false, 500e3, 500e3), 80.0 / 500e3);
}

TEST(CanFrameTime, FdFramesLieBetweenTheirUnstuffedLengthAndAFifthMore) {
  // Unstuffed CAN FD frame: SOF..BRS (17 standard, 36 extended) + CRC delimiter..intermission
  // (13) at the nominal rate; ESI + DLC (5) + data + stuff count (4) + CRC (17 / 21) at the data
  // rate. Stuffing adds at most one bit per four.
  for (bool extended : {false, true}) {
    for (std::size_t n : {std::size_t{0}, std::size_t{8}, std::size_t{16}, std::size_t{64}}) {
      const double nominal = (extended ? 36.0 : 17.0) + 13.0;
      const double data = 5.0 + 8.0 * static_cast<double>(n) + 4.0 + (n <= 16 ? 17.0 : 21.0);
      const double unstuffed = nominal / 1e6 + data / 5e6;
      const double t = can_frame_time_s(n, extended, true, 1e6, 5e6);
      EXPECT_GT(t, unstuffed) << n;
      EXPECT_LE(t, 1.25 * unstuffed) << n;
    }
  }
  // A payload no DLC codes is sent as the next length that one does: 9 bytes go as 12.
  EXPECT_DOUBLE_EQ(can_frame_time_s(9, false, true, 1e6, 5e6), can_frame_time_s(12, false, true, 1e6, 5e6));
  // At equal rates the bit-rate switch buys nothing: a classic frame is shorter than its FD twin.
  EXPECT_LT(can_frame_time_s(8, false, false, 1e6, 1e6), can_frame_time_s(8, false, true, 1e6, 1e6));
}

// A real bench with one CAN device of `frames` frames of `bytes` bytes each at `rate_hz`.
BenchConfig can_bench(int frames, unsigned bytes, double rate_hz, bool fd, std::uint32_t bitrate, std::uint32_t dbitrate) {
  BenchConfig b;
  b.simulated = false;
  CanDevice d;
  d.name = "adc";
  d.interface = "can0";
  d.sample_rate_hz = rate_hz;
  d.fd = fd;
  d.bitrate = bitrate;
  d.dbitrate = dbitrate;
  for (int f = 0; f < frames; ++f) {
    CanSignal s;
    s.name = "s" + std::to_string(f);
    s.id = 0x100 + static_cast<std::uint32_t>(f);
    s.bit_length = 8 * bytes;
    d.signals.push_back(s);
  }
  b.can_devices.push_back(d);
  return b;
}

TEST(CanBusLoad, SumsEveryFrameOfEveryDeviceOnTheInterface) {
  BenchConfig b = can_bench(1, 6, 10000.0, false, 1000000, 0);
  // One 6-byte standard frame: 34 + 48 + 13 + 20 = 115 bits, 10000 times a second on 1 Mbit/s.
  auto loads = can_bus_loads(b);
  ASSERT_EQ(loads.size(), 1u);
  EXPECT_NEAR(loads[0].load, 1.15, 1e-12);
  EXPECT_DOUBLE_EQ(loads[0].frames_per_s, 10000.0);
  // A second device on the same interface adds; one on another interface is its own bus.
  BenchConfig two = b;
  two.can_devices.push_back(b.can_devices[0]);
  two.can_devices.back().name = "adc2";
  two.can_devices.back().sample_rate_hz = 1000.0;
  loads = can_bus_loads(two);
  ASSERT_EQ(loads.size(), 1u);
  EXPECT_NEAR(loads[0].load, 1.15 + 0.115, 1e-12);
  two.can_devices.back().interface = "can1";
  EXPECT_EQ(can_bus_loads(two).size(), 2u);
  // Signals sharing an identifier share a frame: its length is the furthest signal's end.
  BenchConfig shared = can_bench(1, 2, 1000.0, false, 1000000, 0);
  CanSignal second = shared.can_devices[0].signals[0];
  second.name = "t";
  second.byte_offset = 4;
  shared.can_devices[0].signals.push_back(second);
  EXPECT_NEAR(can_bus_loads(shared)[0].load, 1000.0 * can_frame_time_s(6, false, false, 1e6, 1e6), 1e-12);
}

TEST(CanBusLoad, TheIssuesClassicBusIsRefusedAndItsFdTwinAccepted) {
  // Two 24-bit sensors at 10 kHz in one 6-byte frame need 1.15 Mbit/s: beyond classic CAN.
  BenchConfig classic = can_bench(1, 6, 10000.0, false, 1000000, 0);
  try {
    check_link_capacity(classic);
    ADD_FAILURE() << "a classic CAN bus at 115 % was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("interface 'can0'"), std::string::npos) << what;
    EXPECT_NE(what.find("115 %"), std::string::npos) << what;
    EXPECT_NE(what.find("fd = true"), std::string::npos) << what;
  }
  // Without a bitrate the fastest classic CAN is assumed, and said.
  try {
    check_link_capacity(can_bench(1, 6, 10000.0, false, 0, 0));
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no bitrate given"), std::string::npos) << e.what();
  }
  // CAN FD at 1/5 Mbit/s carries the same frames: 34 bits at 1 Mbit/s and 93 at 5, 53 %.
  const BenchConfig fd = can_bench(1, 6, 10000.0, true, 1000000, 5000000);
  EXPECT_NO_THROW(check_link_capacity(fd));
  EXPECT_NEAR(can_bus_loads(fd)[0].load, 10000.0 * (34e-6 + 93.0 / 5e6), 1e-12);
  // A device without an expected rate is not checked (nothing to check against).
  EXPECT_NO_THROW(check_link_capacity(can_bench(1, 6, 0.0, false, 1000000, 0)));
}

// A bench with the table encoder on GPIO and one rotation phase.
BenchConfig gpio_bench(double rate_deg_s, double resolution_rad) {
  BenchConfig b;
  b.simulated = false;
  GpiodEncoder e;
  e.name = "table";
  e.rotary = true;
  e.resolution = resolution_rad;
  b.gpiod_encoders.push_back(e);
  b.table_encoder = {true, resolution_rad, "table.position"};
  TestCase c;
  c.name = "spin";
  Phase p;
  p.kind = PhaseKind::Rotation;
  p.duration_s = 10.0;
  p.rate_rad_s = rate_deg_s * std::numbers::pi / 180.0;
  c.phases.push_back(p);
  b.cases.push_back(c);
  return b;
}

TEST(GpioEdgeRate, PeakSpeedsOfEveryMotionKind) {
  BenchConfig b = gpio_bench(100.0, 1e-6);
  EXPECT_NEAR(encoder_peak_speed(b, b.gpiod_encoders[0]), 100.0 * std::numbers::pi / 180.0, 1e-12);
  // An angle move's (1 - cos) rate profile peaks at twice its mean rate.
  b.cases[0].phases[0].rate_rad_s.reset();
  b.cases[0].phases[0].angle_rad = std::numbers::pi;
  EXPECT_NEAR(encoder_peak_speed(b, b.gpiod_encoders[0]), 2.0 * std::numbers::pi / 10.0, 1e-12);
  // The armature: sine A / (2 pi f), random 4 sd of a_rms / (2 pi sqrt(f1 f2)), shock 2 a T / pi.
  BenchConfig s;
  GpiodEncoder arm;
  arm.name = "armature";
  s.gpiod_encoders.push_back(arm);
  s.linear_encoder = {true, 1e-7, "armature.position"};
  TestCase c;
  Phase sine;
  sine.kind = PhaseKind::Sine;
  sine.frequency_hz = 50.0;
  sine.amplitude_mps2 = 30.0;
  c.phases.push_back(sine);
  s.cases.push_back(c);
  EXPECT_NEAR(encoder_peak_speed(s, arm), 30.0 / (2.0 * std::numbers::pi * 50.0), 1e-12);
  Phase random;
  random.kind = PhaseKind::Random;
  random.f1_hz = 20.0;
  random.f2_hz = 2000.0;
  random.rms_mps2 = 100.0;
  s.cases[0].phases = {random};
  EXPECT_NEAR(encoder_peak_speed(s, arm), 4.0 * 100.0 / (2.0 * std::numbers::pi * 200.0), 1e-12);
  Phase shock;
  shock.kind = PhaseKind::Shock;
  shock.peak_mps2 = 500.0;
  shock.pulse_s = 0.011;
  s.cases[0].phases = {shock};
  EXPECT_NEAR(encoder_peak_speed(s, arm), 2.0 * 500.0 * 0.011 / std::numbers::pi, 1e-12);
  // The motion whatever reads it (the simulator's encoders are no GPIO devices), and its edges.
  EXPECT_EQ(motion_peak_speed(s, false), encoder_peak_speed(s, arm));
  EXPECT_EQ(motion_peak_speed(s, true), 0.0);
  EXPECT_NEAR(quadrature_edges_per_line(1.0, 1e-3), 500.0, 1e-12);   // 1000 counts/s: 500 edges on each of A and B
  // An encoder that is neither reference: no motion is known for it.
  GpiodEncoder other;
  other.name = "spare";
  EXPECT_EQ(encoder_peak_speed(s, other), 0.0);
}

TEST(GpioEdgeRate, TheIssuesTableEncoderIsRefusedAndACoarserOneAccepted) {
  // 100 deg/s at 1 urad per x4 count: 1.745e6 counts/s, 872665 edges/s per line; gpiolib's 16
  // events per line with 1 ms latency carry 16000.
  const BenchConfig fine = gpio_bench(100.0, 1e-6);
  EXPECT_DOUBLE_EQ(gpio_line_edge_capacity(fine.gpiod_encoders[0]), 16000.0);
  try {
    check_link_capacity(fine);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("encoder 'table'"), std::string::npos) << what;
    EXPECT_NE(what.find("872665 edges/s per line"), std::string::npos) << what;
    EXPECT_NE(what.find("counter"), std::string::npos) << what;
  }
  // 10 deg/s at 20 urad per count: 4363 edges/s per line fits.
  EXPECT_NO_THROW(check_link_capacity(gpio_bench(10.0, 20e-6)));
}

TEST(LinkCapacity, TheLoaderRefusesABusItsFramesOverloadAtTheDevicesTable) {
  const fs::path dir = fs::temp_directory_path() / ("inertia_link_capacity_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path p = dir / "bench.toml";
  std::ofstream(p) << "[bench]\nname = \"r\"\nbackend = \"real\"\nsample_rate_hz = 10000.0\n"
                      "[[can_device]]\nname = \"adc\"\ninterface = \"can0\"\nsample_rate_hz = 10000.0\nbitrate = 1000000\n"
                      "[[can_device.signal]]\nname = \"x\"\nid = 0x101\nbit_length = 24\n"
                      "[[can_device.signal]]\nname = \"y\"\nid = 0x101\nbyte_offset = 3\nbit_length = 24\n";
  try {
    (void)load_bench_config(p);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, 5u) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot carry"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
