// The Verlet list must find exactly the contacts the cell search finds, at every step, while
// being rebuilt only now and then.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <tuple>
#include <vector>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {

/// A 5 x 5 x 5 box, periodic in x and z, with walls at the bottom and top in y.
gw::Domain gas_box() {
  gw::Domain domain;
  domain.hi = Vec3(5.0, 5.0, 5.0);
  domain.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kWall};
  return domain;
}

/// 300 spheres of radii 0.15-0.25 at random in gas_box(), with random velocities and, when
/// `spinning`, random angular velocities.
gw::ParticleStore granular_gas(unsigned seed, bool spinning) {
  gw::ParticleStore s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto centred = [&] {
    const double x = u(rng) - 0.5, y = u(rng) - 0.5;
    return Vec3(x, y, u(rng) - 0.5);
  };
  for (int k = 0; k < 300; ++k) {
    const double r = 0.15 + 0.1 * u(rng);
    const double x = 5 * u(rng), y = 0.3 + 4.4 * u(rng), z = 5 * u(rng);
    const Vec3 v = centred();
    const Vec3 w = spinning ? centred() : Vec3::Zero();
    s.add(k, Vec3(x, y, z), v, w, r, r * r * r, 0.4 * r * r * r * r * r);
  }
  return s;
}

/// Linear spring-dashpot with static friction, as the cell-search comparisons use.
dem::ContactModel frictional_model() {
  return dem::make_contact_model("linear_spring_dashpot", {{"stiffness", 1e4}, {"restitution", 0.8}},
                                 "static_friction", {{"friction", 0.3}});
}

/// Largest difference between the forces of two evaluations of the same state, relative to the
/// largest single contact force of `cells` (which sets the size of a rounding difference):
/// contact forces summed in another order round differently.
double worst_force_difference(const dem::ContactForceField& cells, const dem::ContactForceField& other,
                              std::size_t n) {
  double largest = 1.0;
  for (const dem::Contact& c : cells.contacts()) largest = std::max(largest, std::abs(c.normal_force));
  double worst = 0.0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, (cells.force()[i] - other.force()[i]).norm() / largest);
  return worst;
}

/// Under gravity with a Verlet list of skin 0.2; `flag` (fused or batched) set to `value`.
dem::ContactForceSettings listed_settings(bool dem::ContactForceSettings::*flag, bool value) {
  dem::ContactForceSettings s;
  s.gravity = Vec3(0.0, -1.0, 0.0);
  s.verlet_skin = 0.2;
  s.*flag = value;
  return s;
}

/// One contact model evaluated two ways, under gravity with a Verlet list: the fused pass (the
/// default) and the batched one that keeps the list of contacts.
struct FusedAndListed {
  dem::ContactForceField fused, listed;
  FusedAndListed(const dem::ContactModel& model, const gw::Domain& domain)
      : fused(model, domain, listed_settings(&dem::ContactForceSettings::fused, true)),
        listed(model, domain, listed_settings(&dem::ContactForceSettings::fused, false)) {}
};

/// One contact model on a Verlet list in a box periodic on every axis (pairs with and without
/// the minimum image), under gravity: listed pairs computed in lanes of the given width, and
/// contact by contact.
struct BatchedAndSingle {
  dem::ContactForceField batched, single;
  BatchedAndSingle(const dem::ContactModel& model, int lane_width)
      : batched(model, periodic_box(), with_lane_width(lane_width)),
        single(model, periodic_box(), listed_settings(&dem::ContactForceSettings::batched, false)) {}
  static dem::ContactForceSettings with_lane_width(int lane_width) {
    dem::ContactForceSettings s = listed_settings(&dem::ContactForceSettings::batched, true);
    s.lane_width = lane_width;
    return s;
  }
  static gw::Domain periodic_box() {
    gw::Domain domain;
    domain.hi = Vec3(5.0, 5.0, 5.0);
    return domain;
  }
};

/// The batched pass's lane widths this CPU runs (2 always; 4 with AVX2, 8 with AVX-512F).
std::vector<int> lane_widths() {
  std::vector<int> widths;
  for (const int width : {2, 4, 8})
    if (dem::lane_width_supported(width)) widths.push_back(width);
  return widths;
}

