// Time step from Eq. 3.17, free flight under gravity, recycling drag (Eq. 3.18).
#include "particles/dem/Integrators.hpp"
#include "particles/dem/LinearSpringDashpot.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {
gw::Domain open_domain() {
  gw::Domain d;
  d.lo = Vec3::Constant(-10.0);
  d.hi = Vec3::Constant(10.0);
  for (auto& axis : d.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  return d;
}
dem::ContactModel linear(double k, double e) {
  return dem::make_contact_model("linear_spring_dashpot", {{"stiffness", k}, {"restitution", e}},
                                 "static_friction", {{"friction", 0.0}});
}
}  // namespace

TEST(StableTimeStep, UsesLightestPairAndEq317) {
  gw::ParticleStore s;
  s.add(0, Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), 1.0, 4.0, 1.6);
  s.add(1, Vec3(5, 0, 0), Vec3::Zero(), Vec3::Zero(), 0.5, 0.5, 0.05);
  s.add(2, Vec3(9, 0, 0), Vec3::Zero(), Vec3::Zero(), 0.1, 1e-6, 1e-9, gw::kFixed);  // ignored
  const dem::LinearSpringDashpot law({100.0, 0.8});
  const double log_e = std::log(0.8);
  const double tau = std::sqrt((std::numbers::pi * std::numbers::pi + log_e * log_e) * 0.25 / 100.0);
  EXPECT_NEAR(dem::stable_time_step(s, law, 50), tau / 50.0, 1e-15);
}

TEST(Integrators, BallisticFlightIsExactUnderGravity) {
  for (int which = 0; which < 2; ++which) {
    dem::ContactForceSettings settings;
    settings.gravity = Vec3(0, -9.81, 0);
    dem::ContactForceField field(linear(1e3, 1.0), open_domain(), settings);
    gw::ParticleStore s;
    s.add(0, Vec3::Zero(), Vec3(1.0, 2.0, 0), Vec3::Zero(), 0.1, 1.0, 0.004);
    dem::VelocityVerlet vv;
    dem::RungeKutta2 rk;
    const double dt = 1e-3;
    for (int k = 0; k < 300; ++k) which == 0 ? vv.step(s, field, dt) : rk.step(s, field, dt);
    const double t = 0.3;
    EXPECT_NEAR(s.position[0].x(), t, 1e-12);
    EXPECT_NEAR(s.position[0].y(), 2.0 * t - 0.5 * 9.81 * t * t, 1e-12);
    EXPECT_NEAR(s.velocity[0].y(), 2.0 - 9.81 * t, 1e-12);
  }
}

TEST(Integrators, RecyclingDragReachesTerminalVelocity) {
  const double g = 9.81, v_term = 0.7;
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0, -g, 0);
  settings.drag_zones.push_back(dem::RecyclingDragZone::from_terminal_velocity(
      Vec3::Constant(-100), Vec3::Constant(100), g, v_term));
  gw::Domain d = open_domain();
  d.lo = Vec3::Constant(-200);
  d.hi = Vec3::Constant(200);
  dem::ContactForceField field(linear(1e3, 1.0), d, settings);
  gw::ParticleStore s;
  s.add(0, Vec3::Zero(), Vec3(0, 0, 0), Vec3::Zero(), 0.1, 3.0, 0.012);
  dem::RungeKutta2 rk;
  // Exact: v(t) = −v_term tanh(g t / v_term); Δt small enough that Heun's O(Δt²) error < 1e-6.
  const double dt = 2.5e-4;
  for (int k = 0; k < 800; ++k) rk.step(s, field, dt);
  EXPECT_NEAR(s.velocity[0].y(), -v_term * std::tanh(g * 0.2 / v_term), 1e-6);
  for (int k = 0; k < 8000; ++k) rk.step(s, field, dt);
  EXPECT_NEAR(s.velocity[0].y(), -v_term, 1e-6 * v_term);
  // Outside the zone there is no drag.
  field.settings().drag_zones[0].hi = Vec3::Constant(-150);
  s.velocity[0] = Vec3(0, -1.0, 0);
  rk.step(s, field, dt);
  EXPECT_NEAR(s.velocity[0].y(), -1.0 - g * dt, 1e-12);
}
