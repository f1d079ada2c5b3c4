#include "particles/dem/LinkedCells.hpp"

#include "core/Error.hpp"

#include <algorithm>
#include <cmath>

namespace grainwave::particles::dem {

void LinkedCells::build_grid(const Domain& domain, double min_cell_width) {
  if (!(min_cell_width > 0.0))
    throw InputError({"linked cells", 0}, "cell_width", "must be > 0 (largest diameter)");
  grid_domain_ = domain;
  grid_width_request_ = min_cell_width;
  const Vec3 length = domain.length();
  for (int k = 0; k < 3; ++k) {
    const auto uk = static_cast<std::size_t>(k);
    cells_[uk] = k < domain.dimension
                     ? std::max(1, static_cast<int>(std::floor(length[k] / min_cell_width)))
                     : 1;
    inverse_width_[k] = k < domain.dimension ? cells_[uk] / length[k] : 0.0;
  }
  const std::size_t n_cells =
      static_cast<std::size_t>(cells_[0]) * static_cast<std::size_t>(cells_[1]) *
      static_cast<std::size_t>(cells_[2]);
  cell_start_.assign(n_cells + 1, 0);
  neighbours_.assign(n_cells * kStencil, 0);
  stencil_size_.assign(n_cells, 0);
  // Offsets in {-1,0,1}^dim, wrapped or dropped at the box edge; keep unique cells with a
  // higher index so every neighbouring cell pair appears exactly once.
  for (int z = 0; z < cells_[2]; ++z)
    for (int y = 0; y < cells_[1]; ++y)
      for (int x = 0; x < cells_[0]; ++x) {
        const std::size_t c = static_cast<std::size_t>(x + cells_[0] * (y + cells_[1] * z));
        const int home[3] = {x, y, z};
        int count = 0;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int offset[3] = {dx, dy, dz};
              int idx[3];
              bool inside = true;
              for (int k = 0; k < 3; ++k) {
                const auto uk = static_cast<std::size_t>(k);
                idx[k] = home[k] + offset[k];
                if (idx[k] >= 0 && idx[k] < cells_[uk]) continue;
                if (k < domain.dimension && domain.periodic(k))
                  idx[k] = (idx[k] + cells_[uk]) % cells_[uk];
                else
                  inside = false;
              }
              if (!inside) continue;
              const auto d =
                  static_cast<std::uint32_t>(idx[0] + cells_[0] * (idx[1] + cells_[1] * idx[2]));
              if (d <= c) continue;
              std::uint32_t* list = &neighbours_[c * kStencil];
              if (std::find(list, list + count, d) != list + count) continue;
              list[count++] = d;
            }
        stencil_size_[c] = count;
      }
}

void LinkedCells::build(const ParticleStore& store, const Domain& domain, double min_cell_width) {
  const bool same_grid = min_cell_width == grid_width_request_ && domain.lo == grid_domain_.lo &&
                         domain.hi == grid_domain_.hi && domain.dimension == grid_domain_.dimension &&
                         domain.face == grid_domain_.face;
  if (!same_grid) build_grid(domain, min_cell_width);
  const std::size_t n = store.size();
  cell_of_.resize(n);
  sorted_.resize(n);
  std::fill(cell_start_.begin(), cell_start_.end(), 0u);
  for (std::size_t i = 0; i < n; ++i) {
    int idx[3] = {0, 0, 0};
    for (int k = 0; k < domain.dimension; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      int c = static_cast<int>(std::floor((store.position[i][k] - domain.lo[k]) * inverse_width_[k]));
      if (domain.periodic(k)) c = ((c % cells_[uk]) + cells_[uk]) % cells_[uk];
      else c = std::clamp(c, 0, cells_[uk] - 1);
      idx[k] = c;
    }
    const auto cell = static_cast<std::uint32_t>(idx[0] + cells_[0] * (idx[1] + cells_[1] * idx[2]));
    cell_of_[i] = cell;
    ++cell_start_[cell + 1];
  }
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  // cell_start_[c] serves as the write cursor of cell c, then is shifted back to the start.
  for (std::size_t i = 0; i < n; ++i) sorted_[cell_start_[cell_of_[i]]++] = static_cast<std::uint32_t>(i);
  for (std::size_t c = cell_start_.size() - 1; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
  cell_start_[0] = 0;
}

}  // namespace grainwave::particles::dem