/// granular_gas(seed, spinning) at three times the speed, every tenth particle fixed.
gw::ParticleStore fast_gas_with_fixed(unsigned seed) {
  gw::ParticleStore s = granular_gas(seed, true);
  for (auto& v : s.velocity) v *= 3.0;
  for (std::size_t i = 0; i < s.size(); i += 10) s.flags[i] |= gw::kFixed;
  return s;
}

/// One model in gas_box() under gravity three ways: `driver` steps the gas, `cells` (the cell
/// search, every wall against every particle) keeps its list of contacts, and `listed` takes
/// its pairs from a Verlet list of skin 0.2, by the fused pass or (listed_fused false) keeping
/// its list of contacts.
struct CellsAndListed {
  dem::ContactForceField driver, cells, listed;
  CellsAndListed(const dem::ContactModel& model, bool listed_fused)
      : driver(model, gas_box(), with(true, 0.0)), cells(model, gas_box(), with(false, 0.0)),
        listed(model, gas_box(), with(listed_fused, 0.2)) {}
  static dem::ContactForceSettings with(bool fused, double skin) {
    dem::ContactForceSettings s;
    s.gravity = Vec3(0.0, -1.0, 0.0);
    s.fused = fused;
    s.verlet_skin = skin;
    return s;
  }
};

}  // namespace

TEST(VerletList, SameForcesAsCellSearchThroughoutAGranularGas) {
  const auto model = frictional_model();
  CellsAndListed fields(model, true);
  auto& [driver, cells, listed] = fields;

  gw::ParticleStore s = granular_gas(11, false);
  dem::VelocityVerlet verlet;
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  const int steps = 2000;
  double worst = 0.0;
  long contacts_seen = 0;
  for (int step = 0; step < steps; ++step) {
    verlet.step(s, driver, dt);
    cells.evaluate(s, dem::HistoryStage::kSingle, dt);
    listed.evaluate(s, dem::HistoryStage::kSingle, dt);
    ASSERT_EQ(cells.contacts().size(), listed.contact_count()) << "step " << step;
    contacts_seen += static_cast<long>(cells.contacts().size());
    worst = std::max(worst, worst_force_difference(cells, listed, s.size()));
  }
  std::printf("Verlet list: %ld builds in %d steps, %zu pairs listed, %ld contacts seen\n",
              listed.verlet_list().builds(), steps, listed.verlet_list().pair_count(),
              contacts_seen);
  EXPECT_LT(worst, 1e-12);  // only the summation order differs
  EXPECT_GT(contacts_seen, 1000);
  EXPECT_GT(listed.verlet_list().builds(), 1);
  EXPECT_LT(listed.verlet_list().builds(), steps / 5);
}

// With the Verlet list, walls test only the particles near them when the list was built
// (ContactForceField::wall_candidates_). A fast gas, every tenth particle fixed, in the box
// periodic in x and z, with a rectangle standing just inside the periodic face x = 0 (so
// particles that wrap across it land next to the wall) and a tilted ledge in the middle: at
// every step the listed field finds the same wall contacts, with the same forces, as the cell
// search, which tests every particle against every wall.
TEST(VerletList, WallCandidatesFindEveryWallContact) {
  const auto model = frictional_model();
  CellsAndListed fields(model, false);  // the listed field's contacts are read below
  auto& [driver, cells, listed] = fields;
  const auto by_the_face = dem::FiniteWall::rectangle(Vec3(0.05, 2.5, 2.5), Vec3::UnitY(), Vec3::UnitZ(), 4.0, 4.0);
  const auto ledge = dem::FiniteWall::rectangle(Vec3(2.5, 1.25, 2.5), Vec3(3.0, 0.5, 0.0), Vec3::UnitZ(), 3.0, 5.0);
  for (auto* field : {&driver, &cells, &listed}) {
    field->finite_walls().push_back(by_the_face);
    field->finite_walls().push_back(ledge);
  }

  gw::ParticleStore s = fast_gas_with_fixed(5);
  dem::VelocityVerlet verlet;
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  const int steps = 2000;
  double worst = 0.0;
  long wall_contacts = 0, face_wall_contacts = 0;
  const std::size_t face_wall = listed.plane_walls().size();  // the rectangle's wall index
  for (int step = 0; step < steps; ++step) {
    verlet.step(s, driver, dt);
    cells.evaluate(s, dem::HistoryStage::kSingle, dt);
    listed.evaluate(s, dem::HistoryStage::kSingle, dt);
    long walls_here = 0;
    for (const dem::Contact& c : cells.contacts()) {
      walls_here += c.is_wall ? 1 : 0;
      face_wall_contacts += c.is_wall && c.partner == face_wall ? 1 : 0;
    }
    const auto listed_walls = std::count_if(listed.contacts().begin(), listed.contacts().end(),
                                            [](const dem::Contact& c) { return c.is_wall; });
    ASSERT_EQ(walls_here, listed_walls) << "step " << step;
    wall_contacts += walls_here;
    worst = std::max(worst, worst_force_difference(cells, listed, s.size()));
  }
  std::printf("wall candidates: %ld wall contacts (%ld with the wall by the periodic face), %ld list builds\n",
              wall_contacts, face_wall_contacts, listed.verlet_list().builds());
  EXPECT_LT(worst, 1e-12);  // only the summation order of the pair forces differs
  EXPECT_GT(face_wall_contacts, 100);
  EXPECT_GT(wall_contacts, 1000);
  EXPECT_GT(listed.verlet_list().builds(), 1);
}

