// EventDrivenCollider: exact small cases, agreement with the retrospective collider, and the
// Enskog collision frequency of the hard-sphere fluid.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <array>
#include <cstdio>

#include "core/Error.hpp"
#include "hard_sphere_scenes.hpp"
#include "particles/hardsphere/EventDrivenCollider.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace gp = grainwave::particles;
namespace hs = grainwave::particles::hardsphere;
using gp::Vec3;

namespace {

gp::Domain cube(double length, gp::FaceKind kind) {
  gp::Domain d;
  d.lo = Vec3::Constant(-length / 2);
  d.hi = Vec3::Constant(length / 2);
  for (auto& f : d.face) f = {kind, kind};
  return d;
}

void add_sphere(gp::ParticleStore& s, const Vec3& x, const Vec3& v, double r = 0.5, double m = 1.0) {
  s.add(static_cast<std::int64_t>(s.size()), x, v, Vec3::Zero(), r, m, gp::solid_inertia(3, m, r));
}

TEST(EventDrivenCollider, HeadOnPairAcrossPeriodicFace) {
  // The pair meets across the periodic x face: gap 20 - 17 - 1 = 2 closes at speed 2 at t = 1.
  gp::ParticleStore s;
  add_sphere(s, Vec3(8.5, 0, 0), Vec3(1, 0, 0));
  add_sphere(s, Vec3(-8.5, 0, 0), Vec3(-1, 0, 0));
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{1.0, 0.0}});
  std::vector<hs::CollisionRecord> log;
  collider.record_collisions(&log);
  const gp::Domain d = cube(20, gp::FaceKind::kPeriodic);
  collider.initialize(s, d);
  const auto stats = collider.advance_to(s, d, 3.0);
  EXPECT_EQ(stats.collisions, 1);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_NEAR(log[0].time, 1.0, 1e-14);
  EXPECT_NEAR(s.position[0].x(), 8.5 - 1.0, 1e-13);  // back 1 + then 2 the other way
  EXPECT_NEAR(s.velocity[0].x(), -1.0, 1e-14);
  EXPECT_GT(stats.cell_crossings, 0);
}

TEST(EventDrivenCollider, BallBouncesOnFloorUnderGravity) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 1.5, 0), Vec3::Zero());
  s.force[0] = Vec3(0, -2.0, 0);
  gp::Domain d = cube(10, gp::FaceKind::kPeriodic);
  d.lo.y() = 0.0;
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{1.0, 0.0}});
  collider.initialize(s, d);
  const auto stats = collider.advance_to(s, d, 1.5);
  EXPECT_EQ(stats.wall_hits, 1);
  EXPECT_NEAR(s.position[0].y(), 1.25, 1e-13);
  EXPECT_NEAR(s.velocity[0].y(), 1.0, 1e-13);
}

// An elastic ball bouncing on a floor for many periods: the bounce height (energy) is kept, it
// never sinks into the floor, and both colliders agree on the bounce times (period 2).
TEST(EventDrivenCollider, ElasticBallKeepsBouncingForManyPeriods) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 1.5, 0), Vec3(0.3, 0, 0));
  s.force[0] = Vec3(0, -2.0, 0);
  gp::Domain d = cube(10, gp::FaceKind::kPeriodic);
  d.lo.y() = 0.0;
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  gp::ParticleStore s2 = s;
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{1.0, 0.0}});
  collider.initialize(s, d);
  hs::RetrospectiveCollider retrospective(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  long hits = 0, hits2 = 0;
  for (int k = 1; k <= 400; ++k) {
    hits += collider.advance_to(s, d, 0.25 * k).wall_hits;
    hits2 += retrospective.step(s2, d, 0.25).wall_hits;
    for (const gp::ParticleStore* p : {&s, &s2}) {
      const double y = p->position[0].y(), vy = p->velocity[0].y();
      ASSERT_GE(y, 0.5 - 1e-12) << "step " << k;
      ASSERT_NEAR(0.5 * vy * vy + 2.0 * y, 3.0, 1e-11) << "step " << k;  // v^2/2 + g y
    }
  }
  EXPECT_EQ(hits, 50);  // first bounce at t = 1, then every 2 up to t = 100
  EXPECT_EQ(hits2, 50);
}

