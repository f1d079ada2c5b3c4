// RetrospectiveCollider: exact two- and three-body results, walls, gravity, open and periodic
// faces, and dense-gas invariants (no overlap, energy and momentum) at packing fraction 0.5.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>

#include "core/Error.hpp"
#include "hard_sphere_scenes.hpp"
#include "particles/hardsphere/EventDrivenCollider.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace gp = grainwave::particles;
namespace hs = grainwave::particles::hardsphere;
using gp::Vec3;

namespace {

gp::Domain box(double length, gp::FaceKind kind, int dimension = 3) {
  gp::Domain d;
  d.dimension = dimension;
  d.lo = Vec3::Constant(-length / 2);
  d.hi = Vec3::Constant(length / 2);
  if (dimension == 2) d.lo.z() = d.hi.z() = 0.0;
  for (auto& f : d.face) f = {kind, kind};
  return d;
}

void add_sphere(gp::ParticleStore& s, const Vec3& x, const Vec3& v, double r = 0.5, double m = 1.0) {
  s.add(static_cast<std::int64_t>(s.size()), x, v, Vec3::Zero(), r, m, gp::solid_inertia(3, m, r));
}

TEST(RetrospectiveCollider, HeadOnPairMidStepEndsAtExactPositions) {
  // Gap 3 closes at speed 2: contact at t = 1.5; elastic, so at t = 3 both are back where they began.
  gp::ParticleStore s;
  add_sphere(s, Vec3(-2, 0, 0), Vec3(1, 0, 0));
  add_sphere(s, Vec3(2, 0, 0), Vec3(-1, 0, 0));
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  std::vector<hs::CollisionRecord> log;
  collider.record_collisions(&log);
  const auto stats = collider.step(s, box(20, gp::FaceKind::kPeriodic), 3.0);
  EXPECT_EQ(stats.collisions, 1);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_NEAR(log[0].time, 1.5, 1e-14);
  EXPECT_NEAR(s.position[0].x(), -2.0, 1e-14);
  EXPECT_NEAR(s.position[1].x(), 2.0, 1e-14);
  EXPECT_NEAR(s.velocity[0].x(), -1.0, 1e-14);
  EXPECT_NEAR(s.velocity[1].x(), 1.0, 1e-14);
}

TEST(RetrospectiveCollider, NewtonsCradleTransfersMomentumDownTheChainInOneStep) {
  // Three resting spheres 1e-9 apart, one incoming at speed 1: collisions in order 0-1, 1-2, 2-3.
  gp::ParticleStore s;
  add_sphere(s, Vec3(-3, 0, 0), Vec3(1, 0, 0));
  for (int k = 0; k < 3; ++k) add_sphere(s, Vec3(k * (1.0 + 1e-9), 0, 0), Vec3::Zero());
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  std::vector<hs::CollisionRecord> log;
  collider.record_collisions(&log);
  const auto stats = collider.step(s, box(40, gp::FaceKind::kPeriodic), 4.0);
  ASSERT_EQ(stats.collisions, 3);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(log[std::size_t(k)].id_a, k);
    EXPECT_EQ(log[std::size_t(k)].id_b, k + 1);
  }
  EXPECT_NEAR(log[0].time, 2.0, 1e-12);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.velocity[std::size_t(k)].norm(), 0.0, 1e-14);
  EXPECT_NEAR(s.velocity[3].x(), 1.0, 1e-14);
  // The last sphere left at t = 2 + 2e-9 from x = 2 + 2e-9.
  EXPECT_NEAR(s.position[3].x(), 2.0 + 2e-9 + (4.0 - 2.0 - 2e-9), 1e-12);
}

