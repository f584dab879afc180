// Speed of the streaming Allan estimator (analyzer/noise/allan.hpp): samples per second through
// AllanAccumulator::push (overlapping AVAR at octaves 1..2^10 exact, modified AVAR there, octave
// decimation beyond), and the memory it holds (independent of the record's length). Blocks of
// samples are the usual entry (a record's stretch); one sample at a time costs a copy into the
// block more, and the call.
// The real Fourier transform of the sandwich's X'RX (analyzer/noise/fourier.hpp, FFTW) against
// Eigen's bundled kissfft, which it replaced: both in every iteration, alternating, at the
// power-of-two lengths a case's zero-padded column takes; ratio = kissfft's time / FFTW's.
// R x of one column of a case's n rows (noise::covariance_times) through the spectrum's circulant,
// the shortest fast length M >= 2n - 1, against the same product through the density's power of
// two L >= 2n (what it replaced): both in every iteration, alternating; ratio = L's time / M's.
// Run: build/bench/bench_noise
#include <benchmark/benchmark.h>

#include <chrono>
#include <complex>
#include <random>
#include <unsupported/Eigen/FFT>
#include <vector>

#include "analyzer/noise/allan.hpp"
#include "analyzer/noise/coloured_noise.hpp"
#include "analyzer/noise/fourier.hpp"

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

void BM_RealFourierAgainstKissfft(benchmark::State& state) {
  const auto length = static_cast<Eigen::Index>(state.range(0));
  std::mt19937_64 rng(2);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> column(static_cast<std::size_t>(length), 0.0);
  for (Eigen::Index i = 0; i < length / 2; ++i) column[static_cast<std::size_t>(i)] = g(rng);   // a column padded to 2n
  inertia::noise::RealFourier fftw(length);
  Eigen::FFT<double> kiss;
  kiss.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::vector<std::complex<double>> bins;
  using Clock = std::chrono::steady_clock;
  double fftw_s = 0.0, kiss_s = 0.0;
  bool fftw_first = true;
  for (auto _ : state) {
    const auto run_fftw = [&] {
      const auto t0 = Clock::now();
      fftw.samples() = Eigen::Map<const Eigen::VectorXd>(column.data(), length);
      fftw.forward();
      benchmark::DoNotOptimize(fftw.spectrum().data());
      fftw_s += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    const auto run_kiss = [&] {
      const auto t0 = Clock::now();
      kiss.fwd(bins, column);
      benchmark::DoNotOptimize(bins.data());
      kiss_s += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    if (fftw_first) {
      run_fftw();
      run_kiss();
    } else {
      run_kiss();
      run_fftw();
    }
    fftw_first = !fftw_first;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["fftw_ms"] = 1e3 * fftw_s / n;
  state.counters["kissfft_ms"] = 1e3 * kiss_s / n;
  state.counters["ratio_kissfft_over_fftw"] = kiss_s / fftw_s;
}
BENCHMARK(BM_RealFourierAgainstKissfft)->Arg(1 << 16)->Arg(1 << 18)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(1.0);

void BM_CovarianceTimesCirculantAgainstPowerOfTwo(benchmark::State& state) {
  const auto n = static_cast<Eigen::Index>(state.range(0));
  const inertia::noise::SegmentSpectrum spectrum =
      inertia::noise::spectrum_of(n, [](double f) { return 1.0 + 1e-3 / std::max(f, 1e-9); });   // white and flicker
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd column(n, 1);
  for (Eigen::Index i = 0; i < n; ++i) column(i) = g(rng);
  using Clock = std::chrono::steady_clock;
  double circulant_s = 0.0, power_of_two_s = 0.0;
  bool circulant_first = true;
  for (auto _ : state) {
    const auto run_circulant = [&] {
      const auto t0 = Clock::now();
      const Eigen::MatrixXd r_x = inertia::noise::covariance_times(spectrum, column);
      benchmark::DoNotOptimize(r_x.data());
      circulant_s += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    const auto run_power_of_two = [&] {
      const auto t0 = Clock::now();
      inertia::noise::RealFourier power_of_two(spectrum.length);   // as covariance_times makes its own
      power_of_two.samples().head(n) = column.col(0);
      power_of_two.samples().tail(spectrum.length - n).setZero();
      power_of_two.forward();
      power_of_two.spectrum().array() *= spectrum.density.array();
      power_of_two.inverse();
      const Eigen::VectorXd r_x = power_of_two.samples().head(n);
      benchmark::DoNotOptimize(r_x.data());
      power_of_two_s += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    if (circulant_first) {
      run_circulant();
      run_power_of_two();
    } else {
      run_power_of_two();
      run_circulant();
    }
    circulant_first = !circulant_first;
  }
  const double iterations = static_cast<double>(state.iterations());
  state.counters["M"] = static_cast<double>(spectrum.circulant_length);
  state.counters["L"] = static_cast<double>(spectrum.length);
  state.counters["circulant_ms"] = 1e3 * circulant_s / iterations;
  state.counters["power_of_two_ms"] = 1e3 * power_of_two_s / iterations;
  state.counters["ratio_power_of_two_over_circulant"] = power_of_two_s / circulant_s;
}
// The paper plan's cases at 1x (35,000 and 370,000 rows), 16x's shaker (560,000), 4x's table.
BENCHMARK(BM_CovarianceTimesCirculantAgainstPowerOfTwo)->Arg(35000)->Arg(370000)->Arg(560000)->Arg(1480000)->Unit(benchmark::kMillisecond)->MinTime(1.0);

}  // namespace