// Most listed pairs skip the minimum image (VerletList flags at the build the pairs that may
// need it). Through a fast granular gas in a box periodic on all three axes, both with the list
// managing itself and planned before each step, every touching pair's separation must be the
// minimum image to the bit, and pairs must touch across the periodic faces (so both kinds of
// pair were met).
TEST(VerletList, ListedSeparationsAreMinimumImagesBitwise) {
  for (const bool managed : {false, true}) {
    gw::Domain domain;
    domain.hi = Vec3(5.0, 5.0, 5.0);  // periodic on every axis
    const auto model = frictional_model();
    dem::ContactForceSettings settings;
    settings.verlet_skin = 0.2;
    settings.verlet_managed = managed;
    dem::ContactForceField field(model, domain, settings);
    gw::ParticleStore s = granular_gas(7, true);
    for (auto& v : s.velocity) v *= 4.0;  // many wraps within a list's life
    dem::VelocityVerlet verlet;
    const double dt = dem::stable_time_step(s, *model.normal, 50);
    std::vector<Vec3> ahead;
    long across = 0, pairs = 0;
    for (int step = 0; step < 1500; ++step) {
      if (managed) {  // the caller plans the step (as DemSystem does)
        ASSERT_EQ(dem::prepare_listed_step(s, field, &verlet, dt, false, [&] { field.build_list(s); }, {}, ahead),
                  dem::VerletList::kValid);
      }
      verlet.step(s, field, dt);
      field.verlet_list().for_each_touching_pair(
          s, [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2, std::uint32_t) {
            const Vec3 image = domain.separation(s.position[i], s.position[j]);
            ASSERT_EQ(d, image) << "managed " << managed << " step " << step << " pair " << i << "-" << j;
            ASSERT_EQ(distance2, image.squaredNorm());
            across += (s.position[j] - s.position[i]).cwiseAbs().maxCoeff() > 2.5 ? 1 : 0;
            ++pairs;
          });
    }
    std::printf("managed %d: %ld touching pairs, %ld across a periodic face, %ld builds\n", managed ? 1 : 0,
                pairs, across, field.verlet_list().builds());
    EXPECT_GT(pairs, 1000);
    EXPECT_GT(across, 50);
    EXPECT_GT(field.verlet_list().builds(), 5);
  }
}

