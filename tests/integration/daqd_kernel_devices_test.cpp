// The real kernel paths of the CAN and encoder devices, where the kernel offers them:
//   vcan      a virtual CAN bus (needs AF_CAN and the vcan module): --check, the daemon sampling
//             frames sent on it by this test, and a bus-off and restart told by error frames;
//   gpio-sim  simulated GPIO chips in configfs (needs gpio-sim): --check, a line held by another
//             consumer, and the daemon counting quadrature edges made by pulling the lines.
// Elsewhere each test skips and says why; this project's CI kernel has neither (no AF_CAN, no
// GPIO), where the simulator's socketpair and pipe wires stand in (daqd_sim_test.cpp).
#include <fcntl.h>
#include <gpiod.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "hal/unique_fd.hpp"
#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

int shell(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

std::string run_check(const fs::path& bench, int* status) {
  TempDir tmp;
  DaqdProcess check({"--check", "--config", bench.string()}, {}, tmp.path / "out.txt");
  *status = check.wait(60);
  return check.output();
}

// ---- vcan ---------------------------------------------------------------------------------

/// A vcan interface for one test, removed after; `why_not` says why there is none.
struct VirtualCan {
  std::string name = "ivcan" + std::to_string(::getpid() % 100000);
  std::string why_not;
  VirtualCan() {
    const hal::UniqueFd probe(::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW));
    if (!probe.valid()) {
      why_not = std::string("this kernel has no AF_CAN (socket(PF_CAN, SOCK_RAW, CAN_RAW): ") + std::strerror(errno) +
                "): no SocketCAN, so no vcan to run the CAN device on";
      return;
    }
    if (shell("ip link add dev " + name + " type vcan") != 0) {
      why_not = "cannot create a vcan interface (ip link add dev " + name +
                " type vcan: needs the vcan module and CAP_NET_ADMIN)";
      return;
    }
    // MTU 72: CAN FD frames pass (vcan's FD mode).
    if (shell("ip link set " + name + " mtu 72 up") != 0) why_not = "cannot set " + name + " up with MTU 72";
  }
  ~VirtualCan() {
    if (why_not.empty() || why_not.rfind("cannot set", 0) == 0) (void)shell("ip link del dev " + name);
  }
};

