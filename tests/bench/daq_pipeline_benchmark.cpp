// inertia-daqd end to end (issue 4 targets), as measured runs of the real binary:
//  * PacedNominal: the nominal bench (tests/integration/configs/daq-nominal.toml: 9 accelerometer
//    channels + sample counter on CAN, encoder, thermal controller; 10 kHz) paced in real time for
//    DAQ_BENCH_PACED_S seconds (default 60): ring overflows, sequence gaps in the log, live LCM
//    loss, sample-to-LCM-receive latency p50/p99 of each block's newest sample, daemon CPU %.
//  * FastNominal / FastWide: as fast as possible for 20 simulated seconds: channel-samples per
//    second into the log (from READY to exit, the daemon's own count checked against the log).
// Counters carry the figures; each benchmark runs once (Iterations(1)).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdlib>

#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

double env_or(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::atof(v) : fallback;
}

/// CPU seconds per thread of a running process, sampled from /proc/<pid>/task/*/stat until
/// stop(); the last sample of each thread is kept (threads vanish at exit).
class ThreadCpu {
 public:
  explicit ThreadCpu(pid_t pid) : pid_(pid), thread_([this] {
    while (!stop_) {
      sample();
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }) {}
  ~ThreadCpu() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  /// CPU seconds of threads whose name starts with "sim-" (the simulated bench) and of the rest.
  void split(double* sim, double* daemon) const {
    *sim = *daemon = 0;
    for (const auto& [tid, v] : last_) (v.first.rfind("sim-", 0) == 0 ? *sim : *daemon) += v.second;
  }

 private:
  void sample() {
    const fs::path dir = "/proc/" + std::to_string(pid_) + "/task";
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      std::ifstream in(e.path() / "stat");
      std::string line;
      if (!std::getline(in, line)) continue;
      const auto open = line.find('('), close = line.rfind(')');
      if (open == std::string::npos || close == std::string::npos) continue;
      const std::string comm = line.substr(open + 1, close - open - 1);
      std::istringstream rest(line.substr(close + 2));
      std::string field;
      double utime = 0, stime = 0;
      for (int i = 3; i <= 15 && rest >> field; ++i) {  // fields 14, 15: utime, stime in ticks
        if (i == 14) utime = std::stod(field);
        if (i == 15) stime = std::stod(field);
      }
      last_[e.path().filename().string()] = {comm, (utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK))};
    }
  }
  pid_t pid_;
  std::map<std::string, std::pair<std::string, double>> last_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct LogCheck {
  std::int64_t gaps = 0, channel_samples = 0, raw_blocks = 0;
};