// The listed pairs of the linear spring-dashpot with static friction are computed 2, 4 or 8 at
// a time in SIMD lanes (ContactForceSettings::batched, lane_width; each width this CPU runs).
// Against the contact-by-contact fused pass: bitwise the same forces, torques, count and deepest contact, through a fast gas in a
// box periodic on all axes (pairs with and without the minimum image) with some fixed
// particles, for friction with and without regularisation and without friction (F_t = 0
// exactly), and on one configuration whose last slots are ghosts (their pairs skipped).
TEST(ContactForceField, BatchedLanesEqualTheContactByContactPassBitwise) {
  auto compare = [](const dem::ContactForceField& batched, const dem::ContactForceField& single, std::size_t n,
                    const std::string& where) {
    ASSERT_EQ(batched.contact_count(), single.contact_count()) << where;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(batched.force()[i], single.force()[i]) << where << " particle " << i;
      ASSERT_EQ(batched.torque()[i], single.torque()[i]) << where << " particle " << i;
    }
    ASSERT_EQ(batched.deepest_contact().overlap_over_radius, single.deepest_contact().overlap_over_radius) << where;
    ASSERT_EQ(batched.deepest_contact().i, single.deepest_contact().i) << where;
    ASSERT_EQ(batched.deepest_contact().partner, single.deepest_contact().partner) << where;
  };
  struct Friction {
    double friction, regularization_speed;
  };
  for (const int width : lane_widths())
  for (const Friction friction : {Friction{0.3, 0.0}, Friction{0.3, 0.05}, Friction{0.0, 0.0}}) {
    const auto model = dem::make_contact_model(
        "linear_spring_dashpot", {{"stiffness", 1e4}, {"restitution", 0.8}}, "static_friction",
        {{"friction", friction.friction}, {"regularization_speed", friction.regularization_speed}});
    BatchedAndSingle fields(model, width);
    ASSERT_EQ(fields.batched.lane_width(), width);
    auto& [batched, single] = fields;
    gw::ParticleStore s = fast_gas_with_fixed(13);
    dem::VelocityVerlet verlet;
    const double dt = dem::stable_time_step(s, *model.normal, 50);
    long contacts = 0;
    for (int step = 0; step < 1000; ++step) {
      verlet.step(s, batched, dt);
      // Both at the state after the step (the step evaluated at its predicted velocities).
      batched.evaluate(s, dem::HistoryStage::kSingle, dt);
      single.evaluate(s, dem::HistoryStage::kSingle, dt);
      compare(batched, single, s.size(), "lanes " + std::to_string(width) + " friction " +
                                              std::to_string(friction.friction) + " eps " +
                                              std::to_string(friction.regularization_speed) + " step " +
                                              std::to_string(step));
      contacts += static_cast<long>(batched.contact_count());
    }
    EXPECT_GT(contacts, 5000);
    EXPECT_GT(batched.verlet_list().builds(), 5);
  }
  {  // A width the pass does not have is refused, not silently replaced.
    dem::ContactForceSettings odd = listed_settings(&dem::ContactForceSettings::batched, true);
    odd.lane_width = 3;
    EXPECT_THROW((void)dem::ContactForceField(frictional_model(), gas_box(), odd).lane_width(), std::invalid_argument);
  }
  // Ghosts: the last 60 slots are another rank's copies; the lists are caller-managed.
  const auto model = frictional_model();
  dem::ContactForceSettings settings;
  settings.verlet_skin = 0.2;
  settings.verlet_managed = true;
  dem::ContactForceField batched(model, gas_box(), settings);
  settings.batched = false;
  dem::ContactForceField single(model, gas_box(), settings);
  gw::ParticleStore s = granular_gas(17, true);
  for (std::size_t i = s.size() - 60; i < s.size(); ++i) s.flags[i] |= gw::kGhost;
  ASSERT_EQ(s.owned_size(), s.size() - 60);
  for (auto* field : {&batched, &single}) {
    field->build_list(s);
    field->evaluate(s, dem::HistoryStage::kSingle, 1e-4);
  }
  EXPECT_GT(batched.contact_count(), 20u);
  compare(batched, single, s.owned_size(), "with ghosts");

  // Two spheres at rest pressed together, unregularised friction: no slip (|v_t| = 0) gives
  // F_t = 0, not 0/0.
  settings.batched = true;
  dem::ContactForceField batched_rest(model, gas_box(), settings);
  gw::ParticleStore rest;
  rest.add(0, Vec3(2.0, 2.0, 2.0), Vec3::Zero(), Vec3::Zero(), 0.2, 1.0, 0.016);
  rest.add(1, Vec3(2.3, 2.0, 2.0), Vec3::Zero(), Vec3::Zero(), 0.2, 1.0, 0.016);
  batched_rest.build_list(rest);
  batched_rest.evaluate(rest, dem::HistoryStage::kSingle, 1e-4);
  ASSERT_EQ(batched_rest.contact_count(), 1u);
  EXPECT_NEAR(batched_rest.force()[0].x(), -1e4 * 0.1, 1e-9);  // k δ, pushing 0 away from 1
  EXPECT_EQ(batched_rest.force()[0].y(), 0.0);
  EXPECT_EQ(batched_rest.force()[0].z(), 0.0);
  EXPECT_EQ(batched_rest.torque()[0], Vec3::Zero());
}

