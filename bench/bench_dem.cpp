// DEM throughput: particle-steps per second of a dense, sheared granular bed (>= 20 000
// spheres, ~6 contacts each) in a periodic box over a floor, with gravity tilted 25° so it flows.
// One benchmark per tangential law: static friction (no history) and the Coulomb spring with
// id-keyed history, each with the cell search at every step and with a Verlet list.
// Targets on one core: 1.5e7 and 1e7 particle-steps/s.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"
#include "bench/DenseBed.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <cstdio>
#include <vector>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {

struct Bed {
  gw::ParticleStore store;
  gw::Domain domain;
};

Bed make_bed() {
  Bed bed;
  grainwave::bench::make_dense_bed(bed.store, bed.domain);
  return bed;
}

void run_bed(benchmark::State& state, const std::string& tangential, const dem::LawParameters& tp,
             double verlet_skin = 0.0, int lane_width = 0) {
  Bed bed = make_bed();
  dem::ContactForceSettings settings;
  settings.lane_width = lane_width;
  const double tilt = 25.0 * std::numbers::pi / 180.0;
  settings.gravity = Vec3(std::sin(tilt), -std::cos(tilt), 0.0);
  settings.verlet_skin = verlet_skin;
  settings.verlet_managed = verlet_skin > 0.0;  // as DemSystem runs it
  auto model = dem::make_contact_model("linear_spring_dashpot",
                                       {{"stiffness", 2.0e4}, {"restitution", 0.7}}, tangential, tp);
  dem::ContactForceField field(model, bed.domain, settings);
  dem::VelocityVerlet integrator;
  const double dt = dem::stable_time_step(bed.store, *model.normal, 50);
  // With a list, each step is planned first, as in DemSystem (prepare_listed_step).
  std::vector<Vec3> ahead;
  auto step = [&] {
    if (verlet_skin > 0.0)
      dem::prepare_listed_step(bed.store, field, &integrator, dt, false,
                               [&] { field.build_list(bed.store); }, {}, ahead);
    integrator.step(bed.store, field, dt);
  };
  for (int k = 0; k < 50; ++k) step();  // warm up, reach working size
  // Contacts summed over the measured steps, so the counter describes the bed that was timed
  // (not only its last step).
  double contacts = 0.0;
  for (auto _ : state) {
    step();
    contacts += static_cast<double>(field.contact_count());
  }
  const double n = static_cast<double>(bed.store.size());
  state.counters["particles"] = n;
  state.counters["contacts_per_particle"] = contacts / (n * static_cast<double>(state.iterations()));
  state.counters["particle_steps_per_s"] =
      benchmark::Counter(n * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  const double history_bytes =
      static_cast<double>(field.history().bytes()) / n;  // table, spare and pinned data
  // Scratch held by the force field and integrator: contact list, force/torque, Verlet's old
  // forces, inverse masses, cell sort (slot, cell, packed position+radius); with a Verlet list
  // also its pairs, reference positions and ids.
  double scratch_bytes =
      static_cast<double>(field.contacts().capacity() * sizeof(dem::Contact)) / n +
      4 * sizeof(Vec3) + sizeof(double) + 2 * sizeof(std::uint32_t) + 4 * sizeof(double);
  if (verlet_skin > 0.0)
    scratch_bytes += static_cast<double>(field.verlet_list().pair_count() * 2 * sizeof(std::uint32_t)) / n +
                     sizeof(Vec3) + sizeof(std::int64_t);
  state.counters["bytes_per_particle"] =
      static_cast<double>(gw::ParticleStore::bytes_per_particle()) + history_bytes + scratch_bytes;
  state.counters["history_bytes_per_particle"] = history_bytes;
  if (verlet_skin > 0.0) {
    state.counters["lanes"] = field.lane_width();
    state.counters["list_builds"] = static_cast<double>(field.verlet_list().builds());
    state.counters["steps"] = static_cast<double>(state.iterations() + 50);
  }
}

void BM_DenseBedStaticFriction(benchmark::State& state) {
  run_bed(state, "static_friction", {{"friction", 0.5}});
}
void BM_DenseBedCoulombSpringHistory(benchmark::State& state) {
  run_bed(state, "coulomb_spring", {{"stiffness", 5.7e3}, {"friction", 0.5}});
}

// Same beds with a Verlet list of skin 0.1 d (rebuilt when a particle has moved 0.05 d), the
// listed pairs computed in SIMD lanes: the argument is the lane width (0: the widest this CPU
// runs, as a run would use; then each width it runs, to compare).
void BM_DenseBedStaticFrictionVerlet(benchmark::State& state) {
  run_bed(state, "static_friction", {{"friction", 0.5}}, 0.1, static_cast<int>(state.range(0)));
}
void BM_DenseBedCoulombSpringHistoryVerlet(benchmark::State& state) {
  run_bed(state, "coulomb_spring", {{"stiffness", 5.7e3}, {"friction", 0.5}}, 0.1, static_cast<int>(state.range(0)));
}
void lane_widths(benchmark::internal::Benchmark* b) {
  b->ArgName("lanes");
  b->Arg(0);
  for (const int width : {2, 4, 8})
    if (dem::lane_width_supported(width)) b->Arg(width);
}

}  // namespace

BENCHMARK(BM_DenseBedStaticFriction)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_DenseBedCoulombSpringHistory)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_DenseBedStaticFrictionVerlet)->Apply(lane_widths)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK(BM_DenseBedCoulombSpringHistoryVerlet)->Apply(lane_widths)->Unit(benchmark::kMillisecond)->MinTime(3.0);
BENCHMARK_MAIN();
