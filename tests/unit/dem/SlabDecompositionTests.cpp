// The domain-decomposed DEM against the serial one (run on 1 and on 2 or 3 ranks; on 1 rank
// the decomposition has a single slab and the comparison is trivial). Every rank also steps the
// whole system serially, then compares what the ranks own, gathered by id, with it.
#include "core/Mpi.hpp"
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"
#include "particles/dem/SlabDecomposition.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <type_traits>
#include <string>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
namespace mpi = grainwave::mpi;
using gw::Vec3;

namespace {

/// A dense polydisperse gas of frictional spheres in a box periodic in x (the cut axis) and z,
/// with walls in y and gravity towards the floor: contacts between ranks, across the periodic
/// face, with walls, all with tangential history.
struct Gas {
  gw::Domain domain;
  dem::ContactModel model;
  dem::ContactForceSettings settings;
  gw::ParticleStore store;
  double dt = 0;

  explicit Gas(const std::string& tangential_law) {
    domain.hi = Vec3(6.0, 6.0, 3.0);
    domain.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kWall};
    model = dem::make_contact_model("linear_spring_dashpot", {{"stiffness", 1e2}, {"restitution", 0.7}},
                                    tangential_law,
                                    tangential_law == "static_friction"
                                        ? dem::LawParameters{{"friction", 0.4}}
                                        : dem::LawParameters{{"stiffness", 2.0 / 7.0 * 1e2}, {"friction", 0.4}});
    settings.gravity = Vec3(0.0, -2.0, 0.0);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // Lattice sites 0.5 apart with radii 0.2-0.25: touching neighbours from the start.
    long id = 0;
    double largest = 0;
    for (int k = 0; k < 6; ++k)
      for (int j = 0; j < 11; ++j)
        for (int i = 0; i < 12; ++i) {
          const double r = 0.2 + 0.05 * u(rng);
          largest = std::max(largest, r);
          const Vec3 x(0.25 + 0.5 * i, 0.3 + 0.5 * j, 0.25 + 0.5 * k);
          store.add(id++, x, 3.0 * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5),
                    Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5), r, r * r * r,
                    0.4 * r * r * r * r * r);
        }
    settings.cell_width = 2 * largest;
    settings.grid_particles = store.size();
    dt = dem::stable_time_step(store, *model.normal, 50);
  }
};

/// (id, x, v, omega) of the particles every rank owns, sorted by id.
std::vector<std::array<double, 10>> gather_state(const gw::ParticleStore& s) {
  std::vector<double> mine;
  for (std::size_t i = 0; i < s.size(); ++i) {
    mine.push_back(static_cast<double>(s.id[i]));
    for (const Vec3* v : {&s.position[i], &s.velocity[i], &s.angular_velocity[i]})
      mine.insert(mine.end(), {v->x(), v->y(), v->z()});
  }
  const auto all = mpi::all_gather(mine);
  std::vector<std::array<double, 10>> rows(all.size() / 10);
  for (std::size_t k = 0; k < rows.size(); ++k) std::copy_n(&all[10 * k], 10, rows[k].begin());
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
  return rows;
}

/// With a Verlet list, DemSystem's protocol (prepare_listed_step) for one run: a rebuild
/// migrates the particles and exchanges the ghosts first, and between rebuilds the ghosts are
/// only refreshed before each evaluation.
struct ListedRun {
  dem::SlabDecomposition* slabs = nullptr;  ///< null: serial
  std::vector<Vec3> ahead;
  std::int64_t migrated = 0;
  long builds = 0;

  template <class Integrator>
  void prepare(gw::ParticleStore& store, dem::ContactForceField& field, Integrator& integrator,
               double dt, const dem::BeforeEvaluation& refresh) {
    dem::VelocityVerlet* verlet = nullptr;
    if constexpr (std::is_same_v<Integrator, dem::VelocityVerlet>) verlet = &integrator;
    auto rebuild = [&] {
      if (slabs) {
        migrated += static_cast<std::int64_t>(slabs->migrate(
            store, verlet && verlet->has_forces() ? &verlet->stored_forces() : nullptr,
            verlet && verlet->has_forces() ? &verlet->stored_torques() : nullptr,
            field.model().tangential->needs_history() ? &field.history() : nullptr));
        slabs->exchange_ghosts(store);
      }
      field.build_list(store);
      dem::SlabDecomposition::strip_ghosts(store);
      ++builds;
    };
    ASSERT_EQ(dem::prepare_listed_step(store, field, verlet, dt, true, rebuild, refresh, ahead),
              dem::VerletList::kValid);
  }
};

