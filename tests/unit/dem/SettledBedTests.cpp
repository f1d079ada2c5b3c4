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
  // Soft enough for a quick run (overlap under the full bed ≈ 0.005 d) and strongly damped, as
  // 002 §3.2.4 suggests for generating packed beds.
  const double k_n = 1000.0;
  auto model = dem::make_contact_model(
      "linear_spring_dashpot", {{"stiffness", k_n}, {"restitution", 0.1}}, "coulomb_spring",
      {{"stiffness", 2.0 / 7.0 * k_n}, {"friction", 0.3}, {"damping_factor", 0.5}});
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
  // At rest: mean kinetic energy per particle below 1e-5 m g d. (A single sphere may keep
  // rolling on the floor under the bed: there is no rolling resistance, so the maximum speed
  // is not a useful criterion.)
  double kinetic_per_particle = 1.0;
  for (; step * dt < 120.0; ++step) {
    integrator.step(s, field, dt);
    if (step % 200 == 0 && step * dt > 5.0) {
      double kinetic = 0.0;
      for (const Vec3& v : s.velocity) kinetic += 0.5 * mass * v.squaredNorm();
      kinetic_per_particle = kinetic / static_cast<double>(s.size());
      if (kinetic_per_particle < 1e-5) break;
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
              "kinetic energy per particle %.1e, bed height %.2f, phi = %.4f\n",
              s.size(), step * dt, step, seconds, s.size() * step / seconds, kinetic_per_particle,
              top, phi);
  EXPECT_LT(kinetic_per_particle, 1e-5) << "the bed did not come to rest";
  EXPECT_GT(phi, 0.58);
  EXPECT_LT(phi, 0.64);
}