LogCheck check_log(const std::vector<LogEvent>& events) {
  LogCheck c;
  std::map<std::string, std::vector<sample_block_t>> by_channel;
  for (const auto& e : events) {
    if (e.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
    sample_block_t b;
    if (b.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
    c.channel_samples += static_cast<std::int64_t>(b.num_samples) * b.num_channels;
    ++c.raw_blocks;
    by_channel[e.channel].push_back(std::move(b));
  }
  for (const auto& [ch, blocks] : by_channel) c.gaps += sequence_gaps(blocks);
  return c;
}

void BM_PacedNominal(benchmark::State& state) {
  if (lcm_route_missing()) {
    state.SkipWithError(kNoRouteMessage);
    return;
  }
  const double seconds = env_or("DAQ_BENCH_PACED_S", 60.0);
  for (auto _ : state) {
    TempDir tmp;
    const std::string url = private_lcm_url();
    LcmCollector live(url);
    DaqdProcess daqd({"--config", source_path("tests/integration/configs/daq-nominal.toml"), "--duration",
                      std::to_string(seconds), "--log", (tmp.path / "log").string(), "--lcm-url", url},
                     {}, tmp.path / "stderr.txt");
    ThreadCpu threads(daqd.pid());
    const int rc = daqd.wait(seconds + 60);
    threads.stop();
    double sim_cpu = 0, daemon_cpu = 0;
    threads.split(&sim_cpu, &daemon_cpu);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    live.stop();
    if (rc != 0) {
      state.SkipWithError(("daemon failed: " + daqd.output()).c_str());
      return;
    }
    const std::string out = daqd.output();
    const auto events = read_log_dir(tmp.path / "log");
    const LogCheck log = check_log(events);
    std::vector<double> latency_ms;
    std::int64_t raw_received = 0;
    for (const auto& r : live.take()) {
      if (r.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
      ++raw_received;
      if (r.channel != "INERTIA_RAW_ACCEL") continue;
      sample_block_t b;
      if (b.decode(r.data.data(), 0, static_cast<int>(r.data.size())) < 0) continue;
      // Paced: the simulated time base is CLOCK_MONOTONIC, so the newest sample was due then.
      const double newest = static_cast<double>(b.t0_mono_ns) + (b.num_samples - 1) * b.sample_period_s * 1e9;
      latency_ms.push_back((static_cast<double>(r.mono_ns) - newest) * 1e-6);
    }
    std::sort(latency_ms.begin(), latency_ms.end());
    auto pct = [&](double p) {
      return latency_ms.empty() ? -1.0 : latency_ms[static_cast<std::size_t>(p * static_cast<double>(latency_ms.size() - 1))];
    };
    const double run_s = summary_number(out, "  run:", "seconds");
    long long drops = 0;
    for (const char* d : {"  accel:", "  linear_encoder:", "  controller:"}) drops += summary_value(out, d, "ring drops");
    state.counters["seconds"] = run_s;
    state.counters["ring_drops"] = static_cast<double>(drops);
    state.counters["log_seq_gaps"] = static_cast<double>(log.gaps);
    state.counters["log_lost"] = static_cast<double>(summary_value(out, "  log:", "lost"));
    state.counters["lcm_raw_blocks_logged"] = static_cast<double>(log.raw_blocks);
    state.counters["lcm_raw_blocks_lost"] = static_cast<double>(log.raw_blocks - raw_received);
    state.counters["latency_p50_ms"] = pct(0.5);
    state.counters["latency_p99_ms"] = pct(0.99);
    state.counters["latency_max_ms"] = latency_ms.empty() ? -1.0 : latency_ms.back();
    // The simulated bench runs inside the daemon's process: its threads ("sim-*") are the bench,
    // not the daemon, so the target (< 25 % of one core) is checked on the other threads.
    state.counters["cpu_percent_process"] = 100.0 * daqd.cpu_seconds() / std::max(run_s, 1e-9);
    state.counters["cpu_percent_daemon_threads"] = 100.0 * daemon_cpu / std::max(run_s, 1e-9);
    state.counters["cpu_percent_sim_threads"] = 100.0 * sim_cpu / std::max(run_s, 1e-9);
    state.counters["channel_samples"] = static_cast<double>(log.channel_samples);
  }
}

void run_fast(benchmark::State& state, const char* config) {
  if (lcm_route_missing()) {
    state.SkipWithError(kNoRouteMessage);
    return;
  }
  for (auto _ : state) {
    TempDir tmp;
    DaqdProcess daqd({"--config", source_path(config), "--fast", "--duration", "20", "--log",
                      (tmp.path / "log").string(), "--lcm-url", private_lcm_url()},
                     {}, tmp.path / "stderr.txt");
    if (daqd.wait(120) != 0) {
      state.SkipWithError(("daemon failed: " + daqd.output()).c_str());
      return;
    }
    const std::string out = daqd.output();
    const LogCheck log = check_log(read_log_dir(tmp.path / "log"));
    const double run_s = summary_number(out, "  run:", "seconds");
    state.counters["seconds"] = run_s;
    state.counters["channel_samples_in_log"] = static_cast<double>(log.channel_samples);
    state.counters["channel_samples_per_s"] = static_cast<double>(log.channel_samples) / run_s;
    state.counters["daemon_count_minus_log"] = summary_number(out, "  run:", "channel-samples") - static_cast<double>(log.channel_samples);
    state.counters["log_seq_gaps"] = static_cast<double>(log.gaps);
    state.counters["log_lost"] = static_cast<double>(summary_value(out, "  log:", "lost"));
    state.counters["cpu_percent_of_one_core"] = 100.0 * daqd.cpu_seconds() / std::max(run_s, 1e-9);
  }
}

void BM_FastNominal(benchmark::State& state) { run_fast(state, "tests/integration/configs/daq-nominal.toml"); }
void BM_FastWide(benchmark::State& state) { run_fast(state, "tests/integration/configs/daq-wide.toml"); }

BENCHMARK(BM_FastNominal)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_FastWide)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_PacedNominal)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace inertia::daq::testing
