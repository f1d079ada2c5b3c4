// Unit tests of the pieces the DemSystem adds around the kernels: the truncated Gaussian
// diameters, the fills (RSA, lattice, shadowed hopper sites), bin statistics, the history
// table's checkpoint round trip and the velocity-Verlet force cache used for exact restarts.
#include "particles/dem/BinStatistics.hpp"
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Filling.hpp"
#include "particles/dem/Integrators.hpp"
#include "particles/dem/SizeDistribution.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

TEST(TruncatedGaussianDiameter, StaysWithinTwoSigmaWithTheTruncatedMoments) {
  // 002 §3.4: D = 115.5 ± 4.75 µm cut at 2σ gives bounds 106 and 125 µm.
  dem::TruncatedGaussianDiameter sizes(115.5e-6, 4.75e-6);
  std::mt19937_64 rng(1);
  double sum = 0, sum2 = 0, lo = 1, hi = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double d = sizes(rng);
    sum += d;
    sum2 += d * d;
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  EXPECT_GE(lo, 106e-6);
  EXPECT_LE(hi, 125e-6);
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 115.5e-6, 0.05e-6);
  // Truncation at ±2σ leaves a standard deviation of 0.8796 σ.
  EXPECT_NEAR(sd / 4.75e-6, 0.8796, 0.01);
}

TEST(Filling, RandomSequentialAdditionPlacesWithoutOverlap) {
  dem::FillRequest request;
  request.lo = Vec3(0.5, 0.5, 0.5);
  request.hi = Vec3(9.5, 9.5, 9.5);
  request.diameters.assign(300, 1.0);
  std::mt19937_64 rng(3);
  const auto x = dem::random_sequential_addition(request, {}, rng);
  ASSERT_EQ(x.size(), 300u);
  double closest = 1e9;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j) closest = std::min(closest, (x[i] - x[j]).norm());
  EXPECT_GE(closest, 1.0);
}

TEST(Filling, LatticeSkipsSitesUnderAHopperWallAndTouchingIt) {
  // A 2D funnel wall from (0, 2) down to (2, 0): sites below it are outside the hopper.
  dem::FillObstacles obstacles;
  obstacles.finite.push_back(dem::FiniteWall::segment(Vec3(0, 2, 0), Vec3(2, 0, 0)));
  obstacles.finite_clearance.push_back(0.0);
  dem::FillRequest request;
  request.dimension = 2;
  request.lo = Vec3(0.1, 0.1, 0);
  request.hi = Vec3(3.9, 3.9, 0);
  request.diameters.assign(1000, 0.2);
  std::mt19937_64 rng(5);
  const auto x = dem::lattice_fill(request, obstacles, rng);
  ASSERT_FALSE(x.empty());
  for (const Vec3& p : x) {
    EXPECT_GE(p.x() + p.y(), 2.0 + 0.1 * std::sqrt(2.0) - 1e-3) << "site under or on the wall";
  }
}

TEST(BinStatistics, VolumeFractionMeansAndFluctuations) {
  dem::BinStatistics::Layout layout;
  layout.lo = {0, 0};
  layout.hi = {2, 1};
  layout.count = {2, 1};
  layout.depth = 1.0;
  dem::BinStatistics bins(layout);
  gw::ParticleStore store;
  store.add(0, Vec3(0.5, 0.5, 0.5), Vec3::Zero(), Vec3::Zero(), 0.1, 1, 1);
  store.add(1, Vec3(1.5, 0.5, 0.5), Vec3::Zero(), Vec3::Zero(), 0.2, 1, 1);
  std::vector<std::uint8_t> use(2, 1);
  // Two samples: particle 0 moves at u = 1 then 3 (mean 2, u' = 1).
  bins.add_sample(store, 3, {Vec3(1, -1, 0), Vec3(0, -2, 0)}, use);
  bins.add_sample(store, 3, {Vec3(3, -1, 0), Vec3(0, -2, 0)}, use);
  EXPECT_DOUBLE_EQ(bins.beta(0), dem::particle_volume(3, 0.1));
  EXPECT_DOUBLE_EQ(bins.beta(1), dem::particle_volume(3, 0.2));
  EXPECT_DOUBLE_EQ(bins.mean_u(0), 2.0);
  EXPECT_DOUBLE_EQ(bins.rms_u(0), 1.0);
  EXPECT_DOUBLE_EQ(bins.mean_v(1), -2.0);
  EXPECT_DOUBLE_EQ(bins.rms_v(1), 0.0);
  dem::BinStatistics copy(layout);
  copy.restore(bins.samples(), bins.raw());
  EXPECT_EQ(copy.csv(), bins.csv());
}

