#pragma once
// An allocator for large arrays read at random (the event-driven collider's per-particle state,
// 100k particles and more): blocks of 2 MiB and above are aligned to 2 MiB and offered to the
// kernel as transparent huge pages (madvise MADV_HUGEPAGE, Linux), so that a random access costs
// a cache miss but rarely a TLB miss as well. With 4 KiB pages a 26 MB working set spans 6500
// pages, beyond the second-level TLB. bench_hardsphere at N = 97 556 measured 0.40 M collisions/s
// with 4 KiB pages and 0.52 M with glibc's huge-page tunable, which does this for every block.
// Smaller blocks, other systems, and kernels that refuse (THP "never") get ordinary memory: the
// advice changes speed only.
#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace grainwave {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
#if defined(__linux__)
    if (bytes >= kHugePage && alignof(T) <= kHugePage) {
      const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
      void* p = std::aligned_alloc(kHugePage, rounded);
      if (!p) throw std::bad_alloc();
      madvise(p, rounded, MADV_HUGEPAGE);  // advice only: failure leaves ordinary pages
      return static_cast<T*>(p);
    }
#endif
    return std::allocator<T>().allocate(n);
  }

  void deallocate(T* p, std::size_t n) noexcept {
#if defined(__linux__)
    if (n * sizeof(T) >= kHugePage && alignof(T) <= kHugePage) {
      std::free(p);
      return;
    }
#endif
    std::allocator<T>().deallocate(p, n);
  }

  template <class U>
  bool operator==(const HugePageAllocator<U>&) const noexcept {
    return true;
  }
};

/// A std::vector whose large buffers sit on huge pages.
template <class T>
using HugePageVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace grainwave
