// DEM throughput on several MPI ranks: the dense, sheared bed of bench_dem (20 384 spheres, ~6
// contacts each, periodic in x and z, gravity tilted 25° so it flows along x) cut into slabs
// along x (particles/dem/SlabDecomposition), stepped the way DemSystem steps it. With the cell
// search at every step (skin 0): ghost exchange before each force evaluation, migration after
// each step. With a Verlet list (skin 0.1 d, DemSystem's default): before each step the list is
// checked against the step's predicted positions; when it must be rebuilt the particles migrate
// and the ghosts are exchanged anew, otherwise only the ghosts' positions and velocities are
// refreshed before each evaluation. Run it as
//   mpirun -np 1 build/bench/bench_dem_ranks [steps]
//   mpirun -np 2 build/bench/bench_dem_ranks [steps]
// (bench/dem_parallel_efficiency.py runs both and prints the 2-rank parallel efficiency). Prints
// one line per tangential law: ranks, particle-steps/s, the share of the wall time spent in the
// ghost exchange and the migration, ghosts per rank, migrations per step, bytes per particle.
// Target (issue 7): 2-rank parallel efficiency >= 80 %.
#include "core/Mpi.hpp"
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"
#include "particles/dem/SlabDecomposition.hpp"
#include "bench/DenseBed.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
namespace mpi = grainwave::mpi;
using gw::Vec3;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

void run(const std::string& tangential, const dem::LawParameters& parameters, int steps, double skin) {
  gw::Domain domain;
  gw::ParticleStore store;
  grainwave::bench::make_dense_bed(store, domain);
  const auto total = static_cast<double>(store.size());
  dem::ContactForceSettings settings;
  const double tilt = 25.0 * std::numbers::pi / 180.0;
  settings.gravity = Vec3(std::sin(tilt), -std::cos(tilt), 0.0);
  settings.cell_width = 1.0;
  settings.grid_particles = store.size();
  settings.verlet_skin = skin;
  settings.verlet_managed = skin > 0;
  auto model = dem::make_contact_model("linear_spring_dashpot",
                                       {{"stiffness", 2.0e4}, {"restitution", 0.7}}, tangential, parameters);
  const double dt = dem::stable_time_step(store, *model.normal, 50);
  const int ranks = mpi::size();
  dem::SlabDecomposition slabs(domain, 0, dem::SlabDecomposition::balanced_cuts(domain, 0, store, ranks),
                               settings.cell_width + skin);
  slabs.keep_owned(store);
  dem::ContactForceField field(model, domain, settings);
  dem::VelocityVerlet integrator;
  double exchange_s = 0, migration_s = 0;
  std::int64_t ghosts = 0, migrated = 0;
  auto timed = [](double& seconds, auto&& work) {
    const auto start = Clock::now();
    work();
    seconds += seconds_since(start);
  };
  auto with_ghosts = [&](gw::ParticleStore& s) {
    timed(exchange_s, [&] { skin > 0 ? slabs.refresh_ghosts(s) : slabs.exchange_ghosts(s); });
    ghosts += static_cast<std::int64_t>(s.size() - integrator.forces().size());
  };
  auto migrate = [&] {
    timed(migration_s, [&] {
      migrated += static_cast<std::int64_t>(
          slabs.migrate(store, &integrator.stored_forces(), &integrator.stored_torques(),
                        model.tangential->needs_history() ? &field.history() : nullptr));
    });
  };
  std::vector<Vec3> ahead;
  long builds = 0;
  auto rebuild = [&] {
    migrate();
    timed(exchange_s, [&] { slabs.exchange_ghosts(store); });
    field.build_list(store);
    dem::SlabDecomposition::strip_ghosts(store);
    ++builds;
  };
  auto step = [&] {
    if (skin > 0) dem::prepare_listed_step(store, field, &integrator, dt, true, rebuild, with_ghosts, ahead);
    integrator.step(store, field, dt, with_ghosts);
    dem::SlabDecomposition::strip_ghosts(store);
    if (skin == 0) migrate();
  };
  for (int k = 0; k < 50; ++k) step();  // warm up, buffers reach their working size
  exchange_s = migration_s = 0;
  ghosts = migrated = 0;
  builds = 0;
  MPI_Barrier(MPI_COMM_WORLD);
  const auto start = Clock::now();
  for (int k = 0; k < steps; ++k) step();
  MPI_Barrier(MPI_COMM_WORLD);
  const double wall = seconds_since(start);
  const double exchange = mpi::max(exchange_s), migration = mpi::max(migration_s);
  const double ghosts_per_rank = static_cast<double>(mpi::sum(ghosts)) / (2.0 * steps * ranks);
  const double migrations = static_cast<double>(mpi::sum(migrated)) / steps;
  const std::string name = tangential + (skin > 0 ? "+list" : "");
  const double history_bytes =
      static_cast<double>(mpi::sum(static_cast<std::int64_t>(field.history().bytes()))) / total;
  const double bytes = static_cast<double>(gw::ParticleStore::bytes_per_particle()) + history_bytes +
                       (static_cast<double>(field.contacts().capacity() * sizeof(dem::Contact)) * ranks) / total +
                       4 * sizeof(Vec3) + sizeof(double) + 2 * sizeof(std::uint32_t) + 4 * sizeof(double);
  const double busy = wall - exchange_s - migration_s;  // this rank's own work, waits excluded
  const double busiest = mpi::max(busy), least = mpi::min(busy);
  if (mpi::is_root() && ranks > 1)
    std::printf("%-16s ranks %d  work per rank (wall minus exchanges): %.2f to %.2f s (imbalance %.1f %%)\n",
                name.c_str(), ranks, least, busiest, 100 * (busiest / least - 1));
  if (mpi::is_root())
    std::printf("%-16s ranks %d  %8.3g particle-steps/s  wall %6.2f s  ghost exchange %4.1f %%  "
                "migration %4.1f %%  ghosts/rank %6.0f  migrations/step %5.2f  list builds %ld  "
                "bytes/particle %5.0f\n",
                name.c_str(), ranks, total * steps / wall, wall, 100 * exchange / wall,
                100 * migration / wall, ghosts_per_rank, migrations, builds, bytes);
}

}  // namespace

int main(int argc, char** argv) {
  mpi::Session session(&argc, &argv);
  const int given = argc > 1 ? std::atoi(argv[1]) : 0;
  const int steps = given > 0 ? given : 300;
  for (const double skin : {0.0, 0.1}) {
    run("static_friction", {{"friction", 0.5}}, steps, skin);
    run("coulomb_spring", {{"stiffness", 5.7e3}, {"friction", 0.5}}, steps, skin);
  }
  return 0;
}
