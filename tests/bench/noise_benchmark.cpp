// Speed of the streaming Allan estimator (analyzer/noise/allan.hpp): samples per second through
// AllanAccumulator::push (overlapping AVAR at octaves 1..2^10 exact, modified AVAR there, octave
// decimation beyond), and the memory it holds (independent of the record's length).
// Run: build/bench/bench_noise
#include <benchmark/benchmark.h>

#include <random>

#include "analyzer/noise/allan.hpp"

namespace {

void BM_AllanPush(benchmark::State& state) {
  constexpr Eigen::Index kBlock = 1 << 16;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd y(kBlock);
  for (Eigen::Index i = 0; i < kBlock; ++i) y(i) = g(rng);
  inertia::noise::AllanAccumulator acc(1e-4);
  for (auto _ : state) acc.push(y);
  state.SetItemsProcessed(state.iterations() * kBlock);
  state.counters["memory_kB"] = static_cast<double>(acc.memory_bytes()) / 1024.0;
  state.counters["samples"] = static_cast<double>(acc.samples());
}
BENCHMARK(BM_AllanPush)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
