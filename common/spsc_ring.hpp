#pragma once
// Single-producer single-consumer lock-free ring, after rigtorp's
// SPSCQueue: fixed capacity chosen at construction, no copies or moves, indices on their own
// cache lines, each side caching the other side's index so that the common case touches no
// cache line the other thread writes.
//
// Contract:
//   * exactly one producer thread calls try_push(), try_stage() and publish(); exactly one
//     consumer thread calls front(), pop() and consume(); size_approx(), capacity() and empty()
//     (which count published elements only) may be called from any thread;
//   * capacity() is the requested capacity rounded up to a power of two (minimum 1), and all
//     capacity() slots are usable: the indices are free-running counters, so "full" is
//     write - read == capacity and no slot is sacrificed to tell full from empty;
//   * try_push() never waits: a full ring returns false and the caller counts the drop.
//   * Batches: try_stage() writes an element the consumer cannot see yet and publish() makes
//     every staged element visible at once; consume() hands the consumer every visible element
//     (up to a bound) and frees them with one index store. A producer or consumer that moves
//     many elements per wake-up pays one cross-core index transfer per batch instead of one
//     per element (the daemon moves ~10^6 samples/s per device through its rings).
//
// High-water mark: left to the caller. An exact mark would make the producer read the
// consumer's index on every push, which is the cache-line traffic the index caches exist to
// avoid. The consumer (publisher thread) calls size_approx() just before it drains, when the
// occupancy peaks, and keeps the maximum; that costs the ring nothing.

#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace inertia {

