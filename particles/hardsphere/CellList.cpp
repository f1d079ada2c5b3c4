#include "particles/hardsphere/CellList.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace grainwave::particles::hardsphere {

void CellList::configure(const Domain& domain, double min_cell_size) {
  if (!(min_cell_size > 0.0)) throw std::invalid_argument("CellList: cell size must be positive");
  lo_ = domain.lo;
  std::array<bool, 3> periodic{false, false, false};
  for (int k = 0; k < 3; ++k) {
    const auto axis = static_cast<std::size_t>(k);
    const double length = domain.hi[k] - domain.lo[k];
    if (k >= domain.dimension) {
      count_[axis] = 1;
      size_[axis] = std::max(length, min_cell_size);
    } else {
      periodic[axis] = domain.periodic(k);
      if (periodic[axis] && length < 2.0 * min_cell_size) {
        throw std::invalid_argument("CellList: periodic axis " + std::to_string(k) +
                                    " is shorter than two cutoffs; the minimum image is ambiguous");
      }
      count_[axis] = std::max(1, static_cast<int>(std::floor(length / min_cell_size)));
      size_[axis] = length / count_[axis];
    }
    inverse_size_[axis] = 1.0 / size_[axis];
  }
  const int n_cells = count_[0] * count_[1] * count_[2];
  // The adjacency depends on the cell counts and the periodic axes only. A caller that lays the
  // grid before every search (the overlap check after each step) finds it built: laying it
  // again, with a sort per cell, had cost the 1372-sphere gas's check several times its search.
  if (periodic == periodic_ && count_ == adjacency_count_ && !stencil_start_.empty()) return;
  periodic_ = periodic;
  adjacency_count_ = count_;
  cell_start_.assign(static_cast<std::size_t>(n_cells) + 1, 0);
  fill_.assign(static_cast<std::size_t>(n_cells), 0);

  // Adjacency, deduplicated: with one or two cells on a periodic axis the wrapped offsets repeat.
  neighbour_start_.assign(static_cast<std::size_t>(n_cells) + 1, 0);
  stencil_start_.assign(static_cast<std::size_t>(n_cells) + 1, 0);
  neighbour_cells_.clear();
  stencil_cells_.clear();
  std::vector<int> adjacent;
  adjacent.reserve(27);
  for (int iz = 0; iz < count_[2]; ++iz) {
    for (int iy = 0; iy < count_[1]; ++iy) {
      for (int ix = 0; ix < count_[0]; ++ix) {
        const int self = flat(ix, iy, iz);
        adjacent.clear();
        for (int dz = -1; dz <= 1; ++dz) {
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              std::array<int, 3> j{ix + dx, iy + dy, iz + dz};
              bool inside = true;
              for (std::size_t k = 0; k < 3; ++k) {
                if (j[k] >= 0 && j[k] < count_[k]) continue;
                if (periodic[k]) j[k] = (j[k] + count_[k]) % count_[k];
                else inside = false;
              }
              if (inside) adjacent.push_back(flat(j[0], j[1], j[2]));
            }
          }
        }
        std::sort(adjacent.begin(), adjacent.end());
        adjacent.erase(std::unique(adjacent.begin(), adjacent.end()), adjacent.end());
        for (int cell : adjacent) {
          stencil_cells_.push_back(cell);
          if (cell > self) neighbour_cells_.push_back(cell);
        }
        neighbour_start_[static_cast<std::size_t>(self) + 1] = static_cast<int>(neighbour_cells_.size());
        stencil_start_[static_cast<std::size_t>(self) + 1] = static_cast<int>(stencil_cells_.size());
      }
    }
  }
}

int CellList::cell_of(const Vec3& x) const {
  std::array<int, 3> j{};
  for (std::size_t k = 0; k < 3; ++k) {
    const double s = (x[static_cast<int>(k)] - lo_[static_cast<int>(k)]) * inverse_size_[k];
    // Clamping keeps |cell(i) - cell(j)| <= 1 for close pairs even outside the box (it contracts).
    j[k] = s < 0.0 ? 0 : std::min(static_cast<int>(s), count_[k] - 1);
  }
  return flat(j[0], j[1], j[2]);
}

void CellList::build(const std::vector<Vec3>& positions) {
  const int n = static_cast<int>(positions.size());
  order_.resize(positions.size());
  particle_cell_.resize(positions.size());
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
  for (int i = 0; i < n; ++i) {
    const int c = cell_of(positions[static_cast<std::size_t>(i)]);
    particle_cell_[static_cast<std::size_t>(i)] = c;
    ++cell_start_[static_cast<std::size_t>(c) + 1];
  }
  const std::size_t n_cells = fill_.size();
  for (std::size_t c = 0; c < n_cells; ++c) {
    cell_start_[c + 1] += cell_start_[c];
    fill_[c] = cell_start_[c];
  }
  for (int i = 0; i < n; ++i) {
    const auto c = static_cast<std::size_t>(particle_cell_[static_cast<std::size_t>(i)]);
    order_[static_cast<std::size_t>(fill_[c]++)] = i;
  }
}

}  // namespace grainwave::particles::hardsphere