void expect_same_as_serial(const std::string& tangential_law, bool runge_kutta, bool recut = false,
                           int axis = 0, double skin = 0.0) {
  Gas serial(tangential_law), split(tangential_law);
  for (Gas* gas : {&serial, &split}) {
    gas->settings.verlet_skin = skin;
    gas->settings.verlet_managed = skin > 0;
  }
  const int ranks = mpi::size();
  const auto cuts = dem::SlabDecomposition::balanced_cuts(split.domain, axis, split.store, ranks);
  dem::SlabDecomposition slabs(split.domain, axis, cuts, split.settings.cell_width + skin);
  slabs.keep_owned(split.store);
  dem::ContactForceField serial_field(serial.model, serial.domain, serial.settings);
  dem::ContactForceField split_field(split.model, split.domain, split.settings);

  // Contact forces on the starting configuration: bitwise the serial ones.
  if (skin > 0) serial_field.build_list(serial.store);
  serial_field.evaluate(serial.store, dem::HistoryStage::kPredict, serial.dt);
  slabs.exchange_ghosts(split.store);
  if (skin > 0) split_field.build_list(split.store);
  split_field.evaluate(split.store, dem::HistoryStage::kPredict, split.dt);
  long ghosts = 0, mismatched = 0;
  for (std::size_t i = 0; i < split.store.size(); ++i) {
    if (split.store.flags[i] & gw::kGhost) {
      ++ghosts;
      continue;
    }
    const auto k = static_cast<std::size_t>(split.store.id[i]);
    mismatched += split_field.force()[i] == serial_field.force()[k] &&
                          split_field.torque()[i] == serial_field.torque()[k]
                      ? 0
                      : 1;
  }
  EXPECT_EQ(mpi::sum(mismatched), 0) << "particles whose contact force differs from the serial one";
  if (ranks > 1) {
    EXPECT_GT(mpi::sum(ghosts), 0);
  }
  EXPECT_EQ(mpi::sum(static_cast<std::int64_t>(split_field.contact_count())),
            static_cast<std::int64_t>(serial_field.contact_count()));
  dem::SlabDecomposition::strip_ghosts(split.store);

  // Then 3000 steps: the same trajectories, bit for bit, with particles migrating.
  dem::VelocityVerlet serial_verlet, split_verlet;
  dem::RungeKutta2 serial_rk2, split_rk2;
  dem::BeforeEvaluation ghosts_of = [&](gw::ParticleStore& s) { slabs.exchange_ghosts(s); };
  if (skin > 0) ghosts_of = [&](gw::ParticleStore& s) { slabs.refresh_ghosts(s); };
  std::int64_t migrated = 0;
  ListedRun serial_list, split_list;
  split_list.slabs = &slabs;
  for (int step = 0; step < 3000; ++step) {
    if (skin > 0 && runge_kutta) {
      serial_list.prepare(serial.store, serial_field, serial_rk2, serial.dt, {});
      split_list.prepare(split.store, split_field, split_rk2, split.dt, ghosts_of);
    } else if (skin > 0) {
      serial_list.prepare(serial.store, serial_field, serial_verlet, serial.dt, {});
      split_list.prepare(split.store, split_field, split_verlet, split.dt, ghosts_of);
    }
    if (runge_kutta) {
      serial_rk2.step(serial.store, serial_field, serial.dt);
      split_rk2.step(split.store, split_field, split.dt, ghosts_of);
    } else {
      serial_verlet.step(serial.store, serial_field, serial.dt);
      split_verlet.step(split.store, split_field, split.dt, ghosts_of);
    }
    dem::SlabDecomposition::strip_ghosts(split.store);
    if (skin > 0) continue;  // the list's rebuilds migrate
    if (recut && axis != 0 && step % 500 == 499) {
      slabs.set_cuts(slabs.rebalanced_cuts(split.store));
    } else if (recut && step % 500 == 499) {
      // Move every inner cut by a third of a slab: a third of the particles change rank at once.
      auto moved = slabs.cuts();
      const double shift = (step / 500 % 2 == 0 ? 1.0 : -1.0) * split.domain.hi.x() / (3.0 * ranks);
      for (std::size_t r = 1; r + 1 < moved.size(); ++r) moved[r] += shift;
      slabs.set_cuts(moved);
    }
    migrated += static_cast<std::int64_t>(slabs.migrate(
        split.store, runge_kutta ? nullptr : &split_verlet.stored_forces(),
        runge_kutta ? nullptr : &split_verlet.stored_torques(),
        split.model.tangential->needs_history() ? &split_field.history() : nullptr));
    ASSERT_TRUE(std::is_sorted(split.store.id.begin(), split.store.id.end())) << "step " << step;
  }
  migrated = mpi::sum(migrated + split_list.migrated);
  if (skin > 0) {
    EXPECT_EQ(split_list.builds, serial_list.builds) << "the list is rebuilt at the serial run's steps";
    EXPECT_GT(serial_list.builds, 3);
    EXPECT_LT(serial_list.builds, 300) << "the list is kept for several steps";
  }
  if (ranks > 1) {
    EXPECT_GT(migrated, 10) << "the test needs particles crossing between slabs";
  }
  const auto rows = gather_state(split.store);
  ASSERT_EQ(rows.size(), serial.store.size());
  long differ = 0;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto& s = serial.store;
    const std::array<double, 10> expected{static_cast<double>(s.id[k]), s.position[k].x(),
                                          s.position[k].y(), s.position[k].z(), s.velocity[k].x(),
                                          s.velocity[k].y(), s.velocity[k].z(),
                                          s.angular_velocity[k].x(), s.angular_velocity[k].y(),
                                          s.angular_velocity[k].z()};
    differ += rows[k] == expected ? 0 : 1;
  }
  EXPECT_EQ(differ, 0) << "particles not bitwise where the serial run has them, after "
                       << migrated << " migrations";
  if (split.model.tangential->needs_history()) {
    // The springs were loaded: the history that travelled with the migrants mattered.
    std::vector<dem::ContactHistoryEntry> live;
    serial_field.history().live_entries(live);
    const auto loaded = std::count_if(live.begin(), live.end(), [](const auto& e) {
      return e.displacement.norm() > 0;
    });
    EXPECT_GT(loaded, 100);
  }
}

}  // namespace

