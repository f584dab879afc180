// lcm_publish_sample: test helper that publishes inertia::sample_block_t on
// INERTIA_RAW_SIM_REF_1 at 10 Hz (100 samples of 3 sine channels per block, 1 kHz) plus one
// daq_status_t per second, so lcm-spy (build/bin/inertia-lcm-spy) has something to decode.
// Usage: lcm_publish_sample [seconds (default 10)] [LCM URL (default: LCM_DEFAULT_URL)]

#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <thread>

#include "common/lcm/sample_block_layout.hpp"
#include "inertia/daq_status_t.hpp"
#include "inertia/sample_block_t.hpp"

namespace {

std::int64_t clock_ns(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 10.0;
  const std::string url = argc > 2 ? argv[2] : "";
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "lcm_publish_sample: LCM could not start on '%s'\n", url.c_str());
    return 1;
  }
  constexpr int kSamples = 100;
  constexpr double kPeriodS = 1e-3;
  constexpr double kTwoPi = 6.283185307179586;
  inertia::sample_block_t block;
  inertia::shape_sample_block(block, 3, kSamples);
  block.device = "sim_ref_1";
  block.sample_period_s = kPeriodS;
  block.channel_ids = {0, 1, 2};
  block.channel_names = {"a_x", "a_y", "a_z"};
  block.units = {"m/s^2", "m/s^2", "m/s^2"};

  inertia::daq_status_t status;
  status.num_devices = 1;
  status.devices.resize(1);
  status.devices[0].device = block.device;
  status.devices[0].state = inertia::device_status_t::STATE_ACTIVE;
  status.devices[0].nominal_rate_hz = 1.0 / kPeriodS;
  status.devices[0].sample_rate_hz = 1.0 / kPeriodS;
  status.devices[0].ring_capacity = 1024;

  const auto start = std::chrono::steady_clock::now();
  auto next = start;
  std::int64_t sample_index = 0;
  for (std::int64_t seq = 0; std::chrono::steady_clock::now() - start < std::chrono::duration<double>(seconds); ++seq) {
    block.seq = seq;
    block.t0_mono_ns = clock_ns(CLOCK_MONOTONIC);
    block.t0_utime = clock_ns(CLOCK_REALTIME) / 1000;
    for (int c = 0; c < 3; ++c) {
      block.channel_seq[static_cast<std::size_t>(c)] = sample_index;
      for (int s = 0; s < kSamples; ++s) {
        const double t = static_cast<double>(sample_index + s) * kPeriodS;
        block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)] =
            9.80665 * std::sin(kTwoPi * 2.0 * t + c * kTwoPi / 3.0);
        inertia::set_sample_valid(block, c, s, true);
      }
    }
    sample_index += kSamples;
    if (lcm.publish("INERTIA_RAW_SIM_REF_1", &block) != 0) ++status.lcm_publish_failures;
    ++status.lcm_messages;
    if (seq % 10 == 0) {
      status.utime = block.t0_utime;
      status.mono_ns = block.t0_mono_ns;
      status.uptime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      status.devices[0].samples = sample_index;
      status.devices[0].blocks = seq + 1;
      if (lcm.publish("INERTIA_STATUS", &status) != 0) ++status.lcm_publish_failures;
    }
    next += std::chrono::milliseconds(100);
    std::this_thread::sleep_until(next);
  }
  std::printf("published %lld blocks, %lld publish failures\n", static_cast<long long>(status.lcm_messages),
              static_cast<long long>(status.lcm_publish_failures));
  return status.lcm_publish_failures == 0 ? 0 : 1;
}
