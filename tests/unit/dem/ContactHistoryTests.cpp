// Contact history keyed by id pairs: lifetime, purge, growth, and survival of slot reordering.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/ContactHistory.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cstdint>
#include <numbers>
#include <vector>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

TEST(ContactHistory, EntryLivesWhileTouchedEveryStep) {
  dem::ContactHistory h;
  h.begin_step();
  h.prepare();
  dem::ContactHistoryEntry* e = h.touch(7, 3);
  e->displacement = Vec3(1, 2, 3);
  h.begin_step();
  h.prepare();
  EXPECT_EQ(h.touch(3, 7)->displacement, Vec3(1, 2, 3));  // order-independent key
  h.begin_step();  // not touched in this step ...
  h.begin_step();  // ... so stale in the next
  h.prepare();
  EXPECT_EQ(h.find(3, 7), nullptr);
  EXPECT_EQ(h.touch(3, 7)->displacement, Vec3::Zero());
}

TEST(ContactHistory, GrowsAndPurgesWithoutLosingLiveEntries) {
  dem::ContactHistory h;
  for (int step = 0; step < 50; ++step) {
    h.begin_step();
    h.prepare();
    for (std::int64_t k = 0; k < 1000; ++k) {
      if (h.nearly_full()) h.make_room();  // pointers are not kept across iterations here
      // Half the contacts persist, the other half are new every step.
      const std::int64_t other = k < 500 ? k + 1 : 100000 + step * 1000 + k;
      dem::ContactHistoryEntry* e = h.touch(k, other);
      if (k < 500 && step > 0) {
        ASSERT_DOUBLE_EQ(e->displacement.x(), step - 1.0);
      }
      e->displacement.x() = step;
    }
  }
  EXPECT_EQ(h.live_count(), 1500u);  // this step's 1000 plus last step's 500 transient ones
  EXPECT_LE(h.capacity(), 4096u);  // 1500 live entries fill at most half after a purge
}