// The fused pass (forces computed where a contact is found, no list) against the list of
// contacts and the batched laws: bitwise the same forces, torques, count and deepest contact,
// for both normal laws, with walls and a finite wall segment, through a granular gas.
TEST(ContactForceField, FusedPassEqualsTheListOfContactsBitwise) {
  for (const char* normal : {"linear_spring_dashpot", "hertz"}) {
    const gw::Domain domain = gas_box();
    const dem::LawParameters normal_parameters =
        std::string(normal) == "hertz"
            ? dem::LawParameters{{"youngs_modulus", 1e5}, {"restitution", 0.8}, {"reference_velocity", 1.0}}
            : dem::LawParameters{{"stiffness", 1e4}, {"restitution", 0.8}};
    auto model = dem::make_contact_model(normal, normal_parameters, "static_friction",
                                         {{"friction", 0.3}, {"regularization_speed", 1e-3}});
    FusedAndListed fields(model, domain);
    auto& [fused, listed] = fields;
    // A tilted ledge across the box, 3 by 5.
    const auto ledge = dem::FiniteWall::rectangle(Vec3(2.5, 1.25, 2.5), Vec3(3.0, 0.5, 0.0), Vec3::UnitZ(), 3.0, 5.0);
    for (auto* field : {&fused, &listed}) field->finite_walls().push_back(ledge);

    gw::ParticleStore s = granular_gas(5, true);
    dem::VelocityVerlet verlet;
    const double dt = dem::stable_time_step(s, *model.normal, 50);
    long contacts = 0, walls = 0;
    for (int step = 0; step < 1500; ++step) {
      verlet.step(s, fused, dt);
      listed.evaluate(s, dem::HistoryStage::kSingle, dt);
      fused.evaluate(s, dem::HistoryStage::kSingle, dt);
      ASSERT_TRUE(fused.contacts().empty());
      ASSERT_EQ(fused.contact_count(), listed.contacts().size()) << normal << " step " << step;
      ASSERT_EQ(fused.contact_count(), listed.contact_count());
      for (std::size_t i = 0; i < s.size(); ++i) {
        ASSERT_EQ(fused.force()[i], listed.force()[i]) << normal << " step " << step << " particle " << i;
        ASSERT_EQ(fused.torque()[i], listed.torque()[i]) << normal << " step " << step << " particle " << i;
      }
      const auto& a = fused.deepest_contact();
      const auto& b = listed.deepest_contact();
      ASSERT_EQ(a.overlap_over_radius, b.overlap_over_radius);
      ASSERT_EQ(a.i, b.i);
      ASSERT_EQ(a.partner, b.partner);
      contacts += static_cast<long>(fused.contact_count());
      for (const dem::Contact& c : listed.contacts()) walls += c.is_wall ? 1 : 0;
    }
    EXPECT_GT(contacts, 1000) << normal;
    EXPECT_GT(walls, 10) << normal;  // the walls' contacts were compared too
  }
}