// A ball with e < 1 on a floor bounces infinitely often before t* = finite (inelastic collapse).
// Both colliders must report it instead of hanging.
TEST(EventDrivenCollider, InelasticCollapseOnFloorIsReportedNotHung) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 1.5, 0), Vec3::Zero());
  s.force[0] = Vec3(0, -2.0, 0);
  gp::Domain d = cube(10, gp::FaceKind::kPeriodic);
  d.lo.y() = 0.0;
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  gp::ParticleStore s2 = s;
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{0.5, 0.0}});
  collider.initialize(s, d);
  // Bounce k ends at t_k = 1 + 2 (e + ... + e^k): collapse at t* = 1 + 2 e / (1 - e) = 3.
  EXPECT_NO_THROW(collider.advance_to(s, d, 2.9));
  EXPECT_THROW(collider.advance_to(s, d, 4.0), grainwave::NumericalFailure);
  hs::RetrospectiveCollider retrospective(hs::RetrospectiveSettings{hs::CollisionLaw{0.5, 0.0}});
  EXPECT_THROW(retrospective.step(s2, d, 4.0), grainwave::NumericalFailure);
}

TEST(EventDrivenCollider, RejectsUnequalAccelerations) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 0, 0), Vec3::Zero());
  add_sphere(s, Vec3(2, 0, 0), Vec3::Zero());
  s.force[1] = Vec3(1, 0, 0);
  hs::EventDrivenCollider collider;
  EXPECT_THROW(collider.initialize(s, cube(10, gp::FaceKind::kPeriodic)), std::invalid_argument);
}

// Two unit spheres in a box 10^5 diameters wide: 10^15 cells would overflow their numbering.
TEST(EventDrivenCollider, RejectsBoxesOfMoreCellsThanCanBeNumbered) {
  gp::ParticleStore s;
  add_sphere(s, Vec3(0, 0, 0), Vec3(1, 0, 0));
  add_sphere(s, Vec3(2, 0, 0), Vec3::Zero());
  hs::EventDrivenCollider collider;
  EXPECT_THROW(collider.initialize(s, cube(1e5, gp::FaceKind::kWall)), std::invalid_argument);
  EXPECT_NO_THROW(collider.initialize(s, cube(100, gp::FaceKind::kWall)));  // 100^3 cells
}

struct Comparison {
  std::size_t collisions = 0;
  double worst_time = 0, worst_state = 0;
  bool same_sequence = true;
};

Comparison compare_with_retrospective(const gp::ParticleStore& start, const gp::Domain& d, hs::CollisionLaw law) {
  gp::ParticleStore a = start, b = start;
  std::vector<hs::CollisionRecord> log_a, log_b;
  hs::RetrospectiveCollider retrospective(hs::RetrospectiveSettings{law});
  retrospective.record_collisions(&log_a);
  const double dt = 0.01;
  const int steps = 100;
  std::vector<hs::CollisionRecord> step_log;
  for (int k = 0; k < steps; ++k) {
    const std::size_t before = log_a.size();
    retrospective.step(a, d, dt);
    for (std::size_t m = before; m < log_a.size(); ++m) log_a[m].time += k * dt;  // absolute
  }
  hs::EventDrivenCollider event_driven(hs::EventDrivenSettings{law});
  event_driven.record_collisions(&log_b);
  event_driven.initialize(b, d);
  event_driven.advance_to(b, d, steps * dt);

  Comparison c;
  c.collisions = log_a.size();
  c.same_sequence = log_a.size() == log_b.size();
  for (std::size_t m = 0; c.same_sequence && m < log_a.size(); ++m) {
    const auto key = [](const hs::CollisionRecord& r) {
      return std::make_pair(std::min(r.id_a, r.id_b), std::max(r.id_a, r.id_b));
    };
    c.same_sequence = key(log_a[m]) == key(log_b[m]);
    c.worst_time = std::max(c.worst_time, std::abs(log_a[m].time - log_b[m].time));
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    c.worst_state = std::max(c.worst_state, d.separation(a.position[i], b.position[i]).norm());
    c.worst_state = std::max(c.worst_state, (a.velocity[i] - b.velocity[i]).norm());
    c.worst_state = std::max(c.worst_state, (a.angular_velocity[i] - b.angular_velocity[i]).norm());
  }
  return c;
}

