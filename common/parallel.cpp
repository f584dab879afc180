#include "common/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace inertia::parallel {
namespace {
std::atomic<int> g_jobs{1};
thread_local bool t_inside_task = false;

/// Threads kept for for_each_index from one call to the next. A thread started per call costs
/// its stack afresh: glibc hands a finished thread's stack back to the kernel (MADV_DONTNEED),
/// and the next one faults it in again, a huge page at a time where the kernel backs stacks with
/// them. The pool serves one caller at a time; a second caller meanwhile starts threads of its
/// own (run returns false). Its threads wait for work for the life of the process.
class HelperPool {
 public:
  /// Runs `work` on the calling thread and on `helpers` of the pool's threads (started when first
  /// needed), and returns when every one has returned from it. False, without running anything,
  /// while another caller has the pool.
  bool run(int helpers, const std::function<void()>& work) {
    const std::unique_lock<std::mutex> caller(in_use_, std::try_to_lock);
    if (!caller.owns_lock()) return false;
    std::unique_lock<std::mutex> lock(state_);
    while (static_cast<int>(threads_.size()) < helpers) {
      const auto index = static_cast<int>(threads_.size());
      threads_.emplace_back([this, index] { serve(index); });
      threads_.back().detach();
    }
    work_ = &work;
    wanted_ = helpers;
    returned_ = 0;
    ++round_;
    lock.unlock();
    wake_.notify_all();
    work();
    lock.lock();
    done_.wait(lock, [&] { return returned_ == wanted_; });
    work_ = nullptr;
    return true;
  }

 private:
  void serve(int index) {
    long seen = 0;
    std::unique_lock<std::mutex> lock(state_);
    for (;;) {
      wake_.wait(lock, [&] { return round_ != seen; });
      seen = round_;
      if (index >= wanted_) continue;
      const std::function<void()>* work = work_;
      lock.unlock();
      (*work)();
      lock.lock();
      if (++returned_ == wanted_) done_.notify_one();
    }
  }

  std::mutex in_use_;   // held by the caller whose work the pool runs
  std::mutex state_;    // guards the fields below
  std::condition_variable wake_, done_;
  std::vector<std::thread> threads_;
  const std::function<void()>* work_ = nullptr;
  int wanted_ = 0, returned_ = 0;
  long round_ = 0;
};

/// The process's pool, never destroyed: its threads may still wait in it while the process exits.
HelperPool& helper_pool() {
  static auto* pool = new HelperPool();
  return *pool;
}
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
  if (threads == 1) {
    work();
  } else {
    // The caller works beside its helpers: the pool's, or threads of its own while another
    // caller has the pool.
    const std::function<void()> shared_work = work;
    if (!helper_pool().run(threads - 1, shared_work)) {
      std::vector<std::thread> helpers;
      helpers.reserve(static_cast<std::size_t>(threads - 1));
      for (int t = 1; t < threads; ++t) helpers.emplace_back(work);
      work();
      for (std::thread& h : helpers) h.join();
    }
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace inertia::parallel
