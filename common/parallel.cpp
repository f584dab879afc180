#include "common/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <thread>

namespace inertia::parallel {
namespace {
std::atomic<int> g_jobs{1};
}  // namespace

void set_jobs(int jobs) {
  if (jobs <= 0) jobs = static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
  g_jobs.store(jobs, std::memory_order_relaxed);
}

int jobs() { return g_jobs.load(std::memory_order_relaxed); }

int threads_for(long items) { return static_cast<int>(std::clamp<long>(items, 1, jobs())); }

}  // namespace inertia::parallel