// The list as DemSystem manages it (settings.verlet_managed): checked once before each step
// against the positions the step will evaluate at (VelocityVerlet::displacement_ahead), and
// rebuilt only then. At every evaluation it must find what the cell search finds there.
TEST(VerletList, PlannedBeforeTheStepFindsEveryContactOfTheStep) {
  const gw::Domain domain = gas_box();
  const auto model = frictional_model();
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0.0, -1.0, 0.0);
  settings.fused = false;
  dem::ContactForceField cells(model, domain, settings);
  settings.fused = true;
  settings.verlet_skin = 0.2;
  settings.verlet_managed = true;
  dem::ContactForceField listed(model, domain, settings);

  gw::ParticleStore s = granular_gas(11, false);
  dem::VelocityVerlet verlet;
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  // The cell search at the very state each evaluation of the list sees.
  auto alongside = [&](gw::ParticleStore& state) { cells.evaluate(state, dem::HistoryStage::kSingle, dt); };
  std::vector<Vec3> ahead;
  const int steps = 2000;
  double worst = 0.0;
  long contacts_seen = 0;
  listed.build_list(s);
  verlet.prime(s, listed, dt);
  for (int step = 0; step < steps; ++step) {
    verlet.displacement_ahead(s, dt, ahead);
    if (listed.list_stale_ahead(s, ahead) != dem::VerletList::kValid) listed.build_list(s);
    verlet.step(s, listed, dt, alongside);
    ASSERT_EQ(cells.contacts().size(), listed.contact_count()) << "step " << step;
    contacts_seen += static_cast<long>(cells.contacts().size());
    worst = std::max(worst, worst_force_difference(cells, listed, s.size()));
  }
  EXPECT_LT(worst, 1e-12);  // only the summation order differs
  EXPECT_GT(contacts_seen, 1000);
  EXPECT_GT(listed.verlet_list().builds(), 2);
  EXPECT_LT(listed.verlet_list().builds(), steps / 5);
}

TEST(VerletList, StaleAheadNamesTheParticleThatWouldOutrunHalfTheSkin) {
  gw::Domain domain;
  domain.hi = Vec3(4.0, 4.0, 4.0);
  gw::ParticleStore s;
  for (int k = 0; k < 8; ++k)
    s.add(k, Vec3(0.5 + (k % 2) * 2.0, 0.5 + (k / 2 % 2) * 2.0, 0.5 + (k / 4) * 2.0), Vec3::Zero(),
          Vec3::Zero(), 0.4, 1.0, 0.1);
  dem::VerletList list;
  std::vector<Vec3> ahead(s.size(), Vec3::Zero());
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), dem::VerletList::kOtherSlots);  // never built
  list.build(s, domain, 1.0, 0.2);
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), dem::VerletList::kValid);
  ahead[5] = Vec3(0.0, 0.099, 0.0);  // within skin/2
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), dem::VerletList::kValid);
  ahead[5] = Vec3(0.0, 0.101, 0.0);  // past it during the step
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), 5);
  ahead[5].setZero();
  s.position[3] += Vec3(0.0, 0.0, -0.11);  // past it already
  s.position[2] += Vec3(0.0, 0.0, -0.6);   // through the periodic face, wrapped: 0.6 away
  domain.wrap(s.position[2]);
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), 2);
  s.position[2] = list.reference()[2] + Vec3(0.0, 0.0, 0.05);
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), 3);
  s.position[3] = list.reference()[3];
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), dem::VerletList::kValid);
  s.remove(7);  // other particles in the slots
  EXPECT_EQ(list.stale_ahead(s, s.size(), ahead), dem::VerletList::kOtherSlots);

  // Many particles: the first one too far is named, wherever it sits among them (the check runs
  // over chunks of slots).
  gw::Domain box;
  box.hi = Vec3(24.0, 24.0, 6.0);
  gw::ParticleStore lattice;
  for (int k = 0; k < 24 * 24 * 3; ++k)
    lattice.add(k, Vec3(0.5 + k % 24, 0.5 + k / 24 % 24, 0.5 + 2.0 * (k / 576)), Vec3::Zero(), Vec3::Zero(), 0.4,
                1.0, 0.1);
  dem::VerletList many;
  many.build(lattice, box, 1.0, 0.2);
  std::vector<Vec3> displaced(lattice.size(), Vec3::Zero());
  EXPECT_EQ(many.stale_ahead(lattice, lattice.size(), displaced), dem::VerletList::kValid);
  displaced[1300] = Vec3(-0.15, 0.0, 0.0);
  EXPECT_EQ(many.stale_ahead(lattice, lattice.size(), displaced), 1300);
  lattice.position[1700] += Vec3(0.0, 0.0, 0.2);
  lattice.position[700] += Vec3(0.0, 0.0, -0.2);
  EXPECT_EQ(many.stale_ahead(lattice, lattice.size(), displaced), 700);
  EXPECT_EQ(many.stale_ahead(lattice, 1000, displaced), dem::VerletList::kOtherSlots);  // not the build's owned count
}

