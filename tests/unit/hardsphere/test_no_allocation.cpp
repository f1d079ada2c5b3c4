// The hot loops must not allocate once warmed up (design.md: "no allocation inside the contact
// loop"). Global operator new is replaced for this test binary; it only counts while armed.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "hard_sphere_scenes.hpp"
#include "particles/hardsphere/CellList.hpp"
#include "particles/hardsphere/EventDrivenCollider.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
// Kept out of line: inlined into callers, GCC would pair the free() with the new-expression and
// warn (-Wmismatched-new-delete), although this replacement pair is malloc/free throughout.
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace gp = grainwave::particles;
namespace hs = grainwave::particles::hardsphere;

namespace {

struct AllocationCounter {
  AllocationCounter() { g_allocations = 0; g_counting = true; }
  ~AllocationCounter() { g_counting = false; }
  long count() const { return g_allocations.load(); }
};

TEST(NoAllocation, CellListRebuild) {
  gp::ParticleStore s;
  gp::Domain d;
  gp::testing::fcc_gas(s, d, 4, 0.3, 1.0, 1);
  hs::CellList cells;
  cells.configure(d, 1.0);
  cells.build(s.position);
  for (auto& x : s.position) x += gp::Vec3(0.3, -0.2, 0.1);
  for (auto& x : s.position) d.wrap(x);
  AllocationCounter counter;
  cells.build(s.position);
  long visits = 0;
  cells.for_each_pair([&](int, int) { ++visits; });
  EXPECT_EQ(counter.count(), 0);
  EXPECT_GT(visits, 0);
}

TEST(NoAllocation, EventDrivenAdvance) {
  gp::ParticleStore s;
  gp::Domain d;
  gp::testing::fcc_gas(s, d, 4, 0.3, 1.0, 2);
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{0.95, 0.1}});
  collider.initialize(s, d);
  collider.advance_to(s, d, 1.0);
  AllocationCounter counter;
  const auto stats = collider.advance_to(s, d, 3.0);
  EXPECT_EQ(counter.count(), 0);
  EXPECT_GT(stats.collisions, 500);
}

TEST(NoAllocation, RetrospectiveStepAfterWarmUp) {
  gp::ParticleStore s;
  gp::Domain d;
  gp::testing::fcc_gas(s, d, 4, 0.4, 1.0, 3);
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  for (int k = 0; k < 50; ++k) collider.step(s, d, 0.02);
  AllocationCounter counter;
  long collisions = 0;
  for (int k = 0; k < 20; ++k) collisions += collider.step(s, d, 0.02).collisions;
  EXPECT_EQ(counter.count(), 0);
  EXPECT_GT(collisions, 100);
}

}  // namespace
