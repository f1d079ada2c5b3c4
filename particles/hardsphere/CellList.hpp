#pragma once
// Linked cells for pair searches over a Domain (Allen & Tildesley; 000 §4, neighbour binning).
//
// The box is cut into n_k = floor(L_k / h_min) cells per axis, so every cell is at least h_min
// wide; two particles closer than h_min then sit in the same or adjacent cells (adjacency wraps
// across periodic faces). Particles are binned by a counting sort into one index array, O(N), and
// the buffers are kept, so rebuilding at the same or smaller N allocates nothing. Each unordered
// pair of particles in adjacent cells is visited exactly once; the caller measures the distance
// (with Domain::separation for the minimum image). Periodic axes must be at least 2 h_min long so
// that the minimum image is the only image within reach.
#include <array>
#include <cstdint>
#include <vector>

#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

namespace grainwave::particles::hardsphere {

class CellList {
 public:
  /// Lays the grid over `domain` with cells at least `min_cell_size` wide. Allocates (once);
  /// the adjacency is built again only when the cell counts or the periodic axes change.
  void configure(const Domain& domain, double min_cell_size);
  /// Bins the positions (clamped into the box on non-periodic axes). No allocation after warm-up.
  void build(const std::vector<Vec3>& positions);

  int cells_along(int axis) const { return count_[static_cast<std::size_t>(axis)]; }
  int cell_count() const { return static_cast<int>(cell_start_.size()) - 1; }
  double cell_size(int axis) const { return size_[static_cast<std::size_t>(axis)]; }
  int cell_of(const Vec3& x) const;

  /// Calls visit(i, j), i != j, once for every unordered pair in the same or adjacent cells.
  template <class Visit>
  void for_each_pair(Visit&& visit) const {
    const int n_cells = cell_count();
    for (int c = 0; c < n_cells; ++c) {
      const int begin = cell_start_[c], end = cell_start_[c + 1];
      if (begin == end) continue;
      for (int a = begin; a < end; ++a) {
        for (int b = a + 1; b < end; ++b) visit(order_[a], order_[b]);
      }
      for (int k = neighbour_start_[c]; k < neighbour_start_[c + 1]; ++k) {
        const int other = neighbour_cells_[k];
        const int other_begin = cell_start_[other], other_end = cell_start_[other + 1];
        for (int a = begin; a < end; ++a) {
          for (int b = other_begin; b < other_end; ++b) visit(order_[a], order_[b]);
        }
      }
    }
  }

  /// Calls visit(j) for every binned particle in the cell of x or an adjacent one.
  template <class Visit>
  void for_each_near(const Vec3& x, Visit&& visit) const {
    const int c = cell_of(x);
    for (int k = stencil_start_[c]; k < stencil_start_[c + 1]; ++k) {
      const int cell = stencil_cells_[k];
      for (int a = cell_start_[cell]; a < cell_start_[cell + 1]; ++a) visit(order_[a]);
    }
  }

 private:
  int flat(int ix, int iy, int iz) const { return (iz * count_[1] + iy) * count_[0] + ix; }

  Vec3 lo_ = Vec3::Zero();
  std::array<double, 3> size_{1.0, 1.0, 1.0};
  std::array<double, 3> inverse_size_{1.0, 1.0, 1.0};
  std::array<int, 3> count_{1, 1, 1};
  /// What the adjacency below was built for (configure() keeps it while these stay the same).
  std::array<int, 3> adjacency_count_{0, 0, 0};
  std::array<bool, 3> periodic_{false, false, false};
  std::vector<int> cell_start_;       ///< particles of cell c are order_[cell_start_[c] .. [c+1])
  std::vector<int> order_;            ///< particle indices sorted by cell
  std::vector<int> particle_cell_;    ///< scratch: cell of each particle
  std::vector<int> fill_;             ///< scratch: insertion cursor per cell
  std::vector<int> neighbour_start_;  ///< half stencil: adjacent cells with a larger index
  std::vector<int> neighbour_cells_;
  std::vector<int> stencil_start_;    ///< full stencil: the cell itself and all adjacent cells
  std::vector<int> stencil_cells_;
};

}  // namespace grainwave::particles::hardsphere
