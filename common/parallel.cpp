#include "common/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <thread>
#include <vector>

namespace inertia::parallel {
namespace {
std::atomic<int> g_jobs{1};
thread_local bool t_inside_task = false;
}  // namespace

void set_jobs(int jobs) {
  if (jobs <= 0) jobs = static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
  g_jobs.store(jobs, std::memory_order_relaxed);
}

int jobs() { return g_jobs.load(std::memory_order_relaxed); }

int threads_for(long items) { return t_inside_task ? 1 : static_cast<int>(std::clamp<long>(items, 1, jobs())); }

void for_each_index(long items, const std::function<void(long)>& task) {
  if (items <= 0) return;
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(items));
  std::atomic<long> next{0};
  std::atomic<bool> failed{false};   // once a task throws, no new task starts
  const auto work = [&] {
    const bool was_inside = t_inside_task;
    t_inside_task = true;
    for (long i = next.fetch_add(1); i < items && !failed.load(); i = next.fetch_add(1)) {
      try {
        task(i);
      } catch (...) {
        errors[static_cast<std::size_t>(i)] = std::current_exception();
        failed.store(true);
      }
    }
    t_inside_task = was_inside;
  };
  const int threads = threads_for(items);
  std::vector<std::thread> helpers;
  helpers.reserve(static_cast<std::size_t>(threads - 1));
  for (int t = 1; t < threads; ++t) helpers.emplace_back(work);
  work();
  for (std::thread& h : helpers) h.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace inertia::parallel