template <class T>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>,
                "SpscRing copies elements with plain stores and never runs destructors");

 public:
  // 128 rather than 64: x86's adjacent-line prefetcher pulls cache lines in pairs, so two
  // indices 64 bytes apart still ping-pong (why folly sets its destructive interference size
  // to 128 on x86-64).
  // A fixed constant, not std::hardware_destructive_interference_size, whose value GCC warns
  // may change between compiler versions (-Winterference-size) and so must not shape a layout.
  static constexpr std::size_t kFalseSharingRange = 128;

  /// Allocates max(1, bit_ceil(min_capacity)) slots. Throws std::length_error when that
  /// overflows and std::bad_alloc when memory is short. Not real-time (allocates).
  explicit SpscRing(std::size_t min_capacity)
      : capacity_(round_up_capacity(min_capacity)),
        mask_(capacity_ - 1),
        slots_(static_cast<T*>(::operator new(slot_bytes(capacity_), kSlotAlignment))) {}

  ~SpscRing() { ::operator delete(slots_, kSlotAlignment); }

  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;
  SpscRing(SpscRing&&) = delete;
  SpscRing& operator=(SpscRing&&) = delete;

  /// Copies `item` into the ring; false when the ring is full (nothing is written).
  /// Thread: the producer only. Real-time: no allocation, no lock, no wait.
  [[nodiscard]] bool try_push(const T& item) noexcept {
    if (!try_stage(item)) return false;
    publish();
    return true;
  }

  /// Copies `item` into the next free slot without making it visible: the consumer sees it
  /// (with every element staged before it) after the next publish(). Staged elements hold their
  /// slots, so a ring full of staged elements rejects. False when full (nothing is written).
  /// Thread: the producer only. Real-time: no allocation, no lock, no wait.
  [[nodiscard]] bool try_stage(const T& item) noexcept {
    const std::size_t write = producer_.staged;  // only we write it
    if (write - producer_.cached_read == capacity_) {
      // Looks full with the stale copy; refresh it. Acquire pairs with the consumer's release
      // so its reads of the slot we are about to overwrite have finished.
      producer_.cached_read = consumer_.read.load(std::memory_order_acquire);
      if (write - producer_.cached_read == capacity_) return false;
    }
    ::new (static_cast<void*>(slots_ + (write & mask_))) T(item);
    producer_.staged = write + 1;
    return true;
  }

  /// Makes every staged element visible to the consumer. Thread: the producer only. Real-time: yes.
  void publish() noexcept {
    // Release: the consumer that sees the new index also sees the elements.
    producer_.write.store(producer_.staged, std::memory_order_release);
  }

  /// The oldest element, or nullptr when the ring is empty. The element stays valid and in
  /// place until pop(). Thread: the consumer only. Real-time: yes.
  [[nodiscard]] T* front() noexcept {
    const std::size_t read = consumer_.read.load(std::memory_order_relaxed);  // only we store it
    if (read == consumer_.cached_write) {
      // Acquire pairs with try_push()'s release: the element is fully written.
      consumer_.cached_write = producer_.write.load(std::memory_order_acquire);
      if (read == consumer_.cached_write) return nullptr;
    }
    return std::launder(slots_ + (read & mask_));
  }

  /// Releases the element front() returned. Precondition: front() != nullptr since the last
  /// pop(). Thread: the consumer only. Real-time: yes.
  void pop() noexcept {
    const std::size_t read = consumer_.read.load(std::memory_order_relaxed);
    // Release: the producer that sees the slot free also sees that we are done reading it.
    consumer_.read.store(read + 1, std::memory_order_release);
  }

  /// Calls `f(T&)` on the oldest visible elements, at most `max_count` of them, in order, then
  /// frees them all with one index store; returns how many. Elements published while `f` runs
  /// wait for the next call, so the call is bounded. `f` must not call front(), pop() or consume()
  /// on this ring. Thread: the consumer only. Real-time: yes, when `f` is.
  template <class F>
  std::size_t consume(F&& f, std::size_t max_count = SIZE_MAX) noexcept(noexcept(f(std::declval<T&>()))) {
    const std::size_t read = consumer_.read.load(std::memory_order_relaxed);  // only we store it
    // Acquire pairs with publish()'s release: the elements are fully written.
    consumer_.cached_write = producer_.write.load(std::memory_order_acquire);
    std::size_t count = consumer_.cached_write - read;
    if (count > max_count) count = max_count;
    for (std::size_t i = 0; i < count; ++i) f(*std::launder(slots_ + ((read + i) & mask_)));
    // Release: the producer that sees the slots free also sees that we are done reading them.
    if (count != 0) consumer_.read.store(read + count, std::memory_order_release);
    return count;
  }

  /// Number of elements in the ring at some moment during the call, in [0, capacity()].
  /// Exact from the consumer thread when the producer is idle. Thread: any.
  [[nodiscard]] std::size_t size_approx() const noexcept {
    // Read first, then write: write never falls behind read, so the difference cannot wrap
    // negative; it can exceed the capacity if the consumer raced ahead meanwhile, so clamp.
    const std::size_t read = consumer_.read.load(std::memory_order_acquire);
    const std::size_t write = producer_.write.load(std::memory_order_acquire);
    const std::size_t size = write - read;
    return size > capacity_ ? capacity_ : size;
  }

  [[nodiscard]] bool empty() const noexcept { return size_approx() == 0; }
  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }

 private:
  static constexpr std::align_val_t kSlotAlignment{
      alignof(T) > kFalseSharingRange ? alignof(T) : kFalseSharingRange};

  // Whole lines, so no other heap object shares the last slot's line.
  static std::size_t slot_bytes(std::size_t capacity) {
    const std::size_t align = static_cast<std::size_t>(kSlotAlignment);
    return (capacity * sizeof(T) + align - 1) / align * align;
  }

  static std::size_t round_up_capacity(std::size_t min_capacity) {
    constexpr std::size_t kMaxCapacity = (std::size_t{1} << (std::bit_width(SIZE_MAX) - 2)) / sizeof(T);
    if (min_capacity > kMaxCapacity) throw std::length_error("SpscRing capacity too large");
    return std::bit_ceil(min_capacity == 0 ? std::size_t{1} : min_capacity);
  }

  // Indices count pushes and pops since construction (64-bit: no wrap in practice, and the
  // unsigned arithmetic above is right across a wrap anyway). Each side's index shares its
  // line only with that side's private cache of the other index.
  struct alignas(kFalseSharingRange) ProducerSide {
    std::atomic<std::size_t> write{0};  // published: what the consumer may read
    std::size_t staged = 0;             // written, >= write; private to the producer
    std::size_t cached_read = 0;
  };
  struct alignas(kFalseSharingRange) ConsumerSide {
    std::atomic<std::size_t> read{0};
    std::size_t cached_write = 0;
  };

  // Read-only after construction, shared by both threads: its own line, away from both sides.
  alignas(kFalseSharingRange) const std::size_t capacity_;
  const std::size_t mask_;
  T* const slots_;
  ProducerSide producer_;
  ConsumerSide consumer_;
};

}  // namespace inertia