Comparison compare_with_retrospective(hs::CollisionLaw law, bool gravity_and_walls) {
  gp::ParticleStore a;
  gp::Domain d;
  gp::testing::fcc_gas(a, d, 3, 0.3, 1.0, 99);  // N = 108
  if (gravity_and_walls) {
    d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
    d.lo.y() -= 0.2;  // keep the outer lattice layer off the walls
    d.hi.y() += 0.2;
    for (std::size_t i = 0; i < a.size(); ++i) a.force[i] = a.mass[i] * Vec3(0, -3.0, 0);
  }
  return compare_with_retrospective(a, d, law);
}

/// What every comparison with the retrospective collider must show: enough collisions, the same
/// sequence, and times and states equal to round-off.
void expect_agreement(const char* what, const Comparison& c) {
  std::printf("%s: %zu collisions, same order %d, worst time diff %.2e, state diff %.2e\n", what,
              c.collisions, c.same_sequence, c.worst_time, c.worst_state);
  EXPECT_GT(c.collisions, 300u);
  EXPECT_TRUE(c.same_sequence);
  EXPECT_LT(c.worst_time, 1e-10);
  EXPECT_LT(c.worst_state, 1e-9);
}

// Two runs processed the same collisions at the same times and ended in the same state, bitwise.
void expect_same_run(const std::vector<hs::CollisionRecord>& log_a, const std::vector<hs::CollisionRecord>& log_b,
                     const gp::ParticleStore& a, const gp::ParticleStore& b) {
  ASSERT_EQ(log_a.size(), log_b.size());
  for (std::size_t m = 0; m < log_a.size(); ++m) {
    ASSERT_EQ(log_a[m].time, log_b[m].time) << "collision " << m;
    ASSERT_EQ(log_a[m].id_a, log_b[m].id_a) << "collision " << m;
    ASSERT_EQ(log_a[m].id_b, log_b[m].id_b) << "collision " << m;
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.position[i], b.position[i]) << "particle " << i;
    ASSERT_EQ(a.velocity[i], b.velocity[i]) << "particle " << i;
    ASSERT_EQ(a.angular_velocity[i], b.angular_velocity[i]) << "particle " << i;
  }
}

/// 256 rough spheres under gravity between walls in y, periodic in x and z (FCC start).
void rough_gas_between_walls(gp::ParticleStore& start, gp::Domain& d) {
  gp::testing::fcc_gas(start, d, 4, 0.3, 1.0, 7);
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  d.lo.y() -= 0.2;
  d.hi.y() += 0.2;
  for (std::size_t i = 0; i < start.size(); ++i) start.force[i] = start.mass[i] * Vec3(0, -3.0, 0);
}

// The AVX2 paths (where the machine has it: the pair scan in its four variants, the vector
// gather of the adjacent cells, the unaccelerated crossing time) and the portable ones do the
// same operations in the same order: the collision sequence and the final state are bitwise
// equal. Without AVX2 both runs take the portable paths.
void expect_vector_scan_equals_portable(const gp::ParticleStore& start, const gp::Domain& d, hs::CollisionLaw law,
                                        double t_end, std::size_t least_collisions) {
  std::array<gp::ParticleStore, 2> store{start, start};
  std::array<std::vector<hs::CollisionRecord>, 2> log;
  for (std::size_t run = 0; run < 2; ++run) {
    hs::EventDrivenSettings settings{law};
    settings.vector_scan = run == 0;
    hs::EventDrivenCollider collider(settings);
    collider.record_collisions(&log[run]);
    collider.initialize(store[run], d);
    collider.advance_to(store[run], d, t_end);
  }
  std::printf("N = %zu: vector and portable scans: %zu and %zu collisions\n", start.size(), log[0].size(),
              log[1].size());
  EXPECT_GT(log[0].size(), least_collisions);
  expect_same_run(log[0], log[1], store[0], store[1]);
}

// A rough inelastic gas under gravity between walls: the accelerated kernel, with images.
TEST(EventDrivenCollider, VectorAndPortableScansAreBitwiseEqual) {
  gp::ParticleStore start;
  gp::Domain d;
  rough_gas_between_walls(start, d);
  expect_vector_scan_equals_portable(start, d, hs::CollisionLaw{0.9, 0.3}, 1.0, 500);
}