namespace {
/// Two spheres centred at centre_x -/+ 0.099 pressed together and sheared; after 20 steps the
/// slots of one copy are swapped (remove + re-add, as migration or deletion would). Both copies
/// must go on alike: the stored displacement is found by ids and read in the same orientation.
void shear_pair_and_swap_slots(double centre_x) {
  gw::Domain domain;
  for (auto& axis : domain.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  domain.lo = Vec3::Constant(-1.0);
  domain.hi = Vec3::Constant(1.0);
  auto model = dem::make_contact_model("linear_spring_dashpot", {{"stiffness", 1e3}},
                                       "coulomb_spring", {{"stiffness", 1e3}, {"friction", 0.5}});
  auto make_pair = [centre_x](gw::ParticleStore& s, bool swapped) {
    // y and z mid-cell, so the shear motion stays inside one cell row.
    const Vec3 xa(centre_x - 0.099, 0.5, 0.5), xb(centre_x + 0.099, 0.5, 0.5);
    const Vec3 va(0, 0.01, 0), vb(0, -0.01, 0);
    if (!swapped) {
      s.add(10, xa, va, Vec3::Zero(), 0.1, 1.0, 0.004);
      s.add(20, xb, vb, Vec3::Zero(), 0.1, 1.0, 0.004);
    } else {
      s.add(20, xb, vb, Vec3::Zero(), 0.1, 1.0, 0.004);
      s.add(10, xa, va, Vec3::Zero(), 0.1, 1.0, 0.004);
    }
  };
  gw::ParticleStore plain, swapped;
  make_pair(plain, false);
  make_pair(swapped, false);
  dem::ContactForceSettings settings;
  settings.cell_width = 1.0;  // two cells along x: [-1, 0) and [0, 1)
  dem::ContactForceField field_plain(model, domain, settings), field_swapped(model, domain, settings);
  dem::VelocityVerlet a, b;
  const double dt = 1e-4;
  for (int k = 0; k < 20; ++k) {
    a.step(plain, field_plain, dt);
    b.step(swapped, field_swapped, dt);
  }
  // Swap the slots of `swapped`: remove slot 0 (moves id 20 into slot 0), append id 10 again.
  gw::ParticleStore copy = swapped;
  swapped.remove(0);
  swapped.append_from(copy, 0);
  ASSERT_EQ(swapped.id[0], 20);
  a.reset();  // both runs recompute forces at the same state, so they stay bitwise comparable
  b.reset();
  const auto* stored = field_swapped.history().find(10, 20);
  ASSERT_NE(stored, nullptr);
  const Vec3 before = stored->displacement;
  EXPECT_GT(before.norm(), 0.0);
  for (int k = 0; k < 20; ++k) {
    a.step(plain, field_plain, dt);
    b.step(swapped, field_swapped, dt);
  }
  EXPECT_NEAR((swapped.velocity[1] - plain.velocity[0]).norm(), 0.0, 1e-14);
  EXPECT_NEAR((swapped.angular_velocity[0] - plain.angular_velocity[1]).norm(), 0.0, 1e-12);
  EXPECT_NEAR((field_swapped.history().find(20, 10)->displacement -
               field_plain.history().find(10, 20)->displacement).norm(), 0.0, 1e-16);
  // Without the history (fresh field) the swapped run would differ: the test can fail.
  dem::ContactForceField fresh(model, domain);
  fresh.evaluate(swapped, dem::HistoryStage::kPredict, dt);
  EXPECT_GT((fresh.force()[0] - field_swapped.force()[0]).norm(), 1e-6);
}
}  // namespace

TEST(ContactHistory, SurvivesSwappingSlots) {
  // The pair straddles the cell face at x = 0: the search meets it from the lower cell, the
  // particle with id 10, whatever the slots.
  shear_pair_and_swap_slots(0.0);
}

TEST(ContactHistory, OrientationFollowsIdsNotSlots) {
  // Both centres in the cell [0, 1): the search meets the pair in slot order, so the swap turns
  // it round. The stored displacement is kept as seen from the
  // smaller id (ContactForceField's canonical orientation); read from the other side it would
  // push the other way, and the two copies would part.
  shear_pair_and_swap_slots(0.5);
}

TEST(ContactHistory, StoredDisplacementTurnsWithTheContactPlane) {
  // A pair loaded tangentially, then turned rigidly by 45° about z (the axis normal to both the
  // contact normal and the stored displacement): the stored δ_t must turn with it, so the spring
  // force stays tangential with its magnitude (002 §3.2.2: "rotation of the contact plane").
  gw::Domain domain;
  for (auto& axis : domain.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  domain.lo = Vec3::Constant(-1.0);
  domain.hi = Vec3::Constant(1.0);
  const double k_t = 1e3, dt = 1e-3;
  auto model = dem::make_contact_model("linear_spring_dashpot", {{"stiffness", 1e4}},
                                       "coulomb_spring", {{"stiffness", k_t}, {"friction", 10.0}});
  dem::ContactForceField field(model, domain);
  gw::ParticleStore s;
  s.add(1, Vec3(-0.099, 0, 0), Vec3::Zero(), Vec3::Zero(), 0.1, 1.0, 0.004);
  s.add(2, Vec3(0.099, 0, 0), Vec3(0, 1.0, 0), Vec3::Zero(), 0.1, 1.0, 0.004);
  field.evaluate(s, dem::HistoryStage::kSingle, dt);  // δ_t = Δt v_t = 1e-3 ŷ
  ASSERT_NEAR(field.history().find(1, 2)->displacement.y(), 1e-3, 1e-15);

  const Eigen::Matrix3d turn = Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitZ()).toRotationMatrix();
  s.position[0] = turn * s.position[0];
  s.position[1] = turn * s.position[1];
  s.velocity[1].setZero();
  field.evaluate(s, dem::HistoryStage::kPredict, dt);  // uses the stored δ_t, adds nothing
  const Vec3 n = (s.position[1] - s.position[0]).normalized();
  const Vec3 tangential = field.force()[0] - field.force()[0].dot(n) * n;
  EXPECT_NEAR((tangential - k_t * 1e-3 * (turn * Vec3::UnitY())).norm(), 0.0, 1e-12);

  // A small turn about a general axis. Positions cannot reveal a twist about the line of
  // centres, so the reference is the smallest rotation taking the old normal to the new one;
  // projection plus rescaling matches it to O(θ²).
  const double theta = 1e-2;
  const Vec3 n1 = (s.position[1] - s.position[0]).normalized();
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(theta, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 before = field.history().find(1, 2)->displacement;
  s.position[0] = tilt * s.position[0];
  s.position[1] = tilt * s.position[1];
  field.evaluate(s, dem::HistoryStage::kPredict, dt);
  const Vec3 after = field.history().find(1, 2)->displacement;
  const Vec3 n2 = (s.position[1] - s.position[0]).normalized();
  EXPECT_NEAR(after.dot(n2), 0.0, 1e-18);
  EXPECT_NEAR(after.norm(), before.norm(), 1e-16);
  const Eigen::Matrix3d swing = Eigen::Quaterniond::FromTwoVectors(n1, n2).toRotationMatrix();
  EXPECT_LT((after - swing * before).norm(), theta * theta * before.norm());
}

TEST(ContactHistory, AdoptedEntryReplacesAnOlderCopyOnly) {
  // Migration between ranks: the receiving rank may still hold a live copy of the pair from a
  // step ago (it stopped seeing the pair when both particles were the sender's). The sender's
  // copy, touched this step, must win; a copy as old as the local one must not replace it.
  dem::ContactHistory here;
  here.make_room();
  here.begin_step();  // step 1
  here.touch(3, 7)->displacement = Vec3(1, 0, 0);
  here.begin_step();  // step 2: the local copy is a step old, still live
  const dem::ContactHistoryEntry newer{3, 7, 2, Vec3(2, 0, 0), Vec3::Zero(), false};
  const dem::ContactHistoryEntry older{3, 7, 1, Vec3(5, 0, 0), Vec3::Zero(), false};
  here.adopt(older);
  EXPECT_EQ(here.find(3, 7)->displacement, Vec3(1, 0, 0));
  here.adopt(newer);
  EXPECT_EQ(here.find(3, 7)->displacement, Vec3(2, 0, 0));
  EXPECT_EQ(here.find(3, 7)->last_step, 2);
  EXPECT_EQ(here.live_count(), 1u);
  here.adopt(dem::ContactHistoryEntry{4, 9, 2, Vec3(0, 3, 0), Vec3::Zero(), false});
  EXPECT_EQ(here.find(4, 9)->displacement, Vec3(0, 3, 0));
}

// The table keeps lookups short for what a dense bed asks of it: 20 000 particles with ids
// 0..N-1, three or four contacts each (the pair stored under the smaller id) and a thousand
// contacts with one floor wall, renewed over many steps so that stale entries accumulate up
// to the purge. Homes were once spaced 4 slots by id whatever the capacity (a long run of
// occupied slots where the ids crowded) and a wall's contacts all shared the wall's home.
TEST(ContactHistory, LookupsStayShortForDenseIdsAndWallContacts) {
  dem::ContactHistory history;
  const std::int64_t n = 20000;
  for (int step = 0; step < 40; ++step) {
    history.begin_step();
    history.prepare();
    for (std::int64_t a = 0; a < n; ++a) {
      // Partners shift slowly with the step: some contacts end, new ones begin.
      for (const std::int64_t offset : {std::int64_t{1}, std::int64_t{2}, 37 + (a + step / 10) % 3, std::int64_t{53}})
        if (a + offset < n && (offset != 53 || (a + step) % 4 == 0)) {
          if (history.nearly_full()) history.make_room();
          history.touch(a, a + offset);
        }
      if (a < 1000) {
        if (history.nearly_full()) history.make_room();
        history.touch(a, dem::ContactHistory::wall_key(0));
      }
    }
  }
  const double probes = history.mean_probe_length();
  std::printf("%zu live entries in %zu slots, mean probe length %.2f\n", history.live_count(),
              history.capacity(), probes);
  // A particle's k entries sit side by side from its home, (k + 1) / 2 probes on average: about
  // 3 for the 4-5 entries (live and stale) each holds here. (The old homes: about 20 000.)
  EXPECT_LT(probes, 5.0);
  EXPECT_GT(history.live_count(), static_cast<std::size_t>(3 * n));
}

// A Verlet list pins its pairs (ContactHistory::pin): each pair's data sits at its list
// position. Whatever the position holds, touch_pinned() must return the pair's own entry, the
// one find() sees, with the data it had: pairs with an entry before the pin, new pairs, a pair
// listed twice, a position asked for another pair, after purges that move the records, after
// a step without a touch (stale: restarted), and once unpinned again.
TEST(ContactHistory, PinnedTouchReturnsThePairsOwnEntry) {
  dem::ContactHistory h;
  h.begin_step();
  h.prepare();
  constexpr std::int64_t kOld = 600;
  for (std::int64_t k = 0; k < kOld; ++k) {
    if (h.nearly_full()) h.make_room();
    h.touch(k, k + 1)->displacement.x() = static_cast<double>(k);
  }
  // The list: the old pairs in reverse and some the other way round, new pairs between them,
  // and pair (7, 8) a second time at the end.
  std::vector<std::pair<std::int64_t, std::int64_t>> keys;
  for (std::int64_t k = kOld - 1; k >= 0; --k) {
    keys.emplace_back(k % 3 == 0 ? std::pair{k + 1, k} : std::pair{k, k + 1});
    if (k % 5 == 0) keys.emplace_back(5000 + k, 6000 + k);
  }
  keys.emplace_back(7, 8);
  const std::uint64_t generation = h.pin_generation();
  h.pin(keys);
  EXPECT_NE(h.pin_generation(), generation);
  ASSERT_EQ(h.pinned_count(), keys.size());
  h.begin_step();
  std::vector<dem::ContactHistoryEntry*> seen(keys.size());
  auto touch_all = [&](const char* when, bool same_pointers) {
    for (std::size_t p = 0; p < keys.size(); ++p) {
      if (h.nearly_full()) h.make_room();
      const auto [a, b] = keys[p];
      dem::ContactHistoryEntry* e = h.touch_pinned(p, a, b);
      ASSERT_EQ(e, h.find(a, b)) << when << ", position " << p;
      ASSERT_EQ(std::pair(e->first, e->second), std::pair(std::min(a, b), std::max(a, b))) << when << ", position " << p;
      ASSERT_EQ(e->pinned, dem::ContactHistoryEntry::kNotPinned);
      if (same_pointers) {
        ASSERT_EQ(e, seen[p]) << when << ", position " << p;
      }
      seen[p] = e;
      const bool old = std::min(a, b) < kOld;
      ASSERT_EQ(e->displacement.x(), old ? static_cast<double>(std::min(a, b)) : 0.0) << when << ", position " << p;
      if (!old) {
        ASSERT_TRUE(e->is_new);
      }
    }
  };
  touch_all("first touch after the pin", false);
  const auto first_78 = std::find(keys.begin(), keys.end(), std::pair<std::int64_t, std::int64_t>{7, 8});
  EXPECT_EQ(seen.back(), seen[static_cast<std::size_t>(first_78 - keys.begin())]) << "a pair listed twice has one entry";
  for (std::size_t p = 0; p + 1 < keys.size(); ++p)  // the last is the second (7, 8)
    seen[p]->displacement.y() = static_cast<double>(p % 1000);
  // Many other contacts: the table grows, moving every record; pinned data stays where it is.
  const std::size_t before = h.capacity();
  for (std::int64_t k = 0; k < 4 * kOld; ++k) {
    if (h.nearly_full()) h.make_room();
    h.touch(10000 + k, 20000 + k);
  }
  ASSERT_GT(h.capacity(), before);
  h.begin_step();
  touch_all("after the table grew", true);
  // A position asked for a pair that is not pinned there: that pair's own entry.
  EXPECT_EQ(h.touch_pinned(0, 10000, 20000), h.find(10000, 20000));
  EXPECT_EQ(h.touch_pinned(1, 3, 4), h.find(3, 4));
  // Unpinned, every pair keeps its data.
  h.pin({});
  EXPECT_EQ(h.pinned_count(), 0u);
  for (std::size_t p = 0; p + 1 < keys.size(); ++p) {
    const auto [a, b] = keys[p];
    const dem::ContactHistoryEntry* e = h.find(a, b);
    ASSERT_NE(e, nullptr) << "position " << p;
    ASSERT_EQ(e->displacement.y(), static_cast<double>(p % 1000)) << "position " << p;
  }
  // Pinned again and left untouched for a whole step: stale, restarted from zero.
  h.pin(keys);
  h.begin_step();
  h.begin_step();
  const dem::ContactHistoryEntry* restarted = h.touch_pinned(3, keys[3].first, keys[3].second);
  EXPECT_TRUE(restarted->is_new);
  EXPECT_EQ(restarted->displacement.squaredNorm(), 0.0);
  // A restore drops the pins (the positions no longer hold).
  const std::uint64_t pinned_at = h.pin_generation();
  h.restore(h.step(), {});
  EXPECT_EQ(h.pinned_count(), 0u);
  EXPECT_NE(h.pin_generation(), pinned_at);
}
