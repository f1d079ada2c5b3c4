#pragma once
// The dense granular bed the DEM benchmarks step (bench_dem, bench_dem_ranks): a simple cubic
// stack of 28 x 26 x 28 = 20 384 spheres, d = 1, m = 1, small random velocities; periodic in x
// and z over a floor, open above. Spacing 0.999 d: each sphere overlaps its six neighbours (and
// the bottom layer the floor) by 1e-3 d, about what the weight of the column compresses the
// bottom contacts by (26 m g / k_n = 1.3e-3 d), so the bed stays dense while it slides down
// the tilt (measured: 2.7-3.0 contacts per particle through 3000 steps with the Coulomb spring
// and 8000 with static friction). A spacing of 0.98 d,
// used until stop 27, stored 2% overlaps whose spring energy (4 m g d per contact) blew the bed
// up: after ~1500 steps it was a granular gas with 0.1-0.2 contacts per particle, and the
// benchmarks measured that gas.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

#include <random>

namespace grainwave::bench {

inline void make_dense_bed(particles::ParticleStore& store, particles::Domain& domain) {
  using particles::Vec3;
  const int nx = 28, ny = 26, nz = 28;
  const double spacing = 0.999;
  domain.lo = Vec3::Zero();
  domain.hi = Vec3(nx * spacing, 60.0, nz * spacing);
  domain.face[1] = {particles::FaceKind::kWall, particles::FaceKind::kOpen};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  std::int64_t id = 0;
  for (int j = 0; j < ny; ++j)
    for (int k = 0; k < nz; ++k)
      for (int i = 0; i < nx; ++i)
        store.add(id++, Vec3((i + 0.5) * spacing, 0.4995 + j * spacing, (k + 0.5) * spacing),
                  Vec3(u(rng), u(rng), u(rng)), Vec3::Zero(), 0.5, 1.0,
                  particles::solid_inertia(3, 1.0, 0.5));
}

}  // namespace grainwave::bench
