// inertia-daqd end to end against its latency and throughput targets, as measured runs of the
// real binary:
//  * PacedNominal: the nominal bench (tests/integration/configs/daq-nominal.toml: 9 accelerometer
//    channels + sample counter on CAN, encoder, thermal controller; 10 kHz) paced in real time for
//    DAQ_BENCH_PACED_S seconds (default 60): ring overflows, sequence gaps in the log, live LCM
//    loss, sample-to-LCM-receive latency p50/p99 of each block's newest sample, daemon CPU %.
//    It prints the latency distribution (percentiles to p99.99 and a histogram), the longest
//    interval between two blocks' arrivals and where in the run it fell, and whether the daemon
//    got SCHED_FIFO (where it is not permitted, the run says so). DAQ_BENCH_HOG=1 runs a
//    process spinning on the last CPU beside it for the whole run (one CPU hog on the other
//    core); DAQ_BENCH_FIFO=0 runs the daemon without SCHED_FIFO.
//  * FastNominal / FastWide: as fast as possible for 20 simulated seconds: channel-samples per
//    second into the log (from READY to exit, the daemon's own count checked against the log).
// Counters carry the figures; each benchmark runs once (Iterations(1)). The machine may be
// shared, so every benchmark records the 1-minute load average (load1) at its start, and:
//  * latency is given twice: from the receiving thread's clock after LCM dispatched the message
//    (latency_*, includes the receiver's own scheduling delay), from LCM's receive stamp
//    (latency_arrival_*) and, from the log, to the moment the publisher handed the block to LCM
//    (latency_publish_*: the daemon's own part);
//  * DAQ_BENCH_PEER_DAQD=/path/to/another/inertia-daqd runs that build on the same bench right
//    after this one (e.g. the previous commit's), and the fast runs report the ratio
//    ours/peer of channel-samples per second and of CPU per channel-sample, a figure that a
//    busy machine shifts far less than either absolute number.
#include <benchmark/benchmark.h>
#include <sched.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "tests/integration/daqd_harness.hpp"

