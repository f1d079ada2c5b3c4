#pragma once
// Shape of a dense Dim-dimensional array of doubles, shared by the lifting transform and the
// derivative stencils so both agree on one memory layout.
//
// Layout convention (used everywhere in wavelet/): axis 0 (x) is fastest, i.e. the point with
// multi-index (i0, i1, i2) sits at i0 + n0 * (i1 + n1 * i2). Blocks and whole-grid arrays use the
// same order, so a block with ghosts is just an ArrayShape whose extent includes the ghost layers.
#include <array>
#include <cstddef>

namespace grainwave::wavelet {

template <int Dim>
struct ArrayShape {
  static_assert(Dim >= 1 && Dim <= 3, "grainwave supports 1D, 2D and 3D");
  std::array<int, Dim> extent{};

  constexpr std::ptrdiff_t stride(int axis) const {
    std::ptrdiff_t s = 1;
    for (int a = 0; a < axis; ++a) s *= extent[static_cast<std::size_t>(a)];
    return s;
  }
  constexpr std::size_t size() const {
    std::size_t n = 1;
    for (int e : extent) n *= static_cast<std::size_t>(e);
    return n;
  }
  constexpr std::ptrdiff_t index(const std::array<int, Dim>& i) const {
    std::ptrdiff_t idx = 0;
    for (int a = Dim - 1; a >= 0; --a) idx = idx * extent[static_cast<std::size_t>(a)] + i[static_cast<std::size_t>(a)];
    return idx;
  }
  constexpr std::array<int, Dim> coords(std::ptrdiff_t idx) const {
    std::array<int, Dim> i{};
    for (int a = 0; a < Dim; ++a) {
      const auto n = extent[static_cast<std::size_t>(a)];
      i[static_cast<std::size_t>(a)] = static_cast<int>(idx % n);
      idx /= n;
    }
    return i;
  }
};

}  // namespace grainwave::wavelet
