// Walls as infinite-mass, zero-radius partners: geometry, forces, removable plate, rough layer.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"
#include "particles/dem/Walls.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {
gw::Domain open_domain(int dimension) {
  gw::Domain d;
  d.dimension = dimension;
  d.lo = Vec3::Constant(-1.0);
  d.hi = Vec3::Constant(1.0);
  for (auto& axis : d.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  return d;
}
dem::ContactModel frictionless(double k) {
  return dem::make_contact_model("linear_spring_dashpot", {{"stiffness", k}}, "static_friction",
                                 {{"friction", 0.0}});
}
}  // namespace

TEST(Walls, ClosestPointsOfSegmentAndRectangle) {
  const auto seg = dem::FiniteWall::segment(Vec3(0, 0, 0), Vec3(2, 0, 0));
  EXPECT_NEAR((seg.closest_point(Vec3(1.0, 0.5, 0)) - Vec3(1, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((seg.closest_point(Vec3(3.0, 0.5, 0)) - Vec3(2, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((seg.closest_point(Vec3(-1.0, -1.0, 0)) - Vec3(0, 0, 0)).norm(), 0.0, 1e-15);
  const auto rect = dem::FiniteWall::rectangle(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitZ(), 2.0, 4.0);
  EXPECT_NEAR((rect.closest_point(Vec3(0.5, 1.0, 0.5)) - Vec3(0.5, 0, 0.5)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((rect.closest_point(Vec3(3.0, 1.0, -5.0)) - Vec3(1, 0, -2)).norm(), 0.0, 1e-15);
}

TEST(Walls, DomainFacesBecomeInwardPlanes) {
  gw::Domain d = open_domain(3);
  d.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kOpen};
  const auto walls = dem::walls_from_domain(d);
  ASSERT_EQ(walls.size(), 1u);
  EXPECT_EQ(walls[0].normal, Vec3(0, 1, 0));
  EXPECT_DOUBLE_EQ(walls[0].distance(Vec3(0, -0.9, 0)), 0.1);
}

TEST(Walls, PlaneForceIsSpringTimesOverlapAlongNormal) {
  dem::ContactForceField field(frictionless(500.0), open_domain(3));
  dem::PlaneWall floor;
  floor.point = Vec3(0, -0.5, 0);
  floor.normal = Vec3(0, 1, 0);
  field.plane_walls().push_back(floor);
  gw::ParticleStore s;
  s.add(0, Vec3(0.2, -0.45, 0.1), Vec3::Zero(), Vec3::Zero(), 0.1, 2.0, 0.008);
  field.evaluate(s, dem::HistoryStage::kSingle, 1e-3);
  EXPECT_NEAR(field.force()[0].y(), 500.0 * 0.05, 1e-12);
  EXPECT_NEAR(field.force()[0].x(), 0.0, 1e-15);
  // A removable plate: switched off, it exerts nothing.
  field.plane_walls().back().enabled = false;
  field.evaluate(s, dem::HistoryStage::kSingle, 1e-3);
  EXPECT_EQ(field.force()[0], Vec3::Zero());
  EXPECT_TRUE(field.contact_count() == 0);
}

TEST(Walls, SegmentEndPushesRadially) {
  dem::ContactForceField field(frictionless(100.0), open_domain(2));
  field.finite_walls().push_back(dem::FiniteWall::segment(Vec3(-1, 0, 0), Vec3(0, 0, 0)));
  gw::ParticleStore s;
  const Vec3 dir = Vec3(1, 1, 0).normalized();
  s.add(0, 0.08 * dir, Vec3::Zero(), Vec3::Zero(), 0.1, 1.0, 0.005);
  field.evaluate(s, dem::HistoryStage::kSingle, 1e-3);
  EXPECT_NEAR((field.force()[0] - 100.0 * 0.02 * dir).norm(), 0.0, 1e-13);
}

TEST(Walls, RoughLayerIsHexagonalAndFixed) {
  gw::ParticleStore s;
  const std::size_t n = dem::add_rough_wall_layer(s, 3, Vec3::Zero(), Vec3::UnitX(), Vec3::UnitZ(),
                                                  1.0, 1.0, 0.05, 1.0, 1000);
  ASSERT_GT(n, 0u);
  EXPECT_EQ(s.size(), n);
  // Nearest neighbours touch (distance 2r) and no pair overlaps.
  double nearest = 1e9;
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_TRUE(s.is_fixed(i));
    EXPECT_EQ(s.inverse_mass(i), 0.0);
    for (std::size_t j = i + 1; j < n; ++j) {
      const double d = (s.position[i] - s.position[j]).norm();
      nearest = std::min(nearest, d);
    }
  }
  EXPECT_NEAR(nearest, 0.1, 1e-12);
  // Number of sites: 11 per even row, 10 per odd row (shifted by r), rows sqrt(3) r apart.
  const long rows = static_cast<long>(std::floor(1.0 / (std::sqrt(3.0) * 0.05) + 1e-9)) + 1;
  EXPECT_EQ(n, static_cast<std::size_t>((rows + 1) / 2 * 11 + rows / 2 * 10));
}

TEST(Walls, SphereOnRoughLayerIsHeldByThreeFixedParticles) {
  const double r = 0.05;
  gw::ParticleStore s;
  dem::add_rough_wall_layer(s, 3, Vec3(-0.5, 0, -0.5), Vec3::UnitX(), Vec3::UnitZ(), 1.0, 1.0, r,
                            1.0, 1000);
  // The hollow above the triangle (0,0), (2r,0), (r, sqrt3 r) of row 0/1 near the centre.
  const Vec3 a = s.position[5], b = s.position[6];
  const Vec3 c = a + Vec3(r, 0, std::sqrt(3.0) * r);
  const Vec3 centroid = (a + b + c) / 3.0;
  const double height = std::sqrt(4 * r * r - (centroid - a).squaredNorm());
  gw::Domain d = open_domain(3);
  dem::ContactForceField field(frictionless(1e4), d);
  s.add(1, centroid + Vec3(0, 0.999 * height, 0), Vec3::Zero(), Vec3::Zero(), r, 1.0, 0.001);
  field.evaluate(s, dem::HistoryStage::kSingle, 1e-4);
  EXPECT_EQ(field.contact_count(), 3u);
  const Vec3 f = field.force().back();
  EXPECT_GT(f.y(), 0.0);
  EXPECT_NEAR(f.x(), 0.0, 1e-9 * f.y());
  EXPECT_NEAR(f.z(), 0.0, 1e-9 * f.y());
}

TEST(Walls, SphereDroppedOnRoughLayerSettlesInAHollow) {
  const double r = 0.05, m = 1.0, g = 9.81, k = 1e6;
  gw::ParticleStore s;
  dem::add_rough_wall_layer(s, 3, Vec3(-0.5, 0, -0.5), Vec3::UnitX(), Vec3::UnitZ(), 1.0, 1.0, r,
                            1.0, 1000);
  const Vec3 a = s.position[5], b = s.position[6];
  const Vec3 c = a + Vec3(r, 0, std::sqrt(3.0) * r);
  const Vec3 centroid = (a + b + c) / 3.0;
  const double rest_height = std::sqrt(4 * r * r - (centroid - a).squaredNorm());
  // Each of the three contacts carries m g / (3 cos θ) along its normal, cos θ = h / 2r; an
  // overlap δ along the normal lowers the centre by δ / cos θ.
  const double cos_theta = rest_height / (2 * r);
  const double overlap = m * g / (3.0 * k * cos_theta);
  const double expected_y = centroid.y() + rest_height - overlap / cos_theta;
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0, -g, 0);
  auto model = dem::make_contact_model("linear_spring_dashpot", {{"stiffness", k}, {"restitution", 0.3}},
                                       "static_friction", {{"friction", 0.0}});
  dem::ContactForceField field(model, open_domain(3), settings);
  s.add(1, centroid + Vec3(0, rest_height + 0.2 * r, 0), Vec3::Zero(), Vec3::Zero(), r, m,
        gw::solid_inertia(3, m, r));
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  dem::VelocityVerlet integrator;
  for (int step = 0; step < 20000; ++step) integrator.step(s, field, dt);
  const Vec3 x = s.position.back();
  EXPECT_NEAR(x.y(), expected_y, 1e-3 * overlap + 1e-12);
  EXPECT_NEAR(x.x(), centroid.x(), 1e-9);
  EXPECT_NEAR(x.z(), centroid.z(), 1e-9);
  EXPECT_EQ(field.contact_count(), 3u);
  for (std::size_t i = 0; i + 1 < s.size(); ++i) EXPECT_EQ(s.velocity[i], Vec3::Zero());
}

TEST(Walls, MovingFloorDragsSphereToRolling) {
  // A conveyor floor at speed U under a sphere at rest: in the floor's frame the sphere slides at
  // −U and ends rolling at −5U/7, so in the lab it ends at 2U/7 (the wall velocity enters v_ji).
  const double r = 1e-3, m = 1.09e-5, g = 9.81, U = 0.05, mu = 0.3;
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0, -g, 0);
  auto model = dem::make_contact_model(
      "linear_spring_dashpot", {{"stiffness", 1e3}, {"restitution", 0.5}}, "coulomb_spring",
      {{"stiffness", 2e3 / 7.0}, {"friction", mu}, {"damping_factor", 0.5}});
  dem::ContactForceField field(model, open_domain(3), settings);
  dem::PlaneWall floor;
  floor.point = Vec3(0, -0.5, 0);
  floor.normal = Vec3(0, 1, 0);
  field.plane_walls().push_back(floor);
  gw::ParticleStore s;
  s.add(0, Vec3(0, -0.5 + r - m * g / 1e3, 0), Vec3::Zero(), Vec3::Zero(), r, m,
        gw::solid_inertia(3, m, r));
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  dem::VelocityVerlet integrator;
  for (int step = 0; step < 2000; ++step) integrator.step(s, field, dt);  // settle
  field.plane_walls()[0].velocity = Vec3(U, 0, 0);
  const double t_roll = 2.0 * U / (7.0 * mu * g);
  const long steps = static_cast<long>(3.0 * t_roll / dt);
  for (long step = 0; step < steps; ++step) integrator.step(s, field, dt);
  EXPECT_NEAR(s.velocity[0].x(), 2.0 / 7.0 * U, 5e-3 * 2.0 / 7.0 * U);
  // Rolling on the belt: the contact point moves with it, v + ω × (−R ŷ) = U.
  EXPECT_NEAR(s.velocity[0].x() + r * s.angular_velocity[0].z(), U, 1e-3 * U);
}
