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
  /// Sorts the particles into cells of width >= min_cell_width.
  void build(const ParticleStore& store, const Domain& domain, double min_cell_width);

  /// Calls f(i, j) once for every unordered pair of slots in the same or adjacent cells.
  template <class PairFunction>
  void for_each_candidate_pair(PairFunction&& f) const {
    const std::size_t n_cells = cell_start_.size() - 1;
    for (std::size_t c = 0; c < n_cells; ++c) {
      const std::uint32_t begin = cell_start_[c], end = cell_start_[c + 1];
      if (begin == end) continue;
      for (std::uint32_t a = begin; a < end; ++a)
        for (std::uint32_t b = a + 1; b < end; ++b) f(sorted_[a], sorted_[b]);
      const std::uint32_t* stencil = &neighbours_[c * kStencil];
      for (int s = 0; s < stencil_size_[c]; ++s) {
        const std::uint32_t d = stencil[s];
        for (std::uint32_t a = begin; a < end; ++a)
          for (std::uint32_t b = cell_start_[d]; b < cell_start_[d + 1]; ++b)
            f(sorted_[a], sorted_[b]);
      }
    }
  }

  std::size_t cell_count() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }
  const std::array<int, 3>& cells_per_axis() const { return cells_; }

 private:
  static constexpr int kStencil = 13;  ///< at most 26 neighbours, half of them with higher index
  void build_grid(const Domain& domain, double min_cell_width);

  std::array<int, 3> cells_{0, 0, 0};
  Vec3 inverse_width_ = Vec3::Zero();
  double grid_width_request_ = -1.0;
  Domain grid_domain_;
  std::vector<std::uint32_t> cell_start_;
  std::vector<std::uint32_t> cell_of_;
  std::vector<std::uint32_t> sorted_;
  std::vector<std::uint32_t> neighbours_;  ///< per cell: higher-index neighbour cells
  std::vector<int> stencil_size_;
};

}  // namespace grainwave::particles::dem
