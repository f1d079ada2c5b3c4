#pragma once
// A copy whose destination will not be read soon: the solvers' last good state, copied every
// step and read back only after a numerical failure. Ordinary stores first read each destination
// line (a third more memory traffic) and leave it in cache, evicting the state the next step
// reads; non-temporal stores write the lines straight to memory. Short arrays are copied with
// ordinary stores: they fit in cache beside the state, and there the streamed copy was the
// slower (1D Sod's grid: 0.4 -> 0.7 ms over 571 steps; a 600-particle DEM store's arrays of 14 KB:
// 0.18 -> 0.23 s over 25 000 steps). The particle stores keep memcpy even above the bound: a
// 3000-particle DEM store's 72 KB arrays streamed took 0.20-0.23 s instead of 0.15-0.17 s (stop
// 51). Where the machine has no such stores, or the arrays are not 16-byte aligned, it is
// std::copy.
#include <algorithm>
#include <cstddef>
#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace grainwave {

/// Values from which copy_streaming streams (64 KB): the 2D vortex's fields (166 KB each) gained,
/// arrays of 14 KB lost.
inline constexpr std::size_t kStreamedCopyFrom = 8192;

inline void copy_streaming(const double* from, std::size_t count, double* to) {
#if defined(__SSE2__)
  if (count >= kStreamedCopyFrom && reinterpret_cast<std::uintptr_t>(to) % 16 == 0 &&
      reinterpret_cast<std::uintptr_t>(from) % 16 == 0) {
    std::size_t k = 0;
    for (; k + 2 <= count; k += 2) _mm_stream_pd(to + k, _mm_load_pd(from + k));
    if (k < count) to[k] = from[k];
    _mm_sfence();  // the streamed lines are visible before anything that follows
    return;
  }
#endif
  std::copy(from, from + count, to);
}

}  // namespace grainwave
