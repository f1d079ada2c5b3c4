#include "particles/dem/Filling.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace grainwave::particles::dem {

bool clear_of_obstacles(const FillObstacles& obstacles, const Vec3& x, double r) {
  for (const PlaneWall& w : obstacles.planes)
    if (w.enabled && w.distance(x) < r) return false;
  for (std::size_t k = 0; k < obstacles.finite.size(); ++k) {
    const FiniteWall& w = obstacles.finite[k];
    const double reach = r + obstacles.finite_clearance[k];
    if ((w.closest_point(x) - x).squaredNorm() < reach * reach) return false;
    // Shadowed: the wall's in-plane axis crosses the vertical through x above x.
    const Vec3& u = w.axis[0];
    if (std::abs(u.x()) > 1e-12) {
      const double s = (x.x() - w.centre.x()) / u.x();
      if (std::abs(s) <= w.half_extent[0] && w.centre.y() + s * u.y() > x.y()) return false;
    }
  }
  return true;
}

std::vector<Vec3> random_sequential_addition(const FillRequest& request,
                                             const FillObstacles& obstacles, std::mt19937_64& rng,
                                             long max_attempts_per_particle) {
  const int dim = request.dimension;
  double largest = 0.0;
  for (double d : request.diameters) largest = std::max(largest, d);
  // A hash grid of cells one largest diameter wide: a new sphere can only touch spheres in its
  // own and the neighbouring cells.
  const double width = std::max(largest, 1e-300);
  auto key = [&](const Vec3& x) {
    std::int64_t k = 0;
    for (int a = 0; a < 3; ++a) k = k * 2097152 + static_cast<std::int64_t>(std::floor((x[a] - request.lo[a]) / width)) + 1048576;
    return k;
  };
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid;
  std::vector<Vec3> placed;
  std::vector<double> placed_radius;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double diameter : request.diameters) {
    const double r = 0.5 * diameter;
    bool done = false;
    for (long attempt = 0; attempt < max_attempts_per_particle && !done; ++attempt) {
      Vec3 x;
      for (int a = 0; a < 3; ++a)
        x[a] = a < dim ? request.lo[a] + u(rng) * (request.hi[a] - request.lo[a]) : request.lo[a];
      if (!clear_of_obstacles(obstacles, x, r)) continue;
      bool free = true;
      const int reach_z = dim == 3 ? 1 : 0;
      for (int i = -1; i <= 1 && free; ++i)
        for (int j = -1; j <= 1 && free; ++j)
          for (int k = -reach_z; k <= reach_z && free; ++k) {
            const auto it = grid.find(key(x + width * Vec3(i, j, k)));
            if (it == grid.end()) continue;
            for (std::size_t q : it->second) {
              const double reach = r + placed_radius[q];
              if ((placed[q] - x).squaredNorm() < reach * reach) {
                free = false;
                break;
              }
            }
          }
      if (!free) continue;
      grid[key(x)].push_back(placed.size());
      placed.push_back(x);
      placed_radius.push_back(r);
      done = true;
    }
    if (!done) break;
  }
  return placed;
}

std::vector<Vec3> lattice_fill(const FillRequest& request, const FillObstacles& obstacles,
                               std::mt19937_64& rng) {
  const int dim = request.dimension;
  double largest = 0.0;
  for (double d : request.diameters) largest = std::max(largest, d);
  const double pitch = 1.02 * largest;
  // Dense: 2D triangular rows; 3D odd rows shifted by half a pitch in x and z and stacked
  // pitch/√2 apart (face-centred cubic), which keeps a thin periodic depth dense. Otherwise a
  // square / simple cubic lattice, which settles into a disordered packing (a dense
  // monodisperse lattice would keep its crystalline order).
  const double row_spacing = !request.dense ? pitch
                             : dim == 3     ? pitch / std::sqrt(2.0)
                                            : 0.5 * std::sqrt(3.0) * pitch;
  std::uniform_real_distribution<double> jitter(-0.005 * largest, 0.005 * largest);
  long n[3] = {1, 1, 1};
  const double spacing[3] = {pitch, row_spacing, pitch};
  for (int a = 0; a < dim; ++a)
    n[a] = std::max(1L, static_cast<long>(std::floor((request.hi[a] - request.lo[a]) / spacing[a])) + 1);
  std::vector<Vec3> placed;
  for (long j = 0; j < n[1]; ++j)  // bottom rows first: a partial fill sits low
    for (long k = 0; k < n[2]; ++k)
      for (long i = 0; i < n[0]; ++i) {
        if (placed.size() == request.diameters.size()) return placed;
        const double shift = (request.dense && j % 2 == 1) ? 0.5 * pitch : 0.0;
        Vec3 x = request.lo + Vec3(shift + pitch * static_cast<double>(i),
                                   row_spacing * static_cast<double>(j),
                                   dim == 3 ? shift + pitch * static_cast<double>(k) : 0.0);
        if (x.x() > request.hi.x() || x.z() > request.hi.z()) continue;
        x.x() += jitter(rng);
        if (dim == 3) x.z() += jitter(rng);
        if (!clear_of_obstacles(obstacles, x, 0.5 * largest)) continue;
        placed.push_back(x);
      }
  return placed;
}

}  // namespace grainwave::particles::dem