// Periodic gases without acceleration: the kernels without the acceleration's terms, with and
// without images (interior cells of boxes 11 and 40 cells wide), the unaccelerated crossing
// time, and (N = 37 044, a padded grid of 42^3 cells) the neighbours of interior cells found by
// index arithmetic; 2D disks; and a gas between two walls.
TEST(EventDrivenCollider, VectorAndPortableScansAreBitwiseEqualWithoutAcceleration) {
  for (const int k : {6, 21}) {
    gp::ParticleStore start;
    gp::Domain d;
    gp::testing::fcc_gas(start, d, k, 0.3, 1.0, 11);  // N = 864, 37 044
    expect_vector_scan_equals_portable(start, d, hs::CollisionLaw{1.0, 0.0}, k == 6 ? 1.0 : 0.5, 3000);
  }
  gp::ParticleStore disks;
  gp::Domain d;
  gp::testing::disk_gas(disks, d, 20, 0.4, 1.0, 5);  // 400 disks
  expect_vector_scan_equals_portable(disks, d, hs::CollisionLaw{0.95, 0.2}, 1.0, 500);
  // Walls across y without gravity: wall contacts searched, crossings next to a wall face.
  // (The crossing masks' wall faces never decide here: a wall contact always comes first.)
  gp::ParticleStore walled;
  gp::testing::fcc_gas(walled, d, 6, 0.3, 1.0, 13);
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  d.lo.y() -= 0.2;
  d.hi.y() += 0.2;
  expect_vector_scan_equals_portable(walled, d, hs::CollisionLaw{0.9, 0.3}, 1.0, 2000);
}

TEST(EventDrivenCollider, AgreesWithRetrospectiveElasticGas) {
  expect_agreement("elastic gas", compare_with_retrospective(hs::CollisionLaw{1.0, 0.0}, false));
}

// One large sphere among small ones: the cells (one large diameter wide) hold a dozen particles
// or more, whose rings are walked, cut and rejoined at every crossing. Event-driven and
// retrospective must see the same collisions in the same order.
TEST(EventDrivenCollider, AgreesWithRetrospectiveInCrowdedCells) {
  gp::ParticleStore small;
  gp::Domain d;
  gp::testing::fcc_gas(small, d, 5, 0.1, 2.0, 31);  // 500 unit spheres, box 13.8 wide
  const Vec3 centre = 0.5 * (d.lo + d.hi);
  const double big = 2.0;
  gp::ParticleStore start;
  add_sphere(start, centre, Vec3(0.3, -0.2, 0.1), big, 16.0);
  for (std::size_t i = 0; i < small.size(); ++i) {
    if ((small.position[i] - centre).norm() < big + 0.7) continue;
    add_sphere(start, small.position[i], small.velocity[i]);
  }
  std::printf("crowded cells: %zu spheres in 3^3 cells\n", start.size());
  expect_agreement("crowded cells", compare_with_retrospective(start, d, hs::CollisionLaw{0.95, 0.1}));
}

