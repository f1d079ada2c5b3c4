// A bed of monodisperse frictional spheres poured under gravity onto a floor in a periodic box
// settles to a random packing: φ between random loose (≈0.58) and random close (≈0.64,
// Berryman 1983; shared/reference/README.md). Units: d = 1, m = 1, g = 1.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <random>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {
/// Volume of a sphere (centre height yc, radius r) lying between the planes y = a and y = b.
double sphere_volume_in_slab(double yc, double r, double a, double b) {
  const double lo = std::max(a, yc - r) - yc, hi = std::min(b, yc + r) - yc;
  if (hi <= lo) return 0.0;
  auto primitive = [r](double s) { return std::numbers::pi * (r * r * s - s * s * s / 3.0); };
  return primitive(hi) - primitive(lo);
}
}  // namespace

TEST(SettledBed, PackingFractionOfPouredMonodisperseSpheres) {
  const double radius = 0.5, mass = 1.0, length = 8.0;
  const int per_row = 7, layers = 21;  // 1029 particles
  gw::Domain domain;
  domain.lo = Vec3::Zero();
  domain.hi = Vec3(length, 40.0, length);
  domain.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kOpen};
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0, -1.0, 0);
  const double k_n = 2000.0;
  auto model = dem::make_contact_model(
      "linear_spring_dashpot", {{"stiffness", k_n}, {"restitution", 0.3}}, "coulomb_spring",
      {{"stiffness", 2.0 / 7.0 * k_n}, {"friction", 0.3}, {"damping_factor", 0.3}});
  dem::ContactForceField field(model, domain, settings);

  gw::ParticleStore s;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  const double spacing = length / per_row;
  std::int64_t id = 0;
  for (int l = 0; l < layers; ++l)
    for (int i = 0; i < per_row; ++i)
      for (int k = 0; k < per_row; ++k) {
        const Vec3 x((i + 0.5) * spacing + jitter(rng), 0.6 + l * spacing + jitter(rng),
                     (k + 0.5) * spacing + jitter(rng));
        const Vec3 v(jitter(rng), jitter(rng), jitter(rng));
        s.add(id++, x, v, Vec3::Zero(), radius, mass, gw::solid_inertia(3, mass, radius));
      }
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  dem::VelocityVerlet integrator;
  const auto start = std::chrono::steady_clock::now();
  long step = 0;
  double max_speed = 1.0;
  for (; step * dt < 60.0; ++step) {
    integrator.step(s, field, dt);
    if (step % 500 == 0 && step * dt > 10.0) {
      max_speed = 0.0;
      for (const Vec3& v : s.velocity) max_speed = std::max(max_speed, v.norm());
      if (std::getenv("DEM_DEBUG")) {
        double ke = 0; std::size_t arg = 0;
        for (std::size_t i = 0; i < s.size(); ++i) { ke += 0.5 * s.velocity[i].squaredNorm(); if (s.velocity[i].norm() >= max_speed) arg = i; }
        std::printf("t=%.1f ke=%.3e max=%.3e at y=%.2f contacts=%zu\n", step*dt, ke, max_speed, s.position[arg].y(), field.contacts().size());
      }
      if (max_speed < 1e-3) break;
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  double top = 0.0;
  for (const Vec3& x : s.position) top = std::max(top, x.y());
  const double a = 2.0, b = top - 2.0;  // skip the layering at the floor and the free surface
  double solid = 0.0;
  for (const Vec3& x : s.position) solid += sphere_volume_in_slab(x.y(), radius, a, b);
  const double phi = solid / (length * length * (b - a));
  std::printf("settled bed: %zu particles, t = %.1f, %ld steps in %.1f s (%.2e particle-steps/s), "
              "max speed %.1e, bed height %.2f, phi = %.4f\n",
              s.size(), step * dt, step, seconds, s.size() * step / seconds, max_speed, top, phi);
  EXPECT_LT(max_speed, 1e-3) << "the bed did not come to rest";
  EXPECT_GT(phi, 0.58);
  EXPECT_LT(phi, 0.64);
}
