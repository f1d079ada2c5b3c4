#include "particles/dem/LinkedCells.hpp"

#include "core/Error.hpp"

#include <algorithm>
#include <cmath>

namespace grainwave::particles::dem {

namespace {
// Offsets (dx, dy, dz) that come after (0, 0, 0) in z-major order: each unordered pair of
// neighbouring cells is reached from exactly one of its two cells.
constexpr int kUpperOffsets[13][3] = {{1, 0, 0},  {-1, 1, 0}, {0, 1, 0},  {1, 1, 0},  {-1, -1, 1},
                                      {0, -1, 1}, {1, -1, 1}, {-1, 0, 1}, {0, 0, 1},  {1, 0, 1},
                                      {-1, 1, 1}, {0, 1, 1},  {1, 1, 1}};
}  // namespace

int LinkedCells::upper_neighbours(std::size_t c, std::uint32_t* out) const {
  const int home[3] = {static_cast<int>(c % static_cast<std::size_t>(cells_[0])),
                       static_cast<int>((c / static_cast<std::size_t>(cells_[0])) %
                                        static_cast<std::size_t>(cells_[1])),
                       static_cast<int>(c / (static_cast<std::size_t>(cells_[0]) *
                                             static_cast<std::size_t>(cells_[1])))};
  auto neighbour = [&](const int* offset, std::uint32_t& d) {
    int idx[3];
    for (int k = 0; k < 3; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      idx[k] = home[k] + offset[k];
      if (idx[k] >= 0 && idx[k] < cells_[uk]) continue;
      if (!wraps_[uk]) return false;
      idx[k] = (idx[k] + cells_[uk]) % cells_[uk];
    }
    d = static_cast<std::uint32_t>(idx[0] + cells_[0] * (idx[1] + cells_[1] * idx[2]));
    return true;
  };
  int count = 0;
  if (!short_periodic_axis_) {
    for (const auto& offset : kUpperOffsets) {
      std::uint32_t d;
      if (neighbour(offset, d)) out[count++] = d;
    }
    return count;
  }
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int offset[3] = {dx, dy, dz};
        std::uint32_t d;
        if (!neighbour(offset, d) || d <= c) continue;
        if (std::find(out, out + count, d) == out + count) out[count++] = d;
      }
  return count;
}

void LinkedCells::build(const ParticleStore& store, const Domain& domain, double min_cell_width) {
  if (!(min_cell_width > 0.0))
    throw InputError({"linked cells", 0}, "cell_width", "must be > 0 (largest diameter)");
  const std::size_t n = store.size();
  const Vec3 length = domain.length();
  const double max_cells = std::max(65536.0, 8.0 * static_cast<double>(n));
  double width = min_cell_width;
  std::array<int, 3> cells{1, 1, 1};
  while (true) {
    double total = 1.0;
    for (int k = 0; k < domain.dimension; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      cells[uk] = std::max(1, static_cast<int>(std::floor(length[k] / width)));
      total *= cells[uk];
    }
    if (total <= max_cells) break;
    width *= 1.25;
  }
  if (cells != cells_ || cell_start_.empty()) {
    cells_ = cells;
    cell_start_.resize(static_cast<std::size_t>(cells_[0]) * static_cast<std::size_t>(cells_[1]) *
                           static_cast<std::size_t>(cells_[2]) + 1);
  }
  lo_ = domain.lo;
  short_periodic_axis_ = false;
  for (int k = 0; k < 3; ++k) {
    const auto uk = static_cast<std::size_t>(k);
    wraps_[uk] = k < domain.dimension && domain.periodic(k);
    if (wraps_[uk] && cells_[uk] < 3) short_periodic_axis_ = true;
    inverse_width_[k] = k < domain.dimension ? cells_[uk] / length[k] : 0.0;
  }

  cell_of_.resize(n);
  sorted_.resize(n);
  std::fill(cell_start_.begin(), cell_start_.end(), 0u);
  for (std::size_t i = 0; i < n; ++i) {
    int idx[3] = {0, 0, 0};
    for (int k = 0; k < domain.dimension; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      int c = static_cast<int>(std::floor((store.position[i][k] - lo_[k]) * inverse_width_[k]));
      if (wraps_[uk]) c = ((c % cells_[uk]) + cells_[uk]) % cells_[uk];
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
