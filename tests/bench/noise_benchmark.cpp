// Speed of the streaming Allan estimator (analyzer/noise/allan.hpp): samples per second through
// AllanAccumulator::push (overlapping AVAR at octaves 1..2^10 exact, modified AVAR there, octave
// decimation beyond), and the memory it holds (independent of the record's length). Blocks of
// samples are the usual entry (a record's stretch); one sample at a time costs a copy into the
// block more, and the call.
// Run: build/bench/bench_noise
#include <benchmark/benchmark.h>

#include <random>

#include "analyzer/noise/allan.hpp"

namespace {

constexpr Eigen::Index kBlock = 1 << 16;

Eigen::VectorXd white_block() {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd y(kBlock);
  for (Eigen::Index i = 0; i < kBlock; ++i) y(i) = g(rng);
  return y;
}

void report(benchmark::State& state, const inertia::noise::AllanAccumulator& acc) {
  state.SetItemsProcessed(state.iterations() * kBlock);
  state.counters["memory_kB"] = static_cast<double>(acc.memory_bytes()) / 1024.0;
  state.counters["samples"] = static_cast<double>(acc.samples());
}

void BM_AllanPush(benchmark::State& state) {
  const Eigen::VectorXd y = white_block();
  inertia::noise::AllanAccumulator acc(1e-4);
  for (auto _ : state) acc.push(y);
  report(state, acc);
}
BENCHMARK(BM_AllanPush)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_AllanPushOneByOne(benchmark::State& state) {
  const Eigen::VectorXd y = white_block();
  inertia::noise::AllanAccumulator acc(1e-4);
  for (auto _ : state)
    for (Eigen::Index i = 0; i < kBlock; ++i) acc.push(y(i));
  report(state, acc);
}
BENCHMARK(BM_AllanPushOneByOne)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
