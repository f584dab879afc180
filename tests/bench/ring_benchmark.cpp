// bench_ring: inertia::SpscRing against boost::lockfree::spsc_queue in the same binary (a peer
// measured in the same run), producer on this thread and consumer on another, pinned to different CPUs when
// there are two. Both queues get the same capacity and element type and both consumers copy
// each element out, so the only difference is the queue. BM_RingRatio runs both back to back in
// alternating order inside every iteration and reports ratio = ours / boost throughput.
//
// Both sides spin on a full/empty queue and yield after kSpinsBeforeYield failed tries: on a
// two-CPU machine that is also compiling, pure spinning measures the scheduler's time slices
// instead of the queue (a preempted partner leaves the other side spinning for milliseconds).
// Threads are pinned to CPUs 0 and 1 only when INERTIA_BENCH_PIN=1 (a quiet machine).
//
// Run: build/bench/bench_ring [--benchmark_filter=Ratio]

#include <benchmark/benchmark.h>
#include <pthread.h>
#include <sched.h>

#include <array>
#include <boost/lockfree/spsc_queue.hpp>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <thread>

#include "common/spsc_ring.hpp"

namespace {

constexpr std::size_t kCapacity = 4096;
constexpr std::uint64_t kItemsPerTransfer = 1 << 20;

// A sample as a sampling thread would push it: 64 bytes.
struct Sample64 {
  std::uint64_t seq;
  std::array<double, 7> values;
};
static_assert(sizeof(Sample64) == 64);

template <class T>
T make_item(std::uint64_t i) {
  if constexpr (std::is_same_v<T, Sample64>) {
    return Sample64{i, {1.0, 2.0, 3.0, 4.0, 5.0, 6.0, static_cast<double>(i)}};
  } else {
    return static_cast<T>(i);
  }
}

constexpr int kSpinsBeforeYield = 64;

// Called after a failed push or pop; `spins` counts consecutive failures.
inline void back_off(int& spins) {
  if (++spins >= kSpinsBeforeYield) {
    spins = 0;
    std::this_thread::yield();
  }
}

void pin_to_cpu(int cpu) {
  const char* pin = std::getenv("INERTIA_BENCH_PIN");
  if (pin == nullptr || std::string_view(pin) != "1") return;
  cpu_set_t allowed;
  if (sched_getaffinity(0, sizeof allowed, &allowed) != 0 || CPU_COUNT(&allowed) < 2) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);   // best effort; unpinned still works
}

struct Ours {
  template <class T>
  using Queue = inertia::SpscRing<T>;
  template <class T>
  static bool push(Queue<T>& q, const T& v) { return q.try_push(v); }
  template <class T>
  static bool pop(Queue<T>& q, T& out) {
    const T* front = q.front();
    if (front == nullptr) return false;
    out = *front;
    q.pop();
    return true;
  }
};

struct Boost {
  template <class T>
  using Queue = boost::lockfree::spsc_queue<T>;
  template <class T>
  static bool push(Queue<T>& q, const T& v) { return q.push(v); }
  template <class T>
  static bool pop(Queue<T>& q, T& out) { return q.pop(out); }
};

// Seconds to pass kItemsPerTransfer items from this thread to a consumer thread, measured from
// the first push to the consumer having taken the last item.
template <class Impl, class T>
double transfer_seconds() {
  typename Impl::template Queue<T> queue(kCapacity);
  std::atomic<bool> ready{false};
  std::chrono::steady_clock::time_point consumer_done;
  std::thread consumer([&] {
    pin_to_cpu(1);
    ready.store(true, std::memory_order_release);
    T item{};
    int spins = 0;
    for (std::uint64_t received = 0; received < kItemsPerTransfer;) {
      if (Impl::pop(queue, item)) {
        benchmark::DoNotOptimize(item);
        ++received;
        spins = 0;
      } else {
        back_off(spins);
      }
    }
    consumer_done = std::chrono::steady_clock::now();
  });
  pin_to_cpu(0);
  while (!ready.load(std::memory_order_acquire)) {
  }
  const auto start = std::chrono::steady_clock::now();
  int spins = 0;
  for (std::uint64_t i = 0; i < kItemsPerTransfer; ++i) {
    const T item = make_item<T>(i);
    while (!Impl::push(queue, item)) back_off(spins);
    spins = 0;
  }
  consumer.join();
  return std::chrono::duration<double>(consumer_done - start).count();
}

template <class Impl, class T>
void BM_Ring(benchmark::State& state) {
  for (auto _ : state) state.SetIterationTime(transfer_seconds<Impl, T>());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kItemsPerTransfer));
}

template <class T>
void BM_RingRatio(benchmark::State& state) {
  double ours_s = 0.0;
  double boost_s = 0.0;
  bool ours_first = true;
  for (auto _ : state) {
    double a = 0.0;
    double b = 0.0;
    if (ours_first) {
      a = transfer_seconds<Ours, T>();
      b = transfer_seconds<Boost, T>();
    } else {
      b = transfer_seconds<Boost, T>();
      a = transfer_seconds<Ours, T>();
    }
    ours_first = !ours_first;   // neither queue always runs on a warm or cold machine
    ours_s += a;
    boost_s += b;
    state.SetIterationTime(a + b);
  }
  const double items = static_cast<double>(state.iterations() * kItemsPerTransfer);
  state.counters["ours_Mitems_per_s"] = items / ours_s / 1e6;
  state.counters["boost_Mitems_per_s"] = items / boost_s / 1e6;
  state.counters["ratio_ours_over_boost"] = boost_s / ours_s;   // throughput ratio
}

BENCHMARK(BM_Ring<Ours, std::uint64_t>)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ring<Boost, std::uint64_t>)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ring<Ours, Sample64>)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Ring<Boost, Sample64>)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RingRatio<std::uint64_t>)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_RingRatio<Sample64>)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
