#pragma once
// Walls as contact partners (002 §3.2.2): the point of the wall closest to a particle's centre
// acts as particle j with R_j = 0 and m_j = ∞, so the same contact laws give wall forces.
//   PlaneWall   an infinite plane; one-sided: the particle lives where (x − p)·n > 0, so a
//               centre that has crossed the plane is still pushed back out.
//   FiniteWall  a rectangle (3D) or a line segment (2D: half_extent[1] = 0) with a closest
//               point clamped to its edges, so a particle meeting an end or a corner is pushed
//               radially away from that point; two-sided.
// Each wall has `enabled`: a removable plate (e.g. the hopper gate) is a wall switched off.
// Rough walls are a layer of fixed particles in a hexagonal close-packed arrangement
// (add_rough_wall_layer) and interact as ordinary particle pairs.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace grainwave::particles::dem {

struct PlaneWall {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();  ///< unit, pointing into the particle side
  Vec3 velocity = Vec3::Zero();
  bool enabled = true;

  /// Closest wall point to a centre x.
  Vec3 closest_point(const Vec3& x) const { return x - (x - point).dot(normal) * normal; }
  /// Signed distance of x from the plane along the normal.
  double distance(const Vec3& x) const { return (x - point).dot(normal); }
};

struct FiniteWall {
  Vec3 centre = Vec3::Zero();
  Vec3 axis[2] = {Vec3::UnitX(), Vec3::UnitZ()};  ///< orthonormal in-plane directions
  double half_extent[2] = {0.5, 0.0};
  Vec3 velocity = Vec3::Zero();
  bool enabled = true;

  /// 2D segment from a to b (or a 3D line segment).
  static FiniteWall segment(const Vec3& a, const Vec3& b);
  /// 3D rectangle centred at c with edge directions u, v (orthogonalised here) and full sides.
  static FiniteWall rectangle(const Vec3& c, const Vec3& u, const Vec3& v, double side_u,
                              double side_v);

  Vec3 closest_point(const Vec3& x) const {
    const Vec3 d = x - centre;
    Vec3 p = centre;
    for (int k = 0; k < 2; ++k) {
      const double s = std::clamp(d.dot(axis[k]), -half_extent[k], half_extent[k]);
      p += s * axis[k];
    }
    return p;
  }
};

/// Plane walls at the Domain faces marked FaceKind::kWall (normals pointing inwards).
std::vector<PlaneWall> walls_from_domain(const Domain& domain);

/// Rough wall: fixed particles of radius r touching their neighbours in a hexagonal
/// (triangular-lattice) layer centred on the plane through `origin` spanned by unit vectors
/// e1, e2, covering [0, length1] × [0, length2]. In 2D pass length2 = 0 for a single row along
/// e1. Ids are first_id, first_id + 1, ...; the particles carry kFixed and the given mass.
/// Returns the number of particles added.
std::size_t add_rough_wall_layer(ParticleStore& store, int dimension, const Vec3& origin,
                                 const Vec3& e1, const Vec3& e2, double length1, double length2,
                                 double radius, double mass, std::int64_t first_id);

}  // namespace grainwave::particles::dem
