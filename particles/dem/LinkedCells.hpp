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
  /// Sorts the particles into cells of width >= min_cell_width and packs their positions and
  /// radii in cell order. The grid is coarsened so it has at most max(2^16, 8 N) cells, which
  /// keeps a large, sparse box cheap; N is `grid_particles` when given (a domain-decomposed run
  /// passes the global count, so every rank builds the serial run's grid), else the store size.
  /// Within a cell the slots appear in the order of `visit_order` when given (a permutation of
  /// the slots), else in slot order: a rank whose owned particles and ghosts each lie in id
  /// order passes their merge by id, and then visits the touching pairs in the serial order.
  void build(const ParticleStore& store, const Domain& domain, double min_cell_width,
             std::size_t grid_particles = 0, const std::vector<std::uint32_t>* visit_order = nullptr);

  /// Calls f(i, j, d, |d|²) once for every unordered pair of slots whose spheres overlap, with
  /// d = x_j − x_i the minimum-image separation. Only the packed copy is read in the search.
  template <class PairFunction>
  void for_each_touching_pair(PairFunction&& f) const {
    for_each_pair_within(0.0, f);
  }

  /// Same for pairs closer than r_i + r_j + margin (the margin must fit in the cell width).
  template <class PairFunction>
  void for_each_pair_within(double margin, PairFunction&& f) const {
    std::uint32_t neighbours[26];
    Vec3 shifts[26];
    for (const std::uint32_t c : occupied_) {  // ascending: the order of a sweep over all cells
      const std::uint32_t begin = cell_start_[c], end = cell_start_[c + 1];
      for (std::uint32_t a = begin; a < end; ++a)
        for (std::uint32_t b = a + 1; b < end; ++b) test_pair(a, b, Vec3::Zero(), margin, f);
      const int count = interior_[c] ? interior_neighbours(c, neighbours, shifts)
                                     : upper_neighbours(c, neighbours, shifts);
      for (int s = 0; s < count; ++s) {
        const std::uint32_t d = neighbours[s];
        const std::uint32_t d_begin = cell_start_[d], d_end = cell_start_[d + 1];
        for (std::uint32_t a = begin; a < end; ++a)
          for (std::uint32_t b = d_begin; b < d_end; ++b) test_pair(a, b, shifts[s], margin, f);
      }
    }
  }

  std::size_t cell_count() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }
  const std::array<int, 3>& cells_per_axis() const { return cells_; }

 private:
  struct PackedParticle {
    Vec3 x;
    double r;
  };

  template <class PairFunction>
  void test_pair(std::uint32_t a, std::uint32_t b, const Vec3& shift, double margin,
                 PairFunction& f) const {
    const PackedParticle& p = packed_[a];
    const PackedParticle& q = packed_[b];
    Vec3 d = q.x + shift - p.x;
    if (short_periodic_axis_) d = image_(d);
    const double reach = p.r + q.r + margin;
    const double distance2 = d.squaredNorm();
    if (distance2 < reach * reach) f(sorted_[a], sorted_[b], d, distance2);
  }
  /// Neighbour cells of c that are visited from c, with the shift that turns a position in the
  /// neighbour into the image next to c. With >= 3 cells on every periodic axis these are the
  /// 13 "upper half" offsets; otherwise all distinct neighbours with a larger index (a short
  /// periodic axis maps several offsets onto one cell; the separation then takes the minimum
  /// image per pair and the shift is zero).
  int upper_neighbours(std::size_t c, std::uint32_t* out, Vec3* shifts) const;
  /// Same for a cell away from every box face: fixed index offsets, no wrapping.
  int interior_neighbours(std::size_t c, std::uint32_t* out, Vec3* shifts) const {
    for (int s = 0; s < interior_count_; ++s) {
      out[s] = static_cast<std::uint32_t>(static_cast<long>(c) + interior_offsets_[static_cast<std::size_t>(s)]);
      shifts[s].setZero();
    }
    return interior_count_;
  }

  std::array<int, 3> cells_{0, 0, 0};
  std::array<bool, 3> wraps_{false, false, false};
  bool short_periodic_axis_ = false;
  Vec3 lo_ = Vec3::Zero();
  Vec3 period_ = Vec3::Zero();
  Domain::MinimumImage image_;  ///< the domain's, for the pairs across a short periodic axis
  Vec3 inverse_width_ = Vec3::Zero();
  std::vector<std::uint32_t> cell_start_;
  std::vector<std::uint32_t> cell_of_;
  std::vector<std::uint32_t> sorted_;
  std::vector<PackedParticle> packed_;
  std::vector<std::uint8_t> interior_;  ///< per cell: no neighbour crosses a box face
  /// The cells holding particles, ascending: a sparse box (a hopper, a curtain, a rank's slab
  /// of the whole grid) sweeps only these.
  std::vector<std::uint32_t> occupied_;
  std::array<long, 13> interior_offsets_{};
  int interior_count_ = 0;
};

}  // namespace grainwave::particles::dem
