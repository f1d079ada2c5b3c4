// Guardrail: once the contact list, cells and history have reached their working size, a time
// step allocates nothing (design.md: no allocation inside the contact loop). Counts calls to the
// global operator new, replaced for this test binary.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// The replacement pair below is consistent (malloc/free); GCC's -Wmismatched-new-delete cannot
// see that once library code inlines into the sanitizer build, so it is silenced for these
// definitions only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

TEST(Allocation, SteadyStepsAllocateNothing) {
  gw::Domain domain;
  domain.hi = Vec3(6.0, 6.0, 6.0);  // periodic cube
  for (const char* tangential : {"static_friction", "coulomb_spring"}) {
    SCOPED_TRACE(tangential);
    const long at_start = g_allocations.load();
    dem::LawParameters tp{{"friction", 0.5}};
    if (std::string(tangential) == "coulomb_spring") tp.set("stiffness", 300.0);
    auto model = dem::make_contact_model("linear_spring_dashpot",
                                         {{"stiffness", 1e3}, {"restitution", 0.5}}, tangential, tp);
    dem::ContactForceField field(model, domain);
    gw::ParticleStore s;
    // Compressed cubic lattice (spacing 0.99 d): every sphere presses on six neighbours.
    std::int64_t id = 0;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        for (int k = 0; k < 6; ++k)
          s.add(id++, Vec3(i + 0.5, j + 0.5, k + 0.5), Vec3(0.01 * (i % 2), 0, 0), Vec3::Zero(),
                0.505, 1.0, 0.1);
    dem::VelocityVerlet verlet;
    dem::RungeKutta2 rk2;
    const double dt = dem::stable_time_step(s, *model.normal, 50);
    for (int k = 0; k < 20; ++k) verlet.step(s, field, dt);
    for (int k = 0; k < 20; ++k) rk2.step(s, field, dt);
    const std::size_t contacts = field.contact_count();
    const long before = g_allocations.load();
    for (int k = 0; k < 20; ++k) verlet.step(s, field, dt);
    for (int k = 0; k < 20; ++k) rk2.step(s, field, dt);
    EXPECT_GT(before - at_start, 0) << "the counter must see the set-up's allocations";
    EXPECT_EQ(g_allocations.load() - before, 0);
    EXPECT_EQ(field.contact_count(), contacts);
    EXPECT_EQ(contacts, 3u * 216u);  // the test is only meaningful with contacts present
  }
}