/// A CAN_RAW socket on the bus that sends what a CAN ADC module would.
struct CanSender {
  hal::UniqueFd fd;
  explicit CanSender(const std::string& interface) : fd(::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW)) {
    const int on = 1;
    ::setsockopt(fd.get(), SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(::if_nametoindex(interface.c_str()));
    ::bind(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  }
  bool send_counts(std::uint32_t id, std::int32_t counts) const {
    canfd_frame f{};
    f.can_id = id;
    f.len = 16;
    for (int b = 0; b < 3; ++b) f.data[b] = static_cast<std::uint8_t>(static_cast<std::uint32_t>(counts) >> (8 * b));
    return ::write(fd.get(), &f, sizeof f) == static_cast<ssize_t>(sizeof f);
  }
  /// An error frame as a controller's driver reports it (linux/can/error.h).
  bool send_error(std::uint32_t error_class) const {
    can_frame f{};
    f.can_id = CAN_ERR_FLAG | error_class;
    f.len = CAN_ERR_DLC;
    return ::write(fd.get(), &f, sizeof f) == static_cast<ssize_t>(sizeof f);
  }
};

std::string vcan_bench(const std::string& interface) {
  return "[bench]\nname = \"vcan-bench\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n\n"
         "[[can_device]]\nname = \"adc\"\ninterface = \"" + interface + "\"\nsample_rate_hz = 1000.0\nfd = true\n"
         "[[can_device.signal]]\nname = \"acc1\"\nid = 0x101\nbit_length = 24\nsigned = true\nscale = 1e-6\n";
}

TEST(KernelCan, TheDaemonSamplesAVcanBusAndReportsABusOffFromErrorFrames) {
  VirtualCan vcan;
  if (!vcan.why_not.empty()) GTEST_SKIP() << vcan.why_not;
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const fs::path bench = tmp.path / "bench.toml";
  std::ofstream(bench) << vcan_bench(vcan.name);

  int status = -1;
  const std::string check = run_check(bench, &status);
  EXPECT_EQ(status, 0) << check;
  EXPECT_NE(check.find("up, virtual (vcan, MTU 72)"), std::string::npos) << check;
  EXPECT_NE(check.find("CAN_RAW socket"), std::string::npos) << check;

  NotifySocket notify(tmp.path / "notify.sock");
  DaqdProcess daqd({"--config", bench.string(), "--duration", "600", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {"NOTIFY_SOCKET=" + notify.path().string()}, tmp.path / "stderr.txt");
  bool ready = false;
  for (int i = 0; i < 40 && !ready; ++i) ready = notify.receive(0.5).find("READY=1") != std::string::npos;
  ASSERT_TRUE(ready) << daqd.output();
  const CanSender bus(vcan.name);
  constexpr int kFrames = 2000;
  for (int k = 0; k < kFrames; ++k) {
    ASSERT_TRUE(bus.send_counts(0x101, k - 1000));
    if (k % 100 == 99) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // A controller going bus-off, then restarted: the daemon's fault comes and goes.
  ASSERT_TRUE(bus.send_error(CAN_ERR_BUSOFF));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_TRUE(bus.send_error(CAN_ERR_RESTARTED));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const std::string out = daqd.output();
  EXPECT_NE(out.find("adc: fault bus-off"), std::string::npos) << out;
  EXPECT_NE(out.find("adc: cleared bus-off"), std::string::npos) << out;

  const auto events = read_log_dir(tmp.path / "log");
  const auto blocks = decode_all<sample_block_t>(events, "INERTIA_RAW_ADC");
  std::vector<double> values;
  for (const auto& b : blocks)
    for (std::int32_t s = 0; s < b.num_samples; ++s) values.push_back(b.values[0][static_cast<std::size_t>(s)]);
  ASSERT_EQ(values.size(), static_cast<std::size_t>(kFrames)) << "every frame sent after READY, once";
  for (int k = 0; k < kFrames; ++k) EXPECT_NEAR(values[static_cast<std::size_t>(k)], (k - 1000) * 1e-6, 1e-12) << k;
  bool bus_off_on_status = false;
  for (const auto& st : decode_all<daq_status_t>(events, "INERTIA_STATUS"))
    for (const auto& d : st.devices)
      if (d.device == "adc" && std::find(d.faults.begin(), d.faults.end(), "bus-off") != d.faults.end()) bus_off_on_status = true;
  EXPECT_TRUE(bus_off_on_status);
}

// ---- gpio-sim -----------------------------------------------------------------------------

/// A simulated GPIO chip of `lines` lines for one test (gpio-sim, kernel doc
/// admin-guide/gpio/gpio-sim.rst), removed after; `why_not` says why there is none.
struct SimulatedChip {
  fs::path config = "/sys/kernel/config/gpio-sim/inertia-" + std::to_string(::getpid());
  std::string chip, device;   // "gpiochip3", "gpio-sim.0"
  std::string why_not;
  explicit SimulatedChip(int lines) {
    if (!fs::exists("/sys/kernel/config/gpio-sim")) {
      why_not = fs::exists("/sys/kernel/config") ? "no gpio-sim in configfs (modprobe gpio-sim)"
                                                  : "no configfs at /sys/kernel/config: this kernel offers no gpio-sim";
      return;
    }
    std::error_code ec;
    fs::create_directories(config / "bank0", ec);
    if (ec) {
      why_not = "cannot create a gpio-sim chip: " + ec.message();
      return;
    }
    std::ofstream(config / "bank0" / "num_lines") << lines;
    std::ofstream(config / "live") << 1;
    std::ifstream(config / "bank0" / "chip_name") >> chip;
    std::ifstream(config / "dev_name") >> device;
    if (chip.empty()) why_not = "gpio-sim did not bring the chip up";
  }
  ~SimulatedChip() {
    std::error_code ec;
    if (!fs::exists(config, ec)) return;
    std::ofstream(config / "live") << 0;
    fs::remove(config / "bank0", ec);
    fs::remove(config, ec);
  }
  /// Drives line `offset` as the encoder would (gpio-sim: the pull sets the input's level).
  void set(int offset, bool high) const {
    std::ofstream(fs::path("/sys/devices/platform") / device / chip / ("sim_gpio" + std::to_string(offset)) / "pull")
        << (high ? "pull-up" : "pull-down");
  }
};

std::string encoder_bench(const std::string& chip) {
  return "[bench]\nname = \"gpio-bench\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n\n"
         "[[gpiod_encoder]]\nname = \"table\"\nchip = \"" + chip + "\"\nline_a = 0\nline_b = 1\nkind = \"rotary\"\n"
         "resolution = 1e-3\n";
}

TEST(KernelGpio, CheckFindsTheLinesFreeThenNamesTheOneAnotherProgramHolds) {
  SimulatedChip sim(8);
  if (!sim.why_not.empty()) GTEST_SKIP() << sim.why_not;
  TempDir tmp;
  const fs::path bench = tmp.path / "bench.toml";
  std::ofstream(bench) << encoder_bench(sim.chip);
  int status = -1;
  std::string out = run_check(bench, &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_NE(out.find("free, both-edge events"), std::string::npos) << out;

  gpiod_chip* chip = ::gpiod_chip_open_lookup(sim.chip.c_str());
  ASSERT_NE(chip, nullptr);
  gpiod_line* line = ::gpiod_chip_get_line(chip, 1);
  ASSERT_EQ(::gpiod_line_request_input(line, "other-program"), 0);
  out = run_check(bench, &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_NE(out.find("held by 'other-program'"), std::string::npos) << out;
  EXPECT_NE(out.find("at " + bench.string() + ":10:"), std::string::npos) << out;  // line_b
  ::gpiod_chip_close(chip);
}

TEST(KernelGpio, TheDaemonCountsQuadratureEdgesOnARealChip) {
  SimulatedChip sim(8);
  if (!sim.why_not.empty()) GTEST_SKIP() << sim.why_not;
  if (lcm_route_missing()) INERTIA_SKIP_OR_FAIL_IN_CI(kNoRouteMessage);
  TempDir tmp;
  const fs::path bench = tmp.path / "bench.toml";
  std::ofstream(bench) << encoder_bench(sim.chip);
  sim.set(0, false);
  sim.set(1, false);
  NotifySocket notify(tmp.path / "notify.sock");
  DaqdProcess daqd({"--config", bench.string(), "--duration", "600", "--log", (tmp.path / "log").string(), "--lcm-url",
                    private_lcm_url()},
                   {"NOTIFY_SOCKET=" + notify.path().string()}, tmp.path / "stderr.txt");
  bool ready = false;
  for (int i = 0; i < 40 && !ready; ++i) ready = notify.receive(0.5).find("READY=1") != std::string::npos;
  ASSERT_TRUE(ready) << daqd.output();
  // 25 forward cycles (A leads B): 100 x4 counts.
  for (int cycle = 0; cycle < 25; ++cycle) {
    for (auto [offset, high] : {std::pair{0, true}, {1, true}, {0, false}, {1, false}}) {
      sim.set(offset, high);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  daqd.signal(SIGTERM);
  ASSERT_EQ(daqd.wait(20), 0) << daqd.output();
  const auto blocks = decode_all<sample_block_t>(read_log_dir(tmp.path / "log"), "INERTIA_RAW_TABLE");
  ASSERT_FALSE(blocks.empty()) << daqd.output();
  const auto& last = blocks.back();
  const int count = channel_index(last, "count");
  const int position = channel_index(last, "position");
  ASSERT_GE(count, 0);
  const auto n = static_cast<std::size_t>(last.num_samples - 1);
  EXPECT_EQ(std::abs(last.values[static_cast<std::size_t>(count)][n]), 100.0);
  EXPECT_NEAR(std::abs(last.values[static_cast<std::size_t>(position)][n]), 0.1, 1e-12);
  EXPECT_EQ(summary_value(daqd.output(), "  table:", "decode errors"), 0);
}

}  // namespace
}  // namespace inertia::daq::testing
