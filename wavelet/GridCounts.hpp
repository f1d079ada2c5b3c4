#pragma once
// summary.json counts every system on the adaptive grid reports: blocks, points in blocks and
// the range of levels in use. Returns the number of points (for points_fraction).
#include <algorithm>
#include <cstdint>

#include "io/Json.hpp"
#include "wavelet/AdaptiveGrid.hpp"

namespace grainwave::wavelet {

template <int Dim>
double report_grid_counts(const AdaptiveGrid<Dim>& grid, io::Json& counts) {
  const auto blocks = static_cast<std::int64_t>(grid.global_blocks());
  const double points = static_cast<double>(blocks) * static_cast<double>(grid.points_per_block());
  int lmin = grid.config().max_level, lmax = 0;
  for (const auto& k : grid.forest().leaves()) {
    lmin = std::min(lmin, k.level);
    lmax = std::max(lmax, k.level);
  }
  counts.set("blocks", blocks);
  counts.set("points", static_cast<std::int64_t>(points));
  counts.set("level_min", lmin);
  counts.set("level_max", lmax);
  return points;
}

}  // namespace grainwave::wavelet