// Without friction an impulse lies along the normal: spinning spheres keep their angular
// velocities exactly, however many collisions (the general impulse algebra, n x (j n), would
// leave round-off in them), while their velocities change.
// A restart: a collider resumed from the schedule() of another, with a copy of the store that
// one wrote back, processes the same events as the one that goes on (a rough inelastic gas
// under gravity between walls, so that rings, bursts, wall partners and spins all matter).
// Predicting afresh from the same store (initialize) is not enough: other round-off.
TEST(EventDrivenCollider, ResumedFromItsScheduleGoesOnBitwise) {
  gp::ParticleStore start;
  gp::Domain d;
  rough_gas_between_walls(start, d);
  const hs::EventDrivenSettings settings{hs::CollisionLaw{0.9, 0.3}};
  hs::EventDrivenCollider going_on(settings);
  going_on.initialize(start, d);
  going_on.advance_to(start, d, 0.5);
  const hs::EventSchedule schedule = going_on.schedule();
  EXPECT_EQ(schedule.time, 0.5);
  std::array<gp::ParticleStore, 3> store{start, start, start};
  std::array<std::vector<hs::CollisionRecord>, 3> log;
  hs::EventDrivenCollider resumed(settings), fresh(settings);
  resumed.resume(store[1], d, schedule);
  fresh.initialize(store[2], d, 0.5);
  // The resumed state is the saved one, rings included (their order decides ties only, which
  // this gas does not meet, so the run below alone would not see a ring rebuilt in index order).
  const hs::EventSchedule again = resumed.schedule();
  EXPECT_EQ(again.collision_time, schedule.collision_time);
  EXPECT_EQ(again.crossing_time, schedule.crossing_time);
  EXPECT_EQ(again.partner, schedule.partner);
  EXPECT_EQ(again.partner_count, schedule.partner_count);
  EXPECT_EQ(again.counter, schedule.counter);
  EXPECT_EQ(again.burst_start, schedule.burst_start);
  EXPECT_EQ(again.burst_count, schedule.burst_count);
  EXPECT_EQ(again.crossing_face, schedule.crossing_face);
  EXPECT_EQ(again.cell, schedule.cell);
  EXPECT_EQ(again.ring_next, schedule.ring_next);
  EXPECT_EQ(again.head, schedule.head);
  const hs::EventSchedule binned = fresh.schedule();
  EXPECT_TRUE(binned.head != schedule.head || binned.ring_next != schedule.ring_next)
      << "no cell's ring in another order than by index";
  std::array<hs::EventDrivenCollider*, 3> colliders{&going_on, &resumed, &fresh};
  for (std::size_t run = 0; run < 3; ++run) {
    colliders[run]->record_collisions(&log[run]);
    for (const double t : {0.8, 1.1, 1.5}) colliders[run]->advance_to(store[run], d, t);
  }
  EXPECT_GT(log[0].size(), 300u);
  expect_same_run(log[0], log[1], store[0], store[1]);
  bool fresh_differs = log[2].size() != log[0].size();
  for (std::size_t i = 0; i < start.size(); ++i)
    fresh_differs = fresh_differs || store[2].position[i] != store[0].position[i];
  EXPECT_TRUE(fresh_differs) << "predicting afresh gave the same state: the test would not see a lost schedule";
  // A schedule that does not fit is refused, not followed.
  hs::EventSchedule broken = schedule;
  broken.partner[3] = static_cast<std::int64_t>(start.size());
  EXPECT_THROW(resumed.resume(store[1], d, broken), std::invalid_argument);
  broken = schedule;
  broken.head.pop_back();
  EXPECT_THROW(resumed.resume(store[1], d, broken), std::invalid_argument);
  broken = schedule;  // a particle's ring moved to a neighbouring cell
  broken.cell[3 * 5] = broken.cell[3 * 5] == 0 ? 1 : 0;
  EXPECT_THROW(resumed.resume(store[1], d, broken), std::invalid_argument);
}

TEST(EventDrivenCollider, FrictionlessCollisionsLeaveSpinsExactlyAlone) {
  gp::ParticleStore s;
  gp::Domain d;
  gp::testing::fcc_gas(s, d, 4, 0.3, 1.0, 21);  // 256 spheres, random spins
  const auto spins = s.angular_velocity;
  const auto velocities = s.velocity;
  hs::EventDrivenCollider collider({hs::CollisionLaw{0.9, 0.0}});
  collider.initialize(s, d);
  const hs::EventStats stats = collider.advance_to(s, d, 2.0);
  EXPECT_GT(stats.collisions, 1000);
  std::size_t changed = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    ASSERT_EQ(s.angular_velocity[i], spins[i]) << "particle " << i;
    changed += s.velocity[i] != velocities[i] ? 1 : 0;
  }
  EXPECT_GT(changed, s.size() / 2);
}

TEST(EventDrivenCollider, AgreesWithRetrospectiveFrictionalGasUnderGravityWithWalls) {
  expect_agreement("frictional gas, gravity, walls", compare_with_retrospective(hs::CollisionLaw{0.9, 0.2}, true));
}

