#pragma once
// The dense granular bed the DEM benchmarks step (bench_dem, bench_dem_ranks): a simple cubic
// stack of 28 x 26 x 28 = 20 384 spheres, d = 1, m = 1, spacing 0.98 d (each sphere overlaps its
// six neighbours slightly), small random velocities; periodic in x and z over a floor, open
// above.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

#include <random>

namespace grainwave::bench {

inline void make_dense_bed(particles::ParticleStore& store, particles::Domain& domain) {
  using particles::Vec3;
  const int nx = 28, ny = 26, nz = 28;
  const double spacing = 0.98;
  domain.lo = Vec3::Zero();
  domain.hi = Vec3(nx * spacing, 60.0, nz * spacing);
  domain.face[1] = {particles::FaceKind::kWall, particles::FaceKind::kOpen};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  std::int64_t id = 0;
  for (int j = 0; j < ny; ++j)
    for (int k = 0; k < nz; ++k)
      for (int i = 0; i < nx; ++i)
        store.add(id++, Vec3((i + 0.5) * spacing, 0.49 + j * spacing, (k + 0.5) * spacing),
                  Vec3(u(rng), u(rng), u(rng)), Vec3::Zero(), 0.5, 1.0,
                  particles::solid_inertia(3, 1.0, 0.5));
}

}  // namespace grainwave::bench
