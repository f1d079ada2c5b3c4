// Throughput of particle free flight (002 Eqs 2.11-2.13) through the particle system: the floor
// every particle module's step cost is measured against. Prints particle-steps per second.
#include <benchmark/benchmark.h>
#include <mpi.h>

#include "core/Scene.hpp"
#include "particles/ParticleSystem.hpp"

namespace gw = grainwave;

static void FreeFlight(benchmark::State& state) {
  gw::SceneSchema schema;
  gw::particles::ParticleSystem::declare(schema);
  const auto n = state.range(0);
  const auto scene = gw::Scene::parse(
      "[particles]\nbox_lo = [0,0,0]\nbox_hi = [100,100,100]\nplacement = \"random\"\n"
      "radius = 0.5\nvelocity_rms = 1.0\ngravity = [0, 0, -1]\ncount = " +
          std::to_string(n) + "\n",
      "bench", {}, schema);
  gw::particles::ParticleSystem system(scene);
  double t = 0;
  for (auto _ : state) {
    system.advance(t, 1e-3);
    t += 1e-3;
  }
  state.counters["particle_steps_per_s"] =
      benchmark::Counter(static_cast<double>(n) * static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate);
  state.counters["bytes_per_particle"] =
      static_cast<double>(gw::particles::ParticleStore::bytes_per_particle());
}
BENCHMARK(FreeFlight)->Arg(10000)->Arg(100000)->Unit(benchmark::kMicrosecond);

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  MPI_Finalize();
  return 0;
}
