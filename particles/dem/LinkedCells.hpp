#pragma once
// Linked-cell neighbour search (002 §3.2.6): the box is cut into cells at least as wide as the
// largest contact distance (the largest diameter), so a particle can only touch particles in
// its own or the adjacent cells and the pair search costs O(N). Periodic axes wrap the cell
// neighbourhood (with the minimum image taken by Domain::separation); on other axes a centre
// outside the box is clamped into the edge cell, which keeps adjacency correct. Each unordered
// pair of neighbouring cells is visited once (from the lower cell index), so each candidate pair
// is reported once. Arrays are reused between builds: nothing is allocated unless the particle
// count or the grid grows. Periodic axes need a length of at least two cell widths.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace grainwave::particles::dem {

class LinkedCells {
 public:
  /// Sorts the particles into cells of width >= min_cell_width. The grid is coarsened so it has
  /// at most max(2^16, 8 N) cells, which keeps a large, sparse box cheap.
  void build(const ParticleStore& store, const Domain& domain, double min_cell_width);

  /// Calls f(i, j) once for every unordered pair of slots in the same or adjacent cells.
  template <class PairFunction>
  void for_each_candidate_pair(PairFunction&& f) const {
    const std::size_t n_cells = cell_start_.size() - 1;
    std::uint32_t neighbours[26];
    for (std::size_t c = 0; c < n_cells; ++c) {
      const std::uint32_t begin = cell_start_[c], end = cell_start_[c + 1];
      if (begin == end) continue;
      for (std::uint32_t a = begin; a < end; ++a)
        for (std::uint32_t b = a + 1; b < end; ++b) f(sorted_[a], sorted_[b]);
      const int count = upper_neighbours(c, neighbours);
      for (int s = 0; s < count; ++s) {
        const std::uint32_t d = neighbours[s];
        for (std::uint32_t a = begin; a < end; ++a)
          for (std::uint32_t b = cell_start_[d]; b < cell_start_[d + 1]; ++b)
            f(sorted_[a], sorted_[b]);
      }
    }
  }

  std::size_t cell_count() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }
  const std::array<int, 3>& cells_per_axis() const { return cells_; }

 private:
  /// Neighbour cells of c that are visited from c: with >= 3 cells on every periodic axis, the
  /// 13 "upper half" offsets; otherwise all distinct neighbours with a larger index (a short
  /// periodic axis maps several offsets onto one cell).
  int upper_neighbours(std::size_t c, std::uint32_t* out) const;

  std::array<int, 3> cells_{0, 0, 0};
  std::array<bool, 3> wraps_{false, false, false};
  bool short_periodic_axis_ = false;
  Vec3 lo_ = Vec3::Zero();
  Vec3 inverse_width_ = Vec3::Zero();
  std::vector<std::uint32_t> cell_start_;
  std::vector<std::uint32_t> cell_of_;
  std::vector<std::uint32_t> sorted_;
};

}  // namespace grainwave::particles::dem