// 2D disks (I = m r^2 / 2) under gravity between walls, periodic in x, with friction: the two
// colliders must give the same collision sequence, and neither may leave an overlap.
TEST(EventDrivenCollider, AgreesWithRetrospectiveForDisksUnderGravity) {
  gp::ParticleStore a;
  gp::Domain d;
  gp::testing::disk_gas(a, d, 12, 0.4, 1.0, 8);  // 144 disks
  d.face[1] = {gp::FaceKind::kWall, gp::FaceKind::kWall};
  for (std::size_t i = 0; i < a.size(); ++i) a.force[i] = a.mass[i] * Vec3(0, -2.0, 0);
  gp::ParticleStore b = a;
  const hs::CollisionLaw law{0.9, 0.3};
  std::vector<hs::CollisionRecord> log_a, log_b;
  hs::RetrospectiveCollider retrospective(hs::RetrospectiveSettings{law});
  retrospective.record_collisions(&log_a);
  hs::CellList scratch;
  double worst_overlap = 0.0;
  const double dt = 0.01;
  for (int k = 0; k < 100; ++k) {
    const std::size_t before = log_a.size();
    retrospective.step(a, d, dt);
    for (std::size_t m = before; m < log_a.size(); ++m) log_a[m].time += k * dt;
    worst_overlap = std::max(worst_overlap, hs::max_relative_overlap(a, d, scratch));
  }
  hs::EventDrivenCollider event_driven(hs::EventDrivenSettings{law});
  event_driven.record_collisions(&log_b);
  event_driven.initialize(b, d);
  event_driven.advance_to(b, d, 100 * dt);
  EXPECT_LT(worst_overlap, 1e-10);
  EXPECT_LT(hs::max_relative_overlap(b, d, scratch), 1e-10);
  ASSERT_EQ(log_a.size(), log_b.size());
  EXPECT_GT(log_a.size(), 200u);
  double worst_time = 0.0, worst_state = 0.0;
  for (std::size_t m = 0; m < log_a.size(); ++m) {
    ASSERT_EQ(std::minmax(log_a[m].id_a, log_a[m].id_b), std::minmax(log_b[m].id_a, log_b[m].id_b)) << m;
    worst_time = std::max(worst_time, std::abs(log_a[m].time - log_b[m].time));
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    worst_state = std::max(worst_state, d.separation(a.position[i], b.position[i]).norm());
    worst_state = std::max(worst_state, (a.velocity[i] - b.velocity[i]).norm());
    worst_state = std::max(worst_state, std::abs(a.angular_velocity[i].z() - b.angular_velocity[i].z()));
    ASSERT_EQ(b.position[i].z(), 0.0);
    ASSERT_EQ(b.velocity[i].z(), 0.0);
  }
  std::printf("2D disks, gravity, walls: %zu events, worst time diff %.2e, state diff %.2e\n",
              log_a.size(), worst_time, worst_state);
  EXPECT_LT(worst_time, 1e-10);
  EXPECT_LT(worst_state, 1e-9);
}

// Enskog: Gamma = 4 n sigma^2 sqrt(pi kT / m) g(sigma), g = (1 - eta/2) / (1 - eta)^3
// (Carnahan–Starling contact value; reference README). eta = 0.2618 gives n = 0.5.
TEST(EventDrivenCollider, CollisionFrequencyMatchesEnskog) {
  gp::ParticleStore s;
  gp::Domain d;
  const double eta = 0.2618;
  gp::testing::fcc_gas(s, d, 7, eta, 1.0, 5);  // N = 1372
  const double n_density = static_cast<double>(s.size()) / d.length().prod();
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{1.0, 0.0}});
  collider.initialize(s, d);
  collider.advance_to(s, d, 10.0);  // melt the lattice (~75 collisions per particle)
  const double t_measure = 40.0;
  const auto stats = collider.advance_to(s, d, 10.0 + t_measure);
  double twice_kinetic = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) twice_kinetic += s.mass[i] * s.velocity[i].squaredNorm();
  const double kT = twice_kinetic / (3.0 * (static_cast<double>(s.size()) - 1.0));
  const double pi = std::acos(-1.0);
  const double g_contact = (1.0 - eta / 2.0) / std::pow(1.0 - eta, 3);
  const double enskog = 4.0 * n_density * std::sqrt(pi * kT) * g_contact;
  const double measured = 2.0 * static_cast<double>(stats.collisions) /
                          (static_cast<double>(s.size()) * t_measure);
  std::printf("Enskog: n = %.4f, kT = %.4f, Gamma measured %.4f vs theory %.4f (%.2f%%), "
              "%ld collisions\n", n_density, kT, measured, enskog, 100.0 * (measured / enskog - 1.0),
              stats.collisions);
  EXPECT_NEAR(n_density, 0.5, 1e-3);
  EXPECT_NEAR(measured / enskog, 1.0, 0.02);
}

}  // namespace
