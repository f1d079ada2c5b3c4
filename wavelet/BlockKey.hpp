#pragma once
// Key of one block of the forest: its refinement level and the Morton (Z-order) interleave of its
// integer block coordinates at that level (design.md "The adaptive grid").
//
// Conventions:
// - Level 0 is the root level: a domain of roots[a] root blocks along axis a has roots[a] << l
//   blocks along that axis at level l, and block coords (c_0, ..., c_{Dim-1}) with 0 <= c_a <
//   roots[a] << l. A block at level l covers [c_a, c_a + 1) * 2^-l in units of a root block.
// - Bit b of coordinate a sits at bit b * Dim + a of `morton`, so the parent is morton >> Dim and
//   child k (bit a of k = offset along axis a) is (morton << Dim) | k.
// - 64-bit keys hold 64 / Dim bits per axis: levels + ceil(log2(roots)) <= 21 in 3D, 32 in 2D.
#include <array>
#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>

namespace grainwave::wavelet {

template <int Dim>
struct BlockKey {
  static_assert(Dim >= 1 && Dim <= 3, "grainwave supports 1D, 2D and 3D");
  static constexpr int kChildren = 1 << Dim;
  static constexpr int kBitsPerAxis = 64 / Dim > 32 ? 32 : 64 / Dim;

  int level = 0;
  std::uint64_t morton = 0;

  static constexpr BlockKey from_coords(int level, const std::array<std::uint32_t, Dim>& c) {
    BlockKey key{level, 0};
    for (int a = 0; a < Dim; ++a) key.morton |= spread(c[static_cast<std::size_t>(a)]) << a;
    return key;
  }
  constexpr std::array<std::uint32_t, Dim> coords() const {
    std::array<std::uint32_t, Dim> c{};
    for (int a = 0; a < Dim; ++a) c[static_cast<std::size_t>(a)] = compact(morton >> a);
    return c;
  }
  /// Bit b of v moved to bit b * Dim (the low kBitsPerAxis bits), and back: the interleave by
  /// shifts and masks instead of bit by bit (the bit loops were 6% of a moving grid's adaptation).
  static constexpr std::uint64_t spread(std::uint32_t v) {
    std::uint64_t x = v;
    if constexpr (Dim == 2) {
      x = (x | x << 16) & 0x0000FFFF0000FFFFull;
      x = (x | x << 8) & 0x00FF00FF00FF00FFull;
      x = (x | x << 4) & 0x0F0F0F0F0F0F0F0Full;
      x = (x | x << 2) & 0x3333333333333333ull;
      x = (x | x << 1) & 0x5555555555555555ull;
    } else if constexpr (Dim == 3) {
      x &= 0x1FFFFFull;
      x = (x | x << 32) & 0x001F00000000FFFFull;
      x = (x | x << 16) & 0x001F0000FF0000FFull;
      x = (x | x << 8) & 0x100F00F00F00F00Full;
      x = (x | x << 4) & 0x10C30C30C30C30C3ull;
      x = (x | x << 2) & 0x1249249249249249ull;
    }
    return x;
  }
  static constexpr std::uint32_t compact(std::uint64_t x) {
    if constexpr (Dim == 2) {
      x &= 0x5555555555555555ull;
      x = (x | x >> 1) & 0x3333333333333333ull;
      x = (x | x >> 2) & 0x0F0F0F0F0F0F0F0Full;
      x = (x | x >> 4) & 0x00FF00FF00FF00FFull;
      x = (x | x >> 8) & 0x0000FFFF0000FFFFull;
      x = (x | x >> 16) & 0x00000000FFFFFFFFull;
    } else if constexpr (Dim == 3) {
      x &= 0x1249249249249249ull;
      x = (x | x >> 2) & 0x10C30C30C30C30C3ull;
      x = (x | x >> 4) & 0x100F00F00F00F00Full;
      x = (x | x >> 8) & 0x001F0000FF0000FFull;
      x = (x | x >> 16) & 0x001F00000000FFFFull;
      x = (x | x >> 32) & 0x1FFFFFull;
    } else {
      x &= 0xFFFFFFFFull;
    }
    return static_cast<std::uint32_t>(x);
  }
  constexpr BlockKey parent() const { return {level - 1, morton >> Dim}; }
  constexpr BlockKey child(int k) const { return {level + 1, (morton << Dim) | static_cast<std::uint64_t>(k)}; }
  /// Position among its siblings: bit a is the offset along axis a.
  constexpr int child_index() const { return static_cast<int>(morton & (kChildren - 1)); }

  friend constexpr bool operator==(const BlockKey&, const BlockKey&) = default;
  friend constexpr auto operator<=>(const BlockKey&, const BlockKey&) = default;
};

template <int Dim>
struct BlockKeyHash {
  std::size_t operator()(const BlockKey<Dim>& k) const noexcept {
    // Mix the level into the top bits, then scramble (splitmix64 finaliser).
    std::uint64_t x = k.morton ^ (static_cast<std::uint64_t>(k.level) << 58) ^ 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return static_cast<std::size_t>(x ^ (x >> 31));
  }
};

}  // namespace grainwave::wavelet