TEST(ContactHistory, LiveEntriesSurviveACheckpointRoundTrip) {
  dem::ContactHistory history;
  history.begin_step();
  history.prepare();
  for (std::int64_t a = 0; a < 40; ++a) {
    auto* e = history.touch(a, a + 100);
    e->displacement = Vec3(a, 2 * a, 3 * a);
    e->is_new = false;
  }
  std::vector<dem::ContactHistoryEntry> saved;
  history.live_entries(saved);
  ASSERT_EQ(saved.size(), 40u);
  dem::ContactHistory restored;
  restored.restore(history.step(), saved);
  for (std::int64_t a = 0; a < 40; ++a) {
    const auto* e = restored.find(a + 100, a);
    ASSERT_NE(e, nullptr);
    EXPECT_EQ(e->displacement, Vec3(a, 2 * a, 3 * a));
    EXPECT_FALSE(e->is_new);
  }
  EXPECT_EQ(restored.find(1, 2), nullptr);
}

TEST(VelocityVerlet, RestoredForcesContinueBitForBit) {
  // Two overlapping spheres with a history law: stepping on, or stopping, saving the state,
  // history and the integrator's forces and continuing in fresh objects, gives the same bits.
  // (Soft: the contact lasts ~200 steps, so both halves are in contact.)
  gw::Domain domain;
  domain.lo = Vec3::Constant(-5);
  domain.hi = Vec3::Constant(5);
  auto model = dem::make_contact_model("linear_spring_dashpot", {{"stiffness", 100.0}, {"restitution", 0.8}},
                                       "coulomb_spring",
                                       {{"stiffness", 30.0}, {"friction", 0.3}, {"damping_factor", 0.1}});
  auto make_store = [] {
    gw::ParticleStore s;
    s.add(0, Vec3(-0.49, 0, 0), Vec3(0.3, 0.1, 0), Vec3::Zero(), 0.5, 1, 0.1);
    s.add(1, Vec3(0.49, 0.05, 0), Vec3(-0.3, 0, 0.05), Vec3::Zero(), 0.5, 1, 0.1);
    return s;
  };
  const double dt = 1e-3;
  gw::ParticleStore a = make_store();
  dem::ContactForceField field_a(model, domain);
  dem::VelocityVerlet verlet_a;
  for (int k = 0; k < 40; ++k) verlet_a.step(a, field_a, dt);
  gw::ParticleStore b = a;
  std::vector<dem::ContactHistoryEntry> entries;
  field_a.history().live_entries(entries);
  dem::ContactForceField field_b(model, domain);
  field_b.history().restore(field_a.history().step(), entries);
  dem::VelocityVerlet verlet_b;
  verlet_b.restore_forces(verlet_a.forces(), verlet_a.torques());
  for (int k = 0; k < 40; ++k) {
    verlet_a.step(a, field_a, dt);
    verlet_b.step(b, field_b, dt);
  }
  ASSERT_EQ(field_a.contact_count(), 1u) << "still in contact";
  EXPECT_EQ(a.position, b.position);
  EXPECT_EQ(a.velocity, b.velocity);
  EXPECT_EQ(a.angular_velocity, b.angular_velocity);
}
