#pragma once
// Small scene builders shared by the hard-sphere collider tests.
#include <cmath>
#include <random>

#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

namespace grainwave::particles::testing {

/// FCC lattice of 4 k^3 unit-diameter spheres at packing fraction phi in a cube, Maxwellian
/// velocities at temperature kT (zero total momentum), random spins. Returns the box length.
inline double fcc_gas(ParticleStore& store, Domain& domain, int k, double phi, double kT,
                      unsigned seed, bool spin = true) {
  const double sigma = 1.0, mass = 1.0, pi = std::acos(-1.0);
  const double a = std::cbrt(4.0 * pi * sigma * sigma * sigma / (6.0 * phi));
  const double length = k * a;
  domain.dimension = 3;
  domain.lo = Vec3::Zero();
  domain.hi = Vec3::Constant(length);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 basis[4] = {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5), Vec3(0, 0.5, 0.5)};
  store.clear();
  std::int64_t id = 0;
  for (int ix = 0; ix < k; ++ix)
    for (int iy = 0; iy < k; ++iy)
      for (int iz = 0; iz < k; ++iz)
        for (const Vec3& b : basis) {
          const Vec3 x = a * (Vec3(ix, iy, iz) + b + Vec3::Constant(0.25));
          const double r = 0.5 * sigma;
          store.add(id++, x, std::sqrt(kT / mass) * Vec3(g(rng), g(rng), g(rng)),
                    spin ? Vec3(g(rng), g(rng), g(rng)) : Vec3::Zero(), r, mass,
                    solid_inertia(3, mass, r));
        }
  Vec3 mean = Vec3::Zero();
  for (const Vec3& v : store.velocity) mean += v;
  mean /= static_cast<double>(store.size());
  for (Vec3& v : store.velocity) v -= mean;
  return length;
}

/// Square lattice of k x k unit-diameter disks at area fraction phi (2D: z = 0), random in-plane
/// velocities at temperature kT with zero total momentum, random spins about z.
inline double disk_gas(ParticleStore& store, Domain& domain, int k, double phi, double kT,
                       unsigned seed) {
  const double pi = std::acos(-1.0), mass = 1.0, r = 0.5;
  const double a = std::sqrt(pi * r * r / phi);
  domain.dimension = 2;
  domain.lo = Vec3::Zero();
  domain.hi = Vec3(k * a, k * a, 0.0);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  store.clear();
  std::int64_t id = 0;
  for (int ix = 0; ix < k; ++ix)
    for (int iy = 0; iy < k; ++iy) {
      store.add(id++, Vec3(a * (ix + 0.5), a * (iy + 0.5), 0.0),
                std::sqrt(kT / mass) * Vec3(g(rng), g(rng), 0.0), Vec3(0, 0, g(rng)), r, mass,
                solid_inertia(2, mass, r));
    }
  Vec3 mean = Vec3::Zero();
  for (const Vec3& v : store.velocity) mean += v;
  mean /= static_cast<double>(store.size());
  for (Vec3& v : store.velocity) v -= mean;
  return k * a;
}

inline double kinetic_energy(const ParticleStore& s) {
  double e = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    e += 0.5 * s.mass[i] * s.velocity[i].squaredNorm() +
         0.5 * s.inertia[i] * s.angular_velocity[i].squaredNorm();
  }
  return e;
}

inline Vec3 momentum(const ParticleStore& s) {
  Vec3 p = Vec3::Zero();
  for (std::size_t i = 0; i < s.size(); ++i) p += s.mass[i] * s.velocity[i];
  return p;
}

inline double momentum_scale(const ParticleStore& s) {
  double p = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) p += s.mass[i] * s.velocity[i].norm();
  return p;
}

}  // namespace grainwave::particles::testing
