// Speed of the two bulk paths of an identification run:
//  - BM_BuildRegression: Phi for N = 1e6 samples x 60 terms (the order-4 eq. 2 candidate set cut
//    to 60 terms: squares, products, abs/sign, lags, y lags), the size algorithm 2 starts from.
//  - BM_FillRegressors: the same into a Phi allocated once (no page faults): the compute cost.
//  - BM_ReadDataset: one case CSV of 1e6 rows x 9 columns (t, a, w, temp, y) as the daemon's
//    10 kHz recordings produce, parsed by read_dataset on 1 and on 2 threads (its chunks side by
//    side; the second argument). Items = rows.
//  - BM_NarrowCrossProduct against its peer BM_NarrowCrossProductAsOneGemm: A'E for A of 1e6 rows x
//    20 columns and E of 2 columns (ELS's noise columns at order 2, once per pass), as
//    ident::cross_product forms it (a column of E at a time) and as one matrix product per block.
// Run: build/bench/bench_regressors [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <sstream>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/ident/row_products.hpp"
#include "common/dataset/dataset.hpp"
#include "common/parallel.hpp"

namespace {

using namespace inertia;

constexpr Eigen::Index kSamples = 1'000'000;
constexpr std::size_t kTerms = 60;

ident::SignalSet random_signals(Eigen::Index n) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> normal(0.0, 9.81);
  ident::SignalSet s(n);
  for (ident::Variable v : {ident::Variable::Ai, ident::Variable::Ap, ident::Variable::Ao, ident::Variable::Ax,
                            ident::Variable::Ay, ident::Variable::Az, ident::Variable::Y}) {
    Eigen::VectorXd x(n);
    for (Eigen::Index k = 0; k < n; ++k) x[k] = normal(rng);
    s.set(v, std::move(x));
  }
  return s;
}

void BM_BuildRegression(benchmark::State& state) {
  const ident::SignalSet signals = random_signals(kSamples);
  ident::CandidateOptions options;
  options.r = 4;
  std::vector<ident::Term> terms =
      ident::candidate_terms(dataset::SensorKind::Accelerometer, ident::ModelFrame::ExternalAndSensor, options);
  terms.resize(kTerms);
  for (auto _ : state) {
    ident::Regression r = ident::build_regression(terms, signals);
    benchmark::DoNotOptimize(r.phi.data());
    benchmark::ClobberMemory();
  }
  state.counters["terms"] = static_cast<double>(terms.size());
  state.SetItemsProcessed(state.iterations() * kSamples);
}
BENCHMARK(BM_BuildRegression)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

// The same columns into a Phi allocated once: the compute cost without the kernel's first-touch
// of ~480 MB of fresh pages that every build_regression call pays.
void BM_FillRegressors(benchmark::State& state) {
  const ident::SignalSet signals = random_signals(kSamples);
  ident::CandidateOptions options;
  options.r = 4;
  std::vector<ident::Term> terms =
      ident::candidate_terms(dataset::SensorKind::Accelerometer, ident::ModelFrame::ExternalAndSensor, options);
  terms.resize(kTerms);
  const Eigen::Index first_row = ident::first_usable_row(terms);
  Eigen::MatrixXd phi(kSamples - first_row, static_cast<Eigen::Index>(terms.size()));
  ident::fill_regressors(terms, signals, first_row, phi);   // untimed: first touch of phi's pages
  for (auto _ : state) {
    ident::fill_regressors(terms, signals, first_row, phi);
    benchmark::DoNotOptimize(phi.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kSamples);
}
BENCHMARK(BM_FillRegressors)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

std::filesystem::path make_dataset(Eigen::Index rows) {
  const auto dir = std::filesystem::temp_directory_path() / "inertia-bench-dataset";
  std::mt19937_64 rng(2);
  std::normal_distribution<double> normal(0.0, 1.0);
  dataset::Dataset d;
  dataset::CaseData c;
  c.name = "shaker-random";
  c.kind = dataset::CaseKind::Shaker;
  c.file = "shaker-random.csv";
  c.t.resize(rows);
  c.a_e.resize(rows, 3);
  c.w_e.emplace(rows, 3);
  c.temp.emplace(rows);
  c.y.resize(rows);
  for (Eigen::Index k = 0; k < rows; ++k) {
    c.t[k] = static_cast<double>(k) * 1e-4;
    for (int a = 0; a < 3; ++a) {
      c.a_e(k, a) = 9.81 * normal(rng);
      (*c.w_e)(k, a) = 0.01 * normal(rng);
    }
    (*c.temp)[k] = 25.0 + normal(rng);
    c.y[k] = 0.08 * normal(rng);
  }
  d.cases.push_back(std::move(c));
  dataset::write_dataset(dir, d);
  return dir;
}

void BM_NarrowCrossProduct(benchmark::State& state) {
  const Eigen::MatrixXd a = Eigen::MatrixXd::Random(kSamples, 20), e = Eigen::MatrixXd::Random(kSamples, 2);
  for (auto _ : state) benchmark::DoNotOptimize(ident::cross_product(a, e));
  state.SetItemsProcessed(state.iterations() * kSamples);
}
BENCHMARK(BM_NarrowCrossProduct)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_NarrowCrossProductAsOneGemm(benchmark::State& state) {
  const Eigen::MatrixXd a = Eigen::MatrixXd::Random(kSamples, 20), e = Eigen::MatrixXd::Random(kSamples, 2);
  for (auto _ : state) {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(20, 2);
    for (Eigen::Index k0 = 0; k0 < kSamples; k0 += ident::kProductBlockRows) {
      const Eigen::Index rows = std::min(ident::kProductBlockRows, kSamples - k0);
      out.noalias() += a.middleRows(k0, rows).transpose() * e.middleRows(k0, rows);
    }
    benchmark::DoNotOptimize(out);
  }
  state.SetItemsProcessed(state.iterations() * kSamples);
}
BENCHMARK(BM_NarrowCrossProductAsOneGemm)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_ReadDataset(benchmark::State& state) {
  const Eigen::Index rows = state.range(0);
  const std::filesystem::path dir = make_dataset(rows);
  const auto bytes = std::filesystem::file_size(dir / "shaker-random.csv");
  std::ostringstream warnings;
  parallel::set_jobs(static_cast<int>(state.range(1)));
  for (auto _ : state) {
    dataset::Dataset d = dataset::read_dataset(dir, warnings);
    benchmark::DoNotOptimize(d.cases[0].y.data());
  }
  parallel::set_jobs(1);
  state.SetItemsProcessed(state.iterations() * rows);
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(bytes));
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_ReadDataset)->Args({kSamples, 1})->Args({kSamples, 2})->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace
