// Hard-sphere collision throughput: collisions processed per second for the hard-sphere gas at
// packing fraction 0.2618 (n = 0.5 diameters^-3), FCC start melted before timing, e = 1, mu = 0.
// Run, never asserted: `bench_hardsphere --benchmark_counter_tabular=true`.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "particles/hardsphere/EventDrivenCollider.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace gp = grainwave::particles;
namespace hs = grainwave::particles::hardsphere;
using gp::Vec3;

namespace {

constexpr double kPackingFraction = 0.2618;

/// FCC lattice of 4 k^3 unit-diameter spheres, Maxwellian velocities at kT = 1, zero momentum.
void fcc_gas(gp::ParticleStore& store, gp::Domain& domain, int k) {
  const double pi = std::acos(-1.0);
  const double a = std::cbrt(4.0 * pi / (6.0 * kPackingFraction));
  domain = gp::Domain{};
  domain.hi = Vec3::Constant(k * a);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 basis[4] = {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5), Vec3(0, 0.5, 0.5)};
  store.clear();
  store.reserve(static_cast<std::size_t>(4 * k * k * k));
  std::int64_t id = 0;
  for (int ix = 0; ix < k; ++ix)
    for (int iy = 0; iy < k; ++iy)
      for (int iz = 0; iz < k; ++iz)
        for (const Vec3& b : basis) {
          store.add(id++, a * (Vec3(ix, iy, iz) + b + Vec3::Constant(0.25)),
                    Vec3(g(rng), g(rng), g(rng)), Vec3::Zero(), 0.5, 1.0, gp::solid_inertia(3, 1.0, 0.5));
        }
  Vec3 mean = Vec3::Zero();
  for (const Vec3& v : store.velocity) mean += v;
  mean /= static_cast<double>(store.size());
  for (Vec3& v : store.velocity) v -= mean;
}

int lattice_cells(long n) { return static_cast<int>(std::lround(std::cbrt(n / 4.0))); }

// About one collision per particle per call: Enskog gives Gamma ~ 7.7 per unit time at kT = 1.
constexpr double kInterval = 0.26;

void BM_EventDriven(benchmark::State& state) {
  gp::ParticleStore store;
  gp::Domain domain;
  fcc_gas(store, domain, lattice_cells(state.range(0)));
  hs::EventDrivenCollider collider(hs::EventDrivenSettings{hs::CollisionLaw{1.0, 0.0}});
  collider.initialize(store, domain);
  double t = 2.0;
  collider.advance_to(store, domain, t);  // melt
  long collisions = 0, crossings = 0, stale = 0, predictions = 0, checks = 0;
  for (auto _ : state) {
    t += kInterval;
    const auto stats = collider.advance_to(store, domain, t);
    collisions += stats.collisions;
    crossings += stats.cell_crossings;
    stale += stats.stale_events;
    predictions += stats.predictions;
    checks += stats.pair_checks;
  }
  state.counters["predict/coll"] = static_cast<double>(predictions) / static_cast<double>(collisions);
  state.counters["checks/coll"] = static_cast<double>(checks) / static_cast<double>(collisions);
  state.counters["N"] = static_cast<double>(store.size());
  state.counters["collisions/s"] = benchmark::Counter(static_cast<double>(collisions), benchmark::Counter::kIsRate);
  state.counters["crossings/coll"] = static_cast<double>(crossings) / static_cast<double>(collisions);
  state.counters["stale/coll"] = static_cast<double>(stale) / static_cast<double>(collisions);
}

void BM_Retrospective(benchmark::State& state) {
  gp::ParticleStore store;
  gp::Domain domain;
  fcc_gas(store, domain, lattice_cells(state.range(0)));
  hs::RetrospectiveCollider collider(hs::RetrospectiveSettings{hs::CollisionLaw{1.0, 0.0}});
  const double dt = 0.05;  // ~0.4 collisions per particle per step
  for (int k = 0; k < 40; ++k) collider.step(store, domain, dt);  // melt
  long collisions = 0, predictions = 0, substeps = 0;
  for (auto _ : state) {
    const auto stats = collider.step(store, domain, dt);
    collisions += stats.collisions;
    predictions += stats.predictions;
    substeps += stats.substeps;
  }
  state.counters["N"] = static_cast<double>(store.size());
  state.counters["collisions/s"] = benchmark::Counter(static_cast<double>(collisions), benchmark::Counter::kIsRate);
  state.counters["particle-steps/s"] = benchmark::Counter(
      static_cast<double>(store.size()) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["solves/coll"] = static_cast<double>(predictions) / static_cast<double>(collisions);
  state.counters["substeps/step"] = static_cast<double>(substeps) / static_cast<double>(state.iterations());
}

}  // namespace

BENCHMARK(BM_EventDriven)->Arg(1372)->Arg(97556)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Retrospective)->Arg(1372)->Arg(97556)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
