#pragma once
// Large column buffers (a case's columns, a regression matrix: tens to hundreds of MB) are written
// once right after allocation. With 4 KiB pages that first touch costs one page fault per 4 KiB,
// which dominates both the CSV reader and the regressor builder; transparent huge pages take a
// small fraction of that time (docs/validation.md, 'Evidence behind choices in the code').
// Debian's default THP mode is "madvise", so ask for huge pages explicitly. Advice only: no effect
// on results, and a no-op where the kernel does not support it.
#include <cstddef>
#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace inertia::dataset {

/// Asks the kernel to back [data, data + bytes) with transparent huge pages where it can. Call
/// before the first write. Thread: any. Not real-time (a system call).
inline void advise_huge_pages(void* data, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  if (data == nullptr || bytes < 2 * kHugePage) return;   // not worth a system call
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHugePage - 1);
  if (last > first) (void)::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)data;
  (void)bytes;
#endif
}

}  // namespace inertia::dataset
