#include "particles/dem/Walls.hpp"

#include <cmath>

namespace grainwave::particles::dem {

FiniteWall FiniteWall::segment(const Vec3& a, const Vec3& b) {
  FiniteWall w;
  w.centre = 0.5 * (a + b);
  w.axis[0] = (b - a).normalized();
  // Any unit vector normal to axis[0]; its half-extent is zero so it never moves the point.
  w.axis[1] = w.axis[0].unitOrthogonal();
  w.half_extent[0] = 0.5 * (b - a).norm();
  w.half_extent[1] = 0.0;
  return w;
}

FiniteWall FiniteWall::rectangle(const Vec3& c, const Vec3& u, const Vec3& v, double side_u,
                                 double side_v) {
  FiniteWall w;
  w.centre = c;
  w.axis[0] = u.normalized();
  w.axis[1] = (v - v.dot(w.axis[0]) * w.axis[0]).normalized();
  w.half_extent[0] = 0.5 * side_u;
  w.half_extent[1] = 0.5 * side_v;
  return w;
}

std::vector<PlaneWall> walls_from_domain(const Domain& domain) {
  std::vector<PlaneWall> walls;
  for (int axis = 0; axis < domain.dimension; ++axis) {
    for (int side = 0; side < 2; ++side) {
      if (domain.face[static_cast<std::size_t>(axis)][static_cast<std::size_t>(side)] !=
          FaceKind::kWall)
        continue;
      PlaneWall w;
      w.point = side == 0 ? domain.lo : domain.hi;
      w.normal = Vec3::Zero();
      w.normal[axis] = side == 0 ? 1.0 : -1.0;
      walls.push_back(w);
    }
  }
  return walls;
}

std::size_t add_rough_wall_layer(ParticleStore& store, int dimension, const Vec3& origin,
                                 const Vec3& e1, const Vec3& e2, double length1, double length2,
                                 double radius, double mass, std::int64_t first_id) {
  const double spacing = 2.0 * radius;
  const double row_spacing = std::sqrt(3.0) * radius;  // triangular lattice rows
  const auto columns = static_cast<long>(std::floor(length1 / spacing + 1e-9)) + 1;
  const long rows =
      dimension == 2 || length2 <= 0.0 ? 1 : static_cast<long>(std::floor(length2 / row_spacing + 1e-9)) + 1;
  const double inertia = solid_inertia(dimension, mass, radius);
  std::size_t added = 0;
  for (long row = 0; row < rows; ++row) {
    const double shift = (row % 2 == 1) ? radius : 0.0;
    for (long col = 0; col < columns; ++col) {
      const double s1 = shift + static_cast<double>(col) * spacing;
      if (s1 > length1 + 1e-12 * spacing) continue;
      const Vec3 x = origin + s1 * e1 + static_cast<double>(row) * row_spacing * e2;
      store.add(first_id + static_cast<std::int64_t>(added), x, Vec3::Zero(), Vec3::Zero(), radius,
                mass, inertia, kFixed);
      ++added;
    }
  }
  return added;
}

}  // namespace grainwave::particles::dem