namespace inertia::daq::testing {
namespace {

double env_or(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::atof(v) : fallback;
}

double load1() {
  std::ifstream in("/proc/loadavg");
  double v = -1;
  in >> v;
  return v;
}

std::int64_t wall_minus_mono_ns() {
  timespec wall{}, mono{};
  ::clock_gettime(CLOCK_REALTIME, &wall);
  ::clock_gettime(CLOCK_MONOTONIC, &mono);
  return (static_cast<std::int64_t>(wall.tv_sec) - mono.tv_sec) * 1'000'000'000LL + (wall.tv_nsec - mono.tv_nsec);
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

/// A process spinning on one CPU for as long as this object lives: the other load of a latency
/// measurement. Forked before any thread of the benchmark starts, so the child only spins.
class CpuHog {
 public:
  explicit CpuHog(int cpu) : pid_(::fork()) {
    if (pid_ != 0) return;
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    ::sched_setaffinity(0, sizeof set, &set);
    volatile std::uint64_t spins = 0;
    for (;;) spins = spins + 1;
  }
  ~CpuHog() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  CpuHog(const CpuHog&) = delete;
  CpuHog& operator=(const CpuHog&) = delete;

 private:
  pid_t pid_;
};

/// The p-quantile of sorted values (the nearest rank below), -1 when there are none.
double pct_of(const std::vector<double>& sorted, double p) {
  return sorted.empty() ? -1.0 : sorted[static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1))];
}

/// Percentiles and a histogram of sorted latencies, one line each, for the run's record.
void print_distribution(const char* what, const std::vector<double>& sorted_ms) {
  if (sorted_ms.empty()) {
    std::printf("%s: no samples\n", what);
    return;
  }
  auto at = [&](double p) { return pct_of(sorted_ms, p); };
  std::printf("%s (%zu blocks): p50 %.3f, p90 %.3f, p99 %.3f, p99.9 %.3f, p99.99 %.3f, max %.3f ms\n", what,
              sorted_ms.size(), at(0.5), at(0.9), at(0.99), at(0.999), at(0.9999), sorted_ms.back());
  static constexpr double kEdgesMs[] = {0.25, 0.5, 1, 2, 5, 10, 20, 50, 100, 1000};
  std::printf("%s histogram:", what);
  double lower = 0.0;
  auto first = sorted_ms.begin();
  for (double edge : kEdgesMs) {
    const auto last = std::lower_bound(first, sorted_ms.end(), edge);
    if (last != first) std::printf(" [%g, %g) ms %td;", lower, edge, last - first);
    first = last;
    lower = edge;
  }
  if (first != sorted_ms.end()) std::printf(" >= %g ms %td;", lower, sorted_ms.end() - first);
  std::printf("\n");
}

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
  const int fifo = static_cast<int>(env_or("DAQ_BENCH_FIFO", 20));
  const bool hog = env_or("DAQ_BENCH_HOG", 0) > 0;
  state.counters["load1"] = load1();
  state.counters["fifo_priority"] = fifo;
  state.counters["cpu_hog"] = hog ? 1 : 0;
  const std::int64_t wall_offset_ns = wall_minus_mono_ns();
  for (auto _ : state) {
    const long cpus = ::sysconf(_SC_NPROCESSORS_ONLN);
    std::unique_ptr<CpuHog> spinning;
    if (hog) spinning = std::make_unique<CpuHog>(static_cast<int>(std::max(cpus, 1L) - 1));
    TempDir tmp;
    const std::string url = private_lcm_url();
    LcmCollector live(url);
    std::vector<std::string> args{"--config", source_path("tests/integration/configs/daq-nominal.toml"), "--duration",
                                  std::to_string(seconds), "--log", (tmp.path / "log").string(), "--lcm-url", url};
    // As the service runs (LimitRTPRIO, CAP_SYS_NICE): sampling and publishing SCHED_FIFO, so the
    // tail measures the daemon rather than the machine's other load. DAQ_BENCH_FIFO=0: off.
    if (fifo > 0) args.insert(args.end(), {"--fifo-priority", std::to_string(fifo)});
    DaqdProcess daqd(args, {}, tmp.path / "stderr.txt");
    ThreadCpu threads(daqd.pid());
    const int rc = daqd.wait(seconds + 60);
    threads.stop();
    spinning.reset();
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
    // The log's event time is when the publisher handed the block to LCM: sample-to-publish is
    // the daemon's part of the latency, publish-to-arrival LCM's and the kernel's.
    std::vector<double> publish_ms;
    for (const auto& e : events) {
      if (e.channel != "INERTIA_RAW_ACCEL") continue;
      sample_block_t b;
      if (b.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
      const double newest = static_cast<double>(b.t0_mono_ns) + (b.num_samples - 1) * b.sample_period_s * 1e9;
      publish_ms.push_back((static_cast<double>(e.utime * 1000 - wall_offset_ns) - newest) * 1e-6);
    }
    std::sort(publish_ms.begin(), publish_ms.end());
    std::vector<double> latency_ms, arrival_ms;
    std::int64_t raw_received = 0;
    // The longest wait between two blocks' arrivals (a stall of the daemon, LCM or the receiver)
    // and where in the run it fell; the block period is the wait when nothing stalls.
    std::int64_t first_arrival_ns = -1, previous_arrival_ns = -1, longest_gap_ns = 0, longest_gap_at_ns = 0;
    double block_period_ms = 0.0, worst_latency_ms = -1.0, worst_latency_at_s = 0.0;
    for (const auto& r : live.take()) {
      if (r.channel.rfind("INERTIA_RAW_", 0) != 0) continue;
      ++raw_received;
      if (r.channel != "INERTIA_RAW_ACCEL") continue;
      sample_block_t b;
      if (b.decode(r.data.data(), 0, static_cast<int>(r.data.size())) < 0) continue;
      if (first_arrival_ns < 0) first_arrival_ns = r.mono_ns;
      if (previous_arrival_ns >= 0 && r.mono_ns - previous_arrival_ns > longest_gap_ns) {
        longest_gap_ns = r.mono_ns - previous_arrival_ns;
        longest_gap_at_ns = previous_arrival_ns - first_arrival_ns;
      }
      previous_arrival_ns = r.mono_ns;
      block_period_ms = b.num_samples * b.sample_period_s * 1e3;
      // Paced: the simulated time base is CLOCK_MONOTONIC, so the newest sample was due then.
      const double newest = static_cast<double>(b.t0_mono_ns) + (b.num_samples - 1) * b.sample_period_s * 1e9;
      latency_ms.push_back((static_cast<double>(r.mono_ns) - newest) * 1e-6);
      if (latency_ms.back() > worst_latency_ms) {
        worst_latency_ms = latency_ms.back();
        worst_latency_at_s = static_cast<double>(r.mono_ns - first_arrival_ns) * 1e-9;
      }
      arrival_ms.push_back((static_cast<double>(r.recv_utime * 1000 - wall_offset_ns) - newest) * 1e-6);
    }
    std::sort(latency_ms.begin(), latency_ms.end());
    std::sort(arrival_ms.begin(), arrival_ms.end());
    auto pct = [&](double p) { return pct_of(latency_ms, p); };
    const double run_s = summary_number(out, "  run:", "seconds");
    // The daemon says so on stderr (and on INERTIA_STATUS) when the kernel refuses SCHED_FIFO.
    const bool fifo_granted = fifo > 0 && out.find("running without it") == std::string::npos;
    std::printf("paced %.0f s, %s, %s\n", run_s,
                fifo <= 0        ? "SCHED_FIFO not asked for"
                : fifo_granted   ? "SCHED_FIFO granted"
                                 : "SCHED_FIFO refused by this kernel or user: the latency is measured without it",
                hog ? "one process spinning on the last CPU throughout" : "no added load");
    print_distribution("sample-to-LCM-receive latency (receiving thread's clock)", latency_ms);
    print_distribution("sample-to-LCM-receive latency (LCM's receive stamp)", arrival_ms);
    print_distribution("sample-to-publish latency (the daemon's part)", publish_ms);
    std::printf("longest interval between two blocks' arrivals: %.3f ms at %.1f s into the run (block period %.3f ms); "
                "worst latency %.3f ms at %.1f s\n",
                static_cast<double>(longest_gap_ns) * 1e-6, static_cast<double>(longest_gap_at_ns) * 1e-9, block_period_ms,
                worst_latency_ms, worst_latency_at_s);
    std::fflush(stdout);
    state.counters["fifo_granted"] = fifo_granted ? 1 : 0;
    state.counters["longest_arrival_gap_ms"] = static_cast<double>(longest_gap_ns) * 1e-6;
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
    state.counters["latency_publish_p50_ms"] = pct_of(publish_ms, 0.5);
    state.counters["latency_publish_p99_ms"] = pct_of(publish_ms, 0.99);
    state.counters["latency_publish_max_ms"] = publish_ms.empty() ? -1.0 : publish_ms.back();
    state.counters["latency_arrival_p50_ms"] = pct_of(arrival_ms, 0.5);
    state.counters["latency_arrival_p99_ms"] = pct_of(arrival_ms, 0.99);
    state.counters["latency_arrival_max_ms"] = arrival_ms.empty() ? -1.0 : arrival_ms.back();
    // The simulated bench runs inside the daemon's process: its threads ("sim-*") are the bench,
    // not the daemon, so the target (< 25 % of one core) is checked on the other threads.
    state.counters["cpu_percent_process"] = 100.0 * daqd.cpu_seconds() / std::max(run_s, 1e-9);
    state.counters["cpu_percent_daemon_threads"] = 100.0 * daemon_cpu / std::max(run_s, 1e-9);
    state.counters["cpu_percent_sim_threads"] = 100.0 * sim_cpu / std::max(run_s, 1e-9);
    state.counters["channel_samples"] = static_cast<double>(log.channel_samples);
  }
}

struct FastRun {
  bool ok = false;
  std::string error;
  double seconds = 0, channel_samples = 0, daemon_count_minus_log = 0, gaps = 0, log_lost = 0, cpu_s = 0;
  double ring_drops = 0;  // samples a full ring refused: lost before any block, so no seq gap shows them
};

FastRun fast_run(const char* config, const std::string& binary) {
  FastRun r;
  TempDir tmp;
  DaqdProcess daqd({"--config", source_path(config), "--fast", "--duration", "20", "--log", (tmp.path / "log").string(),
                    "--lcm-url", private_lcm_url()},
                   {}, tmp.path / "stderr.txt", binary);
  if (daqd.wait(120) != 0) {
    r.error = "daemon " + binary + " failed: " + daqd.output();
    return r;
  }
  const std::string out = daqd.output();
  const LogCheck log = check_log(read_log_dir(tmp.path / "log"));
  r.seconds = summary_number(out, "  run:", "seconds");
  r.channel_samples = static_cast<double>(log.channel_samples);
  r.daemon_count_minus_log = summary_number(out, "  run:", "channel-samples") - r.channel_samples;
  r.gaps = static_cast<double>(log.gaps);
  r.log_lost = static_cast<double>(summary_value(out, "  log:", "lost"));
  for (const char* d : {"  accel:", "  linear_encoder:", "  controller:"})
    if (out.find(d) != std::string::npos) r.ring_drops += static_cast<double>(summary_value(out, d, "ring drops"));
  r.cpu_s = daqd.cpu_seconds();
  r.ok = true;
  return r;
}

void run_fast(benchmark::State& state, const char* config) {
  if (lcm_route_missing()) {
    state.SkipWithError(kNoRouteMessage);
    return;
  }
  const char* peer = std::getenv("DAQ_BENCH_PEER_DAQD");
  for (auto _ : state) {
    state.counters["load1"] = load1();
    const FastRun r = fast_run(config, daqd_binary());
    if (!r.ok) {
      state.SkipWithError(r.error.c_str());
      return;
    }
    const double rate = r.channel_samples / r.seconds;
    // CPU of the whole process (simulated bench included) per million channel-samples.
    const double cpu_per_m = r.cpu_s / (r.channel_samples * 1e-6);
    state.counters["seconds"] = r.seconds;
    state.counters["channel_samples_in_log"] = r.channel_samples;
    state.counters["channel_samples_per_s"] = rate;
    state.counters["daemon_count_minus_log"] = r.daemon_count_minus_log;
    state.counters["log_seq_gaps"] = r.gaps;
    state.counters["log_lost"] = r.log_lost;
    state.counters["ring_drops"] = r.ring_drops;
    state.counters["cpu_percent_of_one_core"] = 100.0 * r.cpu_s / std::max(r.seconds, 1e-9);
    state.counters["cpu_s_per_M_channel_samples"] = cpu_per_m;
    if (peer != nullptr && *peer != '\0') {
      const FastRun p = fast_run(config, peer);
      if (!p.ok) {
        state.SkipWithError(p.error.c_str());
        return;
      }
      state.counters["peer_channel_samples_per_s"] = p.channel_samples / p.seconds;
      state.counters["peer_cpu_s_per_M_channel_samples"] = p.cpu_s / (p.channel_samples * 1e-6);
      state.counters["ratio_rate_ours_over_peer"] = rate / (p.channel_samples / p.seconds);
      state.counters["ratio_cpu_peer_over_ours"] = (p.cpu_s / (p.channel_samples * 1e-6)) / cpu_per_m;
    }
  }
}

void BM_FastNominal(benchmark::State& state) { run_fast(state, "tests/integration/configs/daq-nominal.toml"); }
void BM_FastWide(benchmark::State& state) { run_fast(state, "tests/integration/configs/daq-wide.toml"); }

BENCHMARK(BM_FastNominal)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_FastWide)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_PacedNominal)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace inertia::daq::testing
