// step() runs in the simulator's sampling path, 10^4 times per second per sensor: it must not
// allocate. Global operator new is replaced in this test binary to count allocations.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "hal/sim/sensors/accelerometer_model.hpp"
#include "hal/sim/sensors/fog_model.hpp"

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace inertia::sim {
namespace {

TEST(SensorModels, StepDoesNotAllocate) {
  AccelerometerParams ap;   // table 1 plus every optional term and noise
  ap.brown_sd_g = 1e-4;
  ap.k_s = ap.k_a = ap.k_oq = 1e-3;
  ap.bias_tc_g_per_degc = ap.scale_tc_per_degc = 1e-4;
  AccelerometerModel accel(ap, 10000.0, 1);
  FogParams fp;
  fp.noise = {{1.0, 0.3, 0.0, 0.0}, {1.0, -0.8, 0.1, 0.0}};
  fp.g_sens_i = {{1e-5, 1e-5, 0.0}, {1.0, -0.5, 0.0}};
  FogModel fog(fp, 10000.0, 1);
  // The counter is live: construction allocates (the stationary-state solve uses heap matrices).
  const long at_start = g_allocations.load();
  { const AccelerometerModel other(ap, 10000.0, 2); }
  ASSERT_GT(g_allocations.load() - at_start, 0);
  const long before = g_allocations.load();
  double sink = 0.0;
  for (int k = 0; k < 100000; ++k) {
    const Eigen::Vector3d a(std::sin(1e-3 * k) * 9.8, 1.0, -2.0);
    sink += accel.step(a, 0.5) + fog.step({0.1, 0.0, 0.0}, a, 0.5);
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_TRUE(std::isfinite(sink));
}

}  // namespace
}  // namespace inertia::sim
