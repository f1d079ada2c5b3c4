#pragma once
// Initial placement of a granular fill (002 §3.2.4): particles on a lattice, or by random
// sequential addition (RSA: random centres, each kept only if it overlaps no particle and no
// wall placed before it), inside an axis-aligned fill box; the fill is then settled under
// gravity by the DemSystem. Obstacles are the finite walls (segments/rectangles, with a
// clearance for the fixed particles of a rough wall) and plane walls. A hopper is filled from
// above: a site with a finite wall above it (under a funnel wall, outside the hopper) is
// skipped, so the fill box may span the whole hopper width.
#include "particles/ParticleStore.hpp"
#include "particles/dem/Walls.hpp"

#include <cstdint>
#include <random>
#include <vector>

namespace grainwave::particles::dem {

struct FillObstacles {
  std::vector<PlaneWall> planes;
  std::vector<FiniteWall> finite;
  std::vector<double> finite_clearance;  ///< extra distance kept from each finite wall
};

/// Diameters for `count` particles; empty placement slots are decided by the caller.
struct FillRequest {
  int dimension = 3;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Ones();  ///< centres lie in [lo, hi]
  std::vector<double> diameters;              ///< one per particle to place, in id order
  bool dense = false;                         ///< lattice: fcc / triangular instead of cubic
};

/// True when a sphere of radius r at x stays clear of every obstacle and no finite wall lies
/// above x (gravity along −y).
bool clear_of_obstacles(const FillObstacles& obstacles, const Vec3& x, double r);

/// RSA: returns centres for as many of the requested diameters as fit within `max_attempts`
/// tries per particle (fewer than requested when the box is too full).
std::vector<Vec3> random_sequential_addition(const FillRequest& request,
                                             const FillObstacles& obstacles, std::mt19937_64& rng,
                                             long max_attempts_per_particle = 2000);

/// A square / simple cubic lattice, or (dense) triangular rows in 2D and a face-centred cubic
/// lattice in 3D, of pitch 1.02 × the largest diameter, filling the box from its low corner, skipping sites that touch an obstacle; a small random jitter breaks the
/// symmetry. Returns at most diameters.size() centres.
std::vector<Vec3> lattice_fill(const FillRequest& request, const FillObstacles& obstacles,
                               std::mt19937_64& rng);

}  // namespace grainwave::particles::dem