TEST(RetrospectiveCollider, BallBouncesOnFloorUnderGravity) {
  // y0 = 1.5, g = -2, r = 0.5: hits y = 0.5 at t = 1 with speed 2, bounces (e = 1), and at
  // t = 1.5 sits at 0.5 + 2 * 0.5 - 0.25 = 1.25 moving up at 1.
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 1.5, 0), Vec3::Zero());
  s.force[0] = Vec3(0, -2.0, 0);
  gp::Domain d = box(10, gp::FaceKind::kPeriodic);
  d.lo.y() = 0.0;
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  hs::StepStats total;
  for (int k = 0; k < 3; ++k) total.wall_hits += collider.step(s, d, 0.5).wall_hits;
  EXPECT_EQ(total.wall_hits, 1);
  EXPECT_NEAR(s.position[0].y(), 1.25, 1e-13);
  EXPECT_NEAR(s.velocity[0].y(), 1.0, 1e-13);
}

// A fixed particle (kFixed: infinite mass) is an obstacle: the moving sphere bounces back with
// factor e and the obstacle does not move; the event-driven collider agrees.
TEST(RetrospectiveCollider, FixedParticleIsAnImmovableObstacle) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(-2, 0, 0), Vec3(2, 0, 0));
  s.add(1, Vec3(0, 0, 0), Vec3::Zero(), Vec3::Zero(), 0.5, 1.0, 0.1, gp::kFixed);
  add_sphere(s, Vec3(0, 3, 0), Vec3::Zero());  // a bystander
  gp::ParticleStore s2 = s;
  const hs::CollisionLaw law{0.6, 0.2};
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{law});
  const gp::Domain d = box(20, gp::FaceKind::kPeriodic);
  const auto stats = collider.step(s, d, 1.0);
  // Contact at t = 0.5 (gap 1 at speed 2), then back at 1.2 for 0.5: x = -1 - 0.6.
  EXPECT_EQ(stats.collisions, 1);
  EXPECT_NEAR(s.velocity[0].x(), -1.2, 1e-14);
  EXPECT_NEAR(s.position[0].x(), -1.6, 1e-14);
  EXPECT_EQ(s.position[1], Vec3::Zero());
  EXPECT_EQ(s.velocity[1], Vec3::Zero());
  hs::EventDrivenCollider event_driven(hs::EventDrivenSettings{law});
  event_driven.initialize(s2, d);
  event_driven.advance_to(s2, d, 1.0);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR((s2.position[i] - s.position[i]).norm(), 0.0, 1e-14);
    EXPECT_NEAR((s2.velocity[i] - s.velocity[i]).norm(), 0.0, 1e-14);
  }
}

TEST(RetrospectiveCollider, OpenFaceRemovesAndPeriodicFaceWraps) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(4.0, 0, 0), Vec3(2, 0, 0));   // leaves through +x (open)
  add_sphere(s, Vec3(0, 4.0, 0), Vec3(0, 2, 0));   // crosses +y (periodic)
  add_sphere(s, Vec3(0, 0, 0), Vec3(0, 0, 0));     // stays
  gp::Domain d = box(10, gp::FaceKind::kPeriodic);
  d.face[0] = {gp::FaceKind::kOpen, gp::FaceKind::kOpen};
  hs::RetrospectiveCollider collider;
  const auto stats = collider.step(s, d, 1.0);
  EXPECT_EQ(stats.removed, 1);
  ASSERT_EQ(s.size(), 2u);
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s.id[i] == 1) {
      EXPECT_NEAR(s.position[i].y(), -4.0, 1e-14);
    }
  }
}

struct GasRun {
  double energy_drift = 0;     // max |E - E0| / E0
  double momentum_drift = 0;   // max |P - P0| / sum m|v|
  double worst_overlap = 0;    // max relative overlap after any step
  long collisions = 0, wall_hits = 0, restarts = 0, substeps = 0;
};

