// Speed of the live estimator (analyzer/online), per sample and per publish:
//  - BM_StatisticsUpdate/p: one sample into the sufficient statistics of p columns (the noise
//    model's A(q) of order 0 or 40, then the Gram update), in chunks of 100 rows as the fusion
//    hands them over. Items = samples: the "sample-updates per second".
//  - BM_EstimatorPush: the whole per-sample path of the default accelerometer model (case-frame
//    basis of the model, its sensitivities and the structure table's candidates; the squares at
//    25 corner nodes; AR(40) noise model): what one sensor at 10 kHz costs.
//  - BM_Snapshot: one publish (two mountings, corner search, misalignment uncertainty, case
//    scatter, structure table): what --publish-hz costs per sensor.
// Run: build/bench/bench_online [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>

#include <random>

#include "analyzer/online/information.hpp"
#include "analyzer/online/online_estimator.hpp"
#include "common/config/bench_config.hpp"

namespace {

using namespace inertia;
using Eigen::Index;

void BM_StatisticsUpdate(benchmark::State& state) {
  const auto p = static_cast<Index>(state.range(0));
  const auto order = static_cast<Index>(state.range(1));
  constexpr Index kChunk = 100;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(kChunk, p);
  Eigen::VectorXd y(kChunk);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = normal(rng);
  for (Index i = 0; i < y.size(); ++i) y(i) = normal(rng);
  Eigen::VectorXd ar = Eigen::VectorXd::Constant(order, 0.5 / static_cast<double>(std::max<Index>(order, 1)));
  online::SegmentPipeline pipeline(ar, {}, {}, 1e-4);
  online::Information info(p, 0, 0);
  for (auto _ : state) {
    pipeline.push(x, y, info);
    benchmark::DoNotOptimize(info.base_gram().data());
  }
  state.SetItemsProcessed(state.iterations() * kChunk);
  state.counters["columns"] = static_cast<double>(p);
  state.counters["ar_order"] = static_cast<double>(order);
}
BENCHMARK(BM_StatisticsUpdate)
    ->ArgsProduct({{10, 20, 40, 80}, {0, 40}})
    ->Unit(benchmark::kMicrosecond);

fusion::FusedChunk shaker_chunk(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> v(0.0, 30.0);
  fusion::FusedChunk c;
  c.case_name = "shaker";
  c.kind = CaseKind::Shaker;
  c.sample_period_s = 1e-4;
  c.t = Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * 1e-4);
  c.a_e.resize(n, 3);
  c.w_e = fusion::Rows3::Zero(n, 3);
  c.y.resize(n);
  for (Index k = 0; k < n; ++k) {
    c.a_e.row(k) << v(rng), 0.0, 9.81;
    c.y(k) = 0.0877 * c.a_e(k, 0) + 1e-3 * v(rng);
  }
  c.phase.assign(static_cast<std::size_t>(n), 0);
  c.phase_names = {"random"};
  return c;
}

online::OnlineOptions live_options() {
  online::OnlineOptions o;
  o.nominal_sample_period_s = 1e-4;
  o.noise_window_s = 0.1;            // fitted on the warm-up rows below
  o.whitening_max_order = 40;
  return o;
}

config::TestCase shaker_case(const char* name, const char* mounting, config::Orientation o) {
  config::TestCase tc;
  tc.name = name;
  tc.kind = CaseKind::Shaker;
  tc.mounting = mounting;
  tc.m_ec = config::slot_orientation(o, 25.0 * 3.14159265358979323846 / 180.0);
  return tc;
}

void BM_EstimatorPush(benchmark::State& state) {
  online::OnlineEstimator est(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, live_options());
  const config::TestCase tc = shaker_case("shaker-ia", "fixture", config::Orientation::IA);
  fusion::FusedChunk warmup = shaker_chunk(2000, 1);
  est.push(warmup, tc);   // past the noise window: the AR(40) model is in place
  constexpr Index kChunk = 200;   // 20 ms at 10 kHz
  fusion::FusedChunk chunk = shaker_chunk(kChunk, 2);
  for (auto _ : state) est.push(chunk, tc);
  state.SetItemsProcessed(state.iterations() * kChunk);
  const online::OnlineSnapshot s = est.snapshot();
  state.counters["noise_order"] = s.noise_order;
}
BENCHMARK(BM_EstimatorPush)->Unit(benchmark::kMicrosecond);

// Arg: 1 with the mountings' twist about n_i searched against the reference (LiveSolver::
// relative_turns), 0 with it held: what the search costs a publish.
void BM_Snapshot(benchmark::State& state) {
  online::OnlineOptions options = live_options();
  options.solver.relative_twist = state.range(0) != 0;
  online::OnlineEstimator est(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, options);
  const config::TestCase cases[3] = {shaker_case("shaker-ia", "fixture", config::Orientation::IA),
                                     shaker_case("shaker-pa", "fixture", config::Orientation::PA),
                                     shaker_case("shaker-oa", "other", config::Orientation::OA)};
  for (std::size_t c = 0; c < 3; ++c) {
    fusion::FusedChunk chunk = shaker_chunk(5000, 10 + c);
    chunk.case_index = c;
    chunk.case_name = cases[c].name;
    est.push(chunk, cases[c]);
    est.end_segment({c, cases[c].name, 0, 5000, true});
  }
  for (auto _ : state) benchmark::DoNotOptimize(est.snapshot());
  const online::OnlineSnapshot s = est.snapshot();
  int twists = 0;
  for (const online::MountingEstimate& m : s.mountings) twists += std::isfinite(m.angles_rad(0)) ? 1 : 0;
  state.counters["twists_found"] = twists;
}
BENCHMARK(BM_Snapshot)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