TEST(SlabDecomposition, StaticFrictionBitwiseAsSerial) { expect_same_as_serial("static_friction", false); }

TEST(SlabDecomposition, HistorySpringsSurviveMigrationBitwise) {
  expect_same_as_serial("coulomb_spring", false);
}

TEST(SlabDecomposition, RungeKutta2WithHistoryBitwiseAsSerial) {
  expect_same_as_serial("coulomb_spring", true);
}

TEST(SlabDecomposition, NewCutsMoveParticlesWithTheirHistoryBitwise) {
  expect_same_as_serial("coulomb_spring", false, true);
}

TEST(SlabDecomposition, SettlingBedCutAlongGravityRebalancedBitwise) {
  expect_same_as_serial("coulomb_spring", false, true, 1);
}

TEST(SlabDecomposition, VerletListWithRefreshedGhostsBitwiseAsSerial) {
  expect_same_as_serial("static_friction", false, false, 0, 0.05);
}

TEST(SlabDecomposition, VerletListHistorySpringsMigrateAtRebuildsBitwise) {
  expect_same_as_serial("coulomb_spring", false, false, 0, 0.05);
}

TEST(SlabDecomposition, VerletListRungeKutta2BitwiseAsSerial) {
  expect_same_as_serial("coulomb_spring", true, false, 0, 0.05);
}

TEST(SlabDecomposition, OwnerFollowsTheCutsAndWrapsPeriodicAxes) {
  gw::Domain domain;
  domain.hi = Vec3(4.0, 1.0, 1.0);
  const int ranks = mpi::size();
  std::vector<double> cuts;
  for (int r = 0; r <= ranks; ++r) cuts.push_back(4.0 * r / ranks);
  dem::SlabDecomposition slabs(domain, 0, cuts, 0.1);
  EXPECT_EQ(slabs.owner(Vec3(0.0, 0.5, 0.5)), 0);
  EXPECT_EQ(slabs.owner(Vec3(3.999, 0.5, 0.5)), ranks - 1);
  EXPECT_EQ(slabs.owner(Vec3(4.0 + 1e-3, 0.5, 0.5)), 0);   // wrapped through the periodic face
  EXPECT_EQ(slabs.owner(Vec3(-1e-3, 0.5, 0.5)), ranks - 1);
}
