// Speed of the simulated bench on the paper's section 3 experiment (config/sim-paper.toml:
// rotation table plus three shaker orientations, 10 kHz, every channel: motion, four monitoring
// accelerometers, control accelerometer, encoders, thermal model, the eq. 12 sensor).
// Counter sim_s_per_wall_s = simulated seconds per wall-clock second (target: well above 60,
// i.e. well under 1 s per simulated minute on one core).
#include <benchmark/benchmark.h>

#include <filesystem>

#include "common/config/bench_config.hpp"
#include "hal/sim/bench_simulation.hpp"
#include "hal/sim/simulate.hpp"

namespace {

const std::filesystem::path kPaper = std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper.toml";

double simulated_seconds(const inertia::config::BenchConfig& bench) {
  double s = 0.0;
  for (const auto& c : bench.cases) {
    for (const auto& p : c.phases) s += p.duration_s;
  }
  return s;
}

// The physics only: every channel of every case, in memory.
void BM_SimulatePaper(benchmark::State& state) {
  const auto bench = inertia::config::load_bench_config(kPaper);
  for (auto _ : state) {
    auto sim = inertia::sim::simulate_bench(bench);
    benchmark::DoNotOptimize(sim.cases.back().sensors.back().y.data());
  }
  state.counters["sim_s_per_wall_s"] =
      benchmark::Counter(simulated_seconds(bench) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulatePaper)->Unit(benchmark::kMillisecond)->UseRealTime();

// What `inertia-analyze simulate` does end to end: physics plus the dataset CSVs (full double
// precision), truth.toml and the reference CSVs.
void BM_SimulatePaperAndWrite(benchmark::State& state) {
  const auto bench = inertia::config::load_bench_config(kPaper);
  const auto out = std::filesystem::temp_directory_path() / "inertia_bench_sim_paper";
  for (auto _ : state) {
    const auto sim = inertia::sim::simulate_bench(bench);
    inertia::sim::write_simulation(bench, sim, out);
  }
  std::filesystem::remove_all(out);
  state.counters["sim_s_per_wall_s"] =
      benchmark::Counter(simulated_seconds(bench) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulatePaperAndWrite)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