GasRun run_gas(hs::CollisionLaw law, bool walls, int steps, double dt) {
  gp::ParticleStore s;
  gp::Domain d;
  gp::testing::fcc_gas(s, d, 5, 0.5, 1.0, 2024);  // N = 500 at phi = 0.5
  if (walls) {  // the lattice's outer layer sits 0.4 from the faces; keep it off the walls
    d.face[0] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
    d.lo.x() -= 0.2;
    d.hi.x() += 0.2;
  }
  EXPECT_EQ(hs::max_relative_overlap(s, d, *std::make_unique<hs::CellList>()), 0.0);
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{law});
  hs::CellList scratch;
  GasRun run;
  const double e0 = gp::testing::kinetic_energy(s);
  const Vec3 p0 = gp::testing::momentum(s);
  const double p_scale = gp::testing::momentum_scale(s);
  double previous_energy = e0;
  for (int k = 0; k < steps; ++k) {
    const auto stats = collider.step(s, d, dt);
    run.collisions += stats.collisions;
    run.wall_hits += stats.wall_hits;
    run.restarts += stats.restarts;
    run.substeps += stats.substeps;
    run.worst_overlap = std::max(run.worst_overlap, hs::max_relative_overlap(s, d, scratch));
    const double e = gp::testing::kinetic_energy(s);
    run.energy_drift = std::max(run.energy_drift, std::abs(e - e0) / e0);
    EXPECT_LE(e, previous_energy * (1 + 1e-13)) << "energy grew in step " << k;
    previous_energy = e;
    run.momentum_drift = std::max(run.momentum_drift, (gp::testing::momentum(s) - p0).norm() / p_scale);
  }
  return run;
}

TEST(RetrospectiveCollider, DenseElasticGasConservesEnergyAndMomentum) {
  const GasRun run = run_gas(hs::CollisionLaw{1.0, 0.0}, false, 200, 0.02);
  std::printf("phi=0.5 N=500 e=1 mu=0: %ld collisions, %ld restarts, energy drift %.2e, "
              "momentum drift %.2e, worst overlap %.2e r\n",
              run.collisions, run.restarts, run.energy_drift, run.momentum_drift, run.worst_overlap);
  EXPECT_GT(run.collisions, 25000);  // ~ N * Gamma * t / 2 with Gamma ~ 40 (Enskog)
  EXPECT_LT(run.worst_overlap, 1e-10);
  EXPECT_LT(run.energy_drift, 1e-12);
  EXPECT_LT(run.momentum_drift, 1e-13);
}

TEST(RetrospectiveCollider, DenseFrictionalInelasticGasHasNoOverlapAndKeepsMomentum) {
  const GasRun run = run_gas(hs::CollisionLaw{0.8, 0.3}, false, 30, 0.02);
  std::printf("phi=0.5 N=500 e=0.8 mu=0.3: %ld collisions, %ld restarts, worst overlap %.2e r, "
              "momentum drift %.2e\n", run.collisions, run.restarts, run.worst_overlap, run.momentum_drift);
  EXPECT_GT(run.collisions, 1500);  // fewer than elastic: the gas cools
  EXPECT_LT(run.worst_overlap, 1e-10);
  EXPECT_LT(run.momentum_drift, 1e-13);
  EXPECT_GT(run.energy_drift, 0.05);  // inelastic and frictional: energy must be lost
}

TEST(RetrospectiveCollider, DenseGasBetweenWallsHasNoOverlap) {
  const GasRun run = run_gas(hs::CollisionLaw{1.0, 0.0}, true, 30, 0.02);
  std::printf("phi=0.5 N=500 walls in x, e=1: %ld collisions, %ld wall hits, worst overlap %.2e r, "
              "energy drift %.2e\n", run.collisions, run.wall_hits, run.worst_overlap, run.energy_drift);
  EXPECT_GT(run.wall_hits, 50);
  EXPECT_LT(run.worst_overlap, 1e-10);
  EXPECT_LT(run.energy_drift, 1e-12);  // walls are elastic and frictionless here
}

TEST(RetrospectiveCollider, LargeStepIsSubdividedAndStillExact) {
  // A step ten times the mean free time: the collider must subdivide, not tunnel or overlap.
  const GasRun run = run_gas(hs::CollisionLaw{1.0, 0.0}, false, 2, 0.25);
  EXPECT_GT(run.substeps, 2);
  EXPECT_LT(run.worst_overlap, 1e-10);
  EXPECT_LT(run.energy_drift, 1e-12);
}

}  // namespace