// The same with the history laws: the fused pass looks each contact's entry up and advances it
// where the contact is found, the batched one does each of these for all contacts in turn.
// Forces, torques and the stored displacements must agree bitwise, with velocity Verlet (one
// evaluation per step) and RK2 (predictor and corrector), through a gas under gravity with walls,
// from an empty history table (which the fused pass grows between contacts).
TEST(ContactForceField, FusedHistoryPassEqualsTheListOfContactsBitwise) {
  struct Law {
    const char* tangential;
    dem::LawParameters parameters;
  };
  const Law laws[] = {{"coulomb_spring", {{"stiffness", 2.0 / 7.0 * 1e4}, {"friction", 0.3}}},
                      {"mindlin", {{"youngs_modulus", 1e5}, {"poisson_ratio", 0.25}, {"friction", 0.3}}}};
  for (const Law& law : laws)
    for (const bool runge_kutta : {false, true}) {
      SCOPED_TRACE(std::string(law.tangential) + (runge_kutta ? " RK2" : " velocity Verlet"));
      const gw::Domain domain = gas_box();
      const std::string tangential = law.tangential;
      auto model = dem::make_contact_model(
          tangential == "mindlin" ? "hertz" : "linear_spring_dashpot",
          tangential == "mindlin"
              ? dem::LawParameters{{"youngs_modulus", 1e5}, {"poisson_ratio", 0.25}, {"restitution", 0.8},
                                   {"reference_velocity", 1.0}}
              : dem::LawParameters{{"stiffness", 1e4}, {"restitution", 0.8}},
          tangential, law.parameters);
      FusedAndListed fields(model, domain);
      auto& [fused, listed] = fields;
      gw::ParticleStore s = granular_gas(7, true);
      const double dt = dem::stable_time_step(s, *model.normal, 50);
      // The batched field evaluated at the very state, and stage, of each evaluation of the fused.
      int evaluation = 0;
      auto alongside = [&](gw::ParticleStore& state) {
        const dem::HistoryStage stage = !runge_kutta ? dem::HistoryStage::kSingle
                                        : evaluation++ % 2 == 0 ? dem::HistoryStage::kPredict
                                                                : dem::HistoryStage::kCorrect;
        listed.evaluate(state, stage, dt);
      };
      dem::VelocityVerlet verlet;
      dem::RungeKutta2 rk2;
      if (!runge_kutta) {
        listed.evaluate(s, dem::HistoryStage::kPredict, dt);
        verlet.prime(s, fused, dt);
      }
      long contacts = 0;
      for (int step = 0; step < 1500; ++step) {
        if (runge_kutta) rk2.step(s, fused, dt, alongside);
        else verlet.step(s, fused, dt, alongside);
        ASSERT_TRUE(fused.contacts().empty());
        ASSERT_EQ(fused.contact_count(), listed.contacts().size()) << "step " << step;
        for (std::size_t i = 0; i < s.size(); ++i) {
          ASSERT_EQ(fused.force()[i], listed.force()[i]) << "step " << step << " particle " << i;
          ASSERT_EQ(fused.torque()[i], listed.torque()[i]) << "step " << step << " particle " << i;
        }
        contacts += static_cast<long>(fused.contact_count());
      }
      std::vector<dem::ContactHistoryEntry> a, b;
      fused.history().live_entries(a);
      listed.history().live_entries(b);
      auto by_pair = [](const auto& x, const auto& y) {
        return std::tie(x.first, x.second) < std::tie(y.first, y.second);
      };
      std::sort(a.begin(), a.end(), by_pair);
      std::sort(b.begin(), b.end(), by_pair);
      ASSERT_EQ(a.size(), b.size());
      long loaded = 0;
      for (std::size_t k = 0; k < a.size(); ++k) {
        ASSERT_EQ(a[k].first, b[k].first);
        ASSERT_EQ(a[k].second, b[k].second);
        ASSERT_EQ(a[k].displacement, b[k].displacement) << "entry " << k;
        ASSERT_EQ(a[k].stage_velocity, b[k].stage_velocity) << "entry " << k;
        loaded += a[k].displacement.norm() > 0 ? 1 : 0;
      }
      EXPECT_GT(contacts, 1000);
      EXPECT_GT(loaded, 5);  // live springs at the end: the history mattered
    }
}

