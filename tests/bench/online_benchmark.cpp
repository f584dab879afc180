// Speed of the live estimator (analyzer/online), per sample and per publish:
//  - BM_StatisticsUpdate/p: one sample into the sufficient statistics of p columns (the noise
//    model's A(q) of order 0 or 40, then the Gram update), in chunks of 100 rows as the fusion
//    hands them over. Items = samples: the "sample-updates per second".
//  - BM_EstimatorPush: the whole per-sample path of the default accelerometer model (case-frame
//    basis of the model, its sensitivities and the structure table's candidates; the squares at
//    25 corner nodes; AR(40) noise model): what one sensor at 10 kHz costs.
//  - BM_Snapshot: one publish (two mountings, corner search, misalignment uncertainty, case
//    scatter, structure table), with and without the search for a mounting's twist about n_i:
//    what --publish-hz costs per sensor.
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
  const bool differences = state.range(2) != 0;   // a model search's step 12 reads them
  constexpr Index kChunk = 100;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(kChunk, p);
  Eigen::VectorXd y(kChunk);
  for (Index i = 0; i < x.size(); ++i) x.data()[i] = normal(rng);
  for (Index i = 0; i < y.size(); ++i) y(i) = normal(rng);
  Eigen::VectorXd ar = Eigen::VectorXd::Constant(order, 0.5 / static_cast<double>(std::max<Index>(order, 1)));
  online::SegmentPipeline pipeline(ar, {}, {}, 1e-4, differences);
  online::Information info(p, 0, 0);
  for (auto _ : state) {
    pipeline.push(x, y, info);
    benchmark::DoNotOptimize(info.base_gram().data());
  }
  state.SetItemsProcessed(state.iterations() * kChunk);
  state.counters["columns"] = static_cast<double>(p);
  state.counters["ar_order"] = static_cast<double>(order);
  state.counters["differences"] = differences ? 1.0 : 0.0;
}
BENCHMARK(BM_StatisticsUpdate)
    ->ArgsProduct({{10, 20, 40, 80}, {0, 40}, {0, 1}})
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

/// Rows of a case whose sensor sits at M_E^S = m_cs m_ec: its scale factor and the cross terms
/// (8.9e-6 per (m/s^2)^2, table 1's), white noise 1e-3.
fusion::FusedChunk with_output(fusion::FusedChunk c, const Eigen::Matrix3d& m_cs, const Eigen::Matrix3d& m_ec, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1e-3);
  const Eigen::Matrix3d m_es = m_cs * m_ec;
  for (Index k = 0; k < c.y.size(); ++k) {
    const Eigen::Vector3d a = m_es * c.a_e.row(k).transpose();
    c.y(k) = 3.44e-3 + 0.0877 * a(0) + 8.9e-6 * (a(0) * a(1) + a(0) * a(2) + a(1) * a(2)) + noise(rng);
  }
  return c;
}

/// Gravity sweeping over the sphere, as a table turning about changing axes.
fusion::FusedChunk table_chunk(Index n) {
  fusion::FusedChunk c = shaker_chunk(n, 99);
  c.kind = CaseKind::RotationTable;
  for (Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * 1e-3;
    const double th = 1.5 + 1.4 * std::sin(1.9 * t), ph = 3.1 * t;
    c.a_e.row(k) << 9.81 * std::sin(th) * std::cos(ph), 9.81 * std::sin(th) * std::sin(ph), 9.81 * std::cos(th);
  }
  return c;
}

// One publish on the paper's two mountings (a table case; a shaker fixture in three orientations,
// turned 1.5 deg about the input axis against it). Arg 1: the fixture's twist about n_i searched
// against the table (LiveSolver::relative_turns), found here (counter twists_found); arg 0: held.
// The difference is what a found twist costs a publish.
void BM_Snapshot(benchmark::State& state) {
  online::OnlineOptions options = live_options();
  options.solver.relative_twist = state.range(0) != 0;
  online::OnlineEstimator est(dataset::SensorKind::Accelerometer, std::nullopt, 25.0, options);
  config::TestCase table;
  table.name = "rotation-table";
  table.kind = CaseKind::RotationTable;
  const Eigen::Matrix3d turned = Eigen::AngleAxisd(1.5 * 3.14159265358979323846 / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::vector<std::pair<config::TestCase, fusion::FusedChunk>> plan;
  plan.emplace_back(table, with_output(table_chunk(6000), Eigen::Matrix3d::Identity(), table.m_ec, 5));
  const config::Orientation orientations[3] = {config::Orientation::IA, config::Orientation::PA, config::Orientation::OA};
  const char* names[3] = {"shaker-ia", "shaker-pa", "shaker-oa"};
  for (int o = 0; o < 3; ++o) {
    const config::TestCase tc = shaker_case(names[o], "fixture", orientations[o]);
    plan.emplace_back(tc, with_output(shaker_chunk(5000, 10 + static_cast<std::uint64_t>(o)), turned, tc.m_ec,
                                      20 + static_cast<std::uint64_t>(o)));
  }
  for (std::size_t c = 0; c < plan.size(); ++c) {
    fusion::FusedChunk& chunk = plan[c].second;
    chunk.case_index = c;
    chunk.case_name = plan[c].first.name;
    est.push(chunk, plan[c].first);
    est.end_segment({c, plan[c].first.name, 0, chunk.rows(), true});
  }
  for (auto _ : state) benchmark::DoNotOptimize(est.snapshot());
  const online::OnlineSnapshot s = est.snapshot();
  int twists = 0;
  for (const online::MountingEstimate& m : s.mountings) {
    if (!std::isfinite(m.angles_rad(0))) continue;
    ++twists;
    state.counters["twist_deg"] = m.angles_rad(0) * 180.0 / 3.14159265358979323846;
    state.counters["twist_sd_deg"] = m.angles_sd_rad(0) * 180.0 / 3.14159265358979323846;
  }
  state.counters["twists_found"] = twists;
}
BENCHMARK(BM_Snapshot)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
