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

int LinkedCells::upper_neighbours(std::size_t c, std::uint32_t* out, Vec3* shifts) const {
  const int home[3] = {static_cast<int>(c % static_cast<std::size_t>(cells_[0])),
                       static_cast<int>((c / static_cast<std::size_t>(cells_[0])) %
                                        static_cast<std::size_t>(cells_[1])),
                       static_cast<int>(c / (static_cast<std::size_t>(cells_[0]) *
                                             static_cast<std::size_t>(cells_[1])))};
  auto neighbour = [&](const int* offset, std::uint32_t& d, Vec3& shift) {
    int idx[3];
    shift.setZero();
    for (int k = 0; k < 3; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      idx[k] = home[k] + offset[k];
      if (idx[k] >= 0 && idx[k] < cells_[uk]) continue;
      if (!wraps_[uk]) return false;
      shift[k] = idx[k] < 0 ? -period_[k] : period_[k];
      idx[k] = (idx[k] + cells_[uk]) % cells_[uk];
    }
    d = static_cast<std::uint32_t>(idx[0] + cells_[0] * (idx[1] + cells_[1] * idx[2]));
    return true;
  };
  int count = 0;
  if (!short_periodic_axis_) {
    for (const auto& offset : kUpperOffsets) {
      if (neighbour(offset, out[count], shifts[count])) ++count;
    }
    return count;
  }
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int offset[3] = {dx, dy, dz};
        std::uint32_t d;
        Vec3 shift;
        if (!neighbour(offset, d, shift) || d <= c) continue;
        if (std::find(out, out + count, d) != out + count) continue;
        shifts[count].setZero();  // short periodic axis: minimum image per pair instead
        out[count++] = d;
      }
  return count;
}

void LinkedCells::build(const ParticleStore& store, const Domain& domain, double min_cell_width,
                        std::size_t grid_particles, const std::vector<std::uint32_t>* visit_order) {
  if (!(min_cell_width > 0.0))
    throw InputError({"linked cells", 0}, "cell_width", "must be > 0 (largest diameter)");
  const std::size_t n = store.size();
  const Vec3 length = domain.length();
  const double max_cells =
      std::max(65536.0, 8.0 * static_cast<double>(grid_particles > 0 ? grid_particles : n));
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
    const std::size_t n_cells = static_cast<std::size_t>(cells_[0]) *
                                static_cast<std::size_t>(cells_[1]) *
                                static_cast<std::size_t>(cells_[2]);
    cell_start_.resize(n_cells + 1);
    // Interior cells: every upper offset stays inside the grid on the axes in use.
    interior_count_ = 0;
    for (const auto& offset : kUpperOffsets) {
      if (domain.dimension == 2 && offset[2] != 0) continue;
      interior_offsets_[static_cast<std::size_t>(interior_count_++)] =
          offset[0] + static_cast<long>(cells_[0]) * (offset[1] + static_cast<long>(cells_[1]) * offset[2]);
    }
    interior_.assign(n_cells, 0);
    for (int z = 0; z < cells_[2]; ++z)
      for (int y = 0; y < cells_[1]; ++y)
        for (int x = 0; x < cells_[0]; ++x) {
          const bool inside = x >= 1 && x + 1 < cells_[0] && y >= 1 && y + 1 < cells_[1] &&
                              (domain.dimension == 2 || (z >= 1 && z + 1 < cells_[2]));
          interior_[static_cast<std::size_t>(x + cells_[0] * (y + cells_[1] * z))] = inside ? 1 : 0;
        }
  }
  lo_ = domain.lo;
  image_ = domain.minimum_image();
  short_periodic_axis_ = false;
  for (int k = 0; k < 3; ++k) {
    const auto uk = static_cast<std::size_t>(k);
    wraps_[uk] = k < domain.dimension && domain.periodic(k);
    if (wraps_[uk] && cells_[uk] < 3) short_periodic_axis_ = true;
    inverse_width_[k] = k < domain.dimension ? cells_[uk] / length[k] : 0.0;
    period_[k] = wraps_[uk] ? length[k] : 0.0;
  }

  cell_of_.resize(n);
  sorted_.resize(n);
  packed_.resize(n);
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
  occupied_.clear();
  occupied_.reserve(n);  // at most one per particle: no allocation once at working size
  for (std::size_t c = 1; c < cell_start_.size(); ++c) {
    if (cell_start_[c] != 0) occupied_.push_back(static_cast<std::uint32_t>(c - 1));
    cell_start_[c] += cell_start_[c - 1];
  }
  // cell_start_[c] serves as the write cursor of cell c, then is shifted back to the start.
  if (visit_order) {
    for (const std::uint32_t i : *visit_order) sorted_[cell_start_[cell_of_[i]]++] = i;
  } else {
    for (std::size_t i = 0; i < n; ++i) sorted_[cell_start_[cell_of_[i]]++] = static_cast<std::uint32_t>(i);
  }
  for (std::size_t c = cell_start_.size() - 1; c > 0; --c) cell_start_[c] = cell_start_[c - 1];
  cell_start_[0] = 0;
  // The packed copy is wrapped into the box on periodic axes: the per-cell shifts assume each
  // position lies in the cell it was sorted into (RK2 evaluates unwrapped predicted positions).
  for (std::size_t a = 0; a < n; ++a) {
    Vec3 x = store.position[sorted_[a]];
    for (int k = 0; k < domain.dimension; ++k)
      if (wraps_[static_cast<std::size_t>(k)])
        x[k] -= period_[k] * std::floor((x[k] - lo_[k]) / period_[k]);
    packed_[a] = {x, store.radius[sorted_[a]]};
  }
}

}  // namespace grainwave::particles::dem