// The Coulomb spring with history on a Verlet list is also computed in lanes of each width this
// CPU runs (velocity Verlet's single stage). Two identical simulations, one batched and one
// contact by contact, each driving its own particles: after every step bitwise the same
// positions, velocities, forces and torques, and the same live history entries (pair, last
// touch, stored displacement, stage velocity). Through a fast spinning gas in a box periodic
// on all axes with fixed particles, with and without tangential damping, and with friction low
// enough that contacts slip (the rare lane branch) and high enough that they stick.
TEST(ContactForceField, BatchedCoulombSpringEqualsTheContactByContactPassBitwise) {
  struct Tangential {
    double friction, damping_factor;
  };
  for (const int width : lane_widths())
  for (const Tangential law : {Tangential{0.1, 0.0}, Tangential{0.3, 0.5}, Tangential{5.0, 0.5}}) {
    const auto model = dem::make_contact_model(
        "linear_spring_dashpot", {{"stiffness", 1e4}, {"restitution", 0.8}}, "coulomb_spring",
        {{"stiffness", 3e3}, {"friction", law.friction}, {"damping_factor", law.damping_factor}});
    BatchedAndSingle fields(model, width);
    ASSERT_EQ(fields.batched.lane_width(), width);
    auto& [batched, single] = fields;
    gw::ParticleStore a = fast_gas_with_fixed(19);
    gw::ParticleStore b = a;
    dem::VelocityVerlet verlet_a, verlet_b;
    const double dt = dem::stable_time_step(a, *model.normal, 50);
    std::vector<dem::ContactHistoryEntry> entries_a, entries_b;
    auto by_pair = [](const dem::ContactHistoryEntry& x, const dem::ContactHistoryEntry& y) {
      return std::tie(x.first, x.second) < std::tie(y.first, y.second);
    };
    long contacts = 0, stored = 0;
    for (int step = 0; step < 1000; ++step) {
      verlet_a.step(a, batched, dt);
      verlet_b.step(b, single, dt);
      const std::string where = "lanes " + std::to_string(width) + " friction " + std::to_string(law.friction) + " damping " +
                                std::to_string(law.damping_factor) + " step " + std::to_string(step);
      ASSERT_EQ(batched.contact_count(), single.contact_count()) << where;
      for (std::size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a.position[i], b.position[i]) << where << " particle " << i;
        ASSERT_EQ(a.velocity[i], b.velocity[i]) << where << " particle " << i;
        ASSERT_EQ(a.angular_velocity[i], b.angular_velocity[i]) << where << " particle " << i;
        ASSERT_EQ(batched.force()[i], single.force()[i]) << where << " particle " << i;
        ASSERT_EQ(batched.torque()[i], single.torque()[i]) << where << " particle " << i;
      }
      batched.history().live_entries(entries_a);
      single.history().live_entries(entries_b);
      ASSERT_EQ(entries_a.size(), entries_b.size()) << where;
      std::sort(entries_a.begin(), entries_a.end(), by_pair);
      std::sort(entries_b.begin(), entries_b.end(), by_pair);
      for (std::size_t k = 0; k < entries_a.size(); ++k) {
        const auto& x = entries_a[k];
        const auto& y = entries_b[k];
        ASSERT_EQ(std::tie(x.first, x.second, x.last_step, x.is_new), std::tie(y.first, y.second, y.last_step, y.is_new))
            << where << " entry " << k;
        ASSERT_EQ(x.displacement, y.displacement) << where << " pair " << x.first << "-" << x.second;
        ASSERT_EQ(x.stage_velocity, y.stage_velocity) << where << " pair " << x.first << "-" << x.second;
        stored += x.displacement.squaredNorm() > 0.0 ? 1 : 0;
      }
      contacts += static_cast<long>(batched.contact_count());
    }
    std::printf("lanes %d, coulomb spring mu %.1f damping %.1f: %ld contacts, %ld stored springs, %ld builds\n",
                width, law.friction, law.damping_factor, contacts, stored, batched.verlet_list().builds());
    EXPECT_GT(contacts, 5000);
    EXPECT_GT(stored, 1000);
    EXPECT_GT(batched.verlet_list().builds(), 5);
  }
}
