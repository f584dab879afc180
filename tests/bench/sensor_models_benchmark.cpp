// Cost of one sample of each sensor truth model. The paper's experiment runs at 10 kHz for
// minutes; the bench simulator must stay well under 1 s per simulated minute (600k samples per
// sensor), so a step must cost tens of ns. Inputs vary every sample so nothing is hoisted.
#include <benchmark/benchmark.h>

#include <cmath>

#include "hal/sim/sensors/accelerometer_model.hpp"
#include "hal/sim/sensors/fog_model.hpp"

namespace {

using inertia::sim::AccelerometerModel;
using inertia::sim::AccelerometerParams;
using inertia::sim::FogModel;
using inertia::sim::FogParams;

void accelerometer_step(benchmark::State& state, AccelerometerParams p) {
  AccelerometerModel model(p, 10000.0, 7);
  Eigen::Vector3d a(9.80665, 0.5, -0.3);
  double phase = 0.0;
  for (auto _ : state) {
    phase += 1e-3;
    a.x() = 9.80665 * std::sin(phase);   // sign changes exercise the sign/abs branches
    benchmark::DoNotOptimize(model.step(a, 0.1));
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_AccelerometerTable1(benchmark::State& state) {
  AccelerometerParams p;   // table 1: white + pink (0.01 Hz .. Nyquist), three high-pass terms
  accelerometer_step(state, p);
}
BENCHMARK(BM_AccelerometerTable1);

void BM_AccelerometerAllNoises(benchmark::State& state) {
  AccelerometerParams p;
  p.brown_sd_g = 1e-4;
  p.k_s = 1e-3;
  p.k_a = 1e-3;
  p.k_oq = 1e-3;
  accelerometer_step(state, p);
}
BENCHMARK(BM_AccelerometerAllNoises);

void BM_AccelerometerNoiseless(benchmark::State& state) {
  AccelerometerParams p;
  p.white_sd_g = p.pink_sd_g = 0.0;
  accelerometer_step(state, p);
}
BENCHMARK(BM_AccelerometerNoiseless);

void BM_FogColouredNoiseAndGSensitivity(benchmark::State& state) {
  FogParams p;
  p.noise = {{1.0, 0.3, 0.1, 0.0}, {1.0, -1.2, 0.5, -0.05}};
  p.g_sens_i = {{1e-5, 2e-5, 0.0}, {1.0, -0.5, 0.1}};
  p.g_sens_p = {{1e-5, 0.0, 0.0}, {1.0, -0.2, 0.0}};
  p.g_sens_o = {{1e-5, 0.0, 1e-5}, {1.0, 0.1, 0.0}};
  p.c_f1 = 1e-4;
  p.eps_t_ppm_per_degc = 50.0;
  p.c_t1 = 1e-6;
  p.c_t2 = 1e-6;
  FogModel model(p, 10000.0, 7);
  Eigen::Vector3d w(0.1, 0.0, 0.0), a(0.0, 0.0, 9.80665);
  double phase = 0.0;
  for (auto _ : state) {
    phase += 1e-3;
    w.x() = std::sin(phase);
    benchmark::DoNotOptimize(model.step(w, a, 0.5));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FogColouredNoiseAndGSensitivity);

}  // namespace
