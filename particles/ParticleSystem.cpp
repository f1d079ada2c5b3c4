#include "particles/ParticleSystem.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <type_traits>
#include <unordered_map>

#include "core/Mpi.hpp"

namespace grainwave::particles {

namespace {
const std::vector<std::string> kFaceKinds = {"periodic", "wall", "open"};

FaceKind face_kind(const std::string& s) {
  if (s == "wall") return FaceKind::kWall;
  if (s == "open") return FaceKind::kOpen;
  return FaceKind::kPeriodic;
}

Vec3 vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

/// Mass of a sphere (3D) or of a disk of unit depth (2D).
double particle_mass(int dimension, double radius, double density) {
  return dimension == 2 ? density * std::numbers::pi * radius * radius
                        : density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
}

struct InitialParticle {
  Vec3 x, v, omega;
  double radius, density;
};
}  // namespace

void ParticleSystem::declare(SceneSchema& schema) {
  auto& s = schema.section("particles",
                           "Particles in a box: free flight under body forces; builds the "
                           "particle system.");
  s.integer("dimension", 3, "2: disks in the x-y plane (unit depth); 3: spheres").in_range(2, 3);
  s.reals("box_lo", std::nullopt, "lower corner of the box").of_length(3);
  s.reals("box_hi", std::nullopt, "upper corner of the box").of_length(3);
  for (const char* axis : {"x", "y", "z"})
    s.texts(fmt::format("boundary_{}", axis), std::vector<std::string>{"periodic", "periodic"},
            fmt::format("kind of the low and high {} faces", axis))
        .one_of(kFaceKinds)
        .of_length(2);
  s.reals("gravity", std::vector<double>{0, 0, 0}, "body-force acceleration").of_length(3);
  s.text("placement", "random",
         "initial positions: random (non-overlapping), cubic or fcc lattice, or list "
         "([[particle]] entries)")
      .one_of({"random", "cubic", "fcc", "list"});
  s.integer("count", 0, "number of particles (random, cubic; fcc fills the box)").at_least(0);
  s.real("radius", 0.5, "particle radius").above(0);
  s.real("density", 1.0, "particle material density").above(0);
  s.real("velocity_rms", 0.0,
         "initial random velocities: root-mean-square speed (zero net momentum)")
      .at_least(0);
  s.integer("seed", 12345, "random seed for placement and velocities");

  auto& p = schema.section("particle",
                           "One explicitly placed particle (used with particles.placement = "
                           "\"list\").",
                           true);
  p.reals("position", std::nullopt, "centre").of_length(3);
  p.reals("velocity", std::vector<double>{0, 0, 0}, "velocity").of_length(3);
  p.reals("angular_velocity", std::vector<double>{0, 0, 0}, "angular velocity").of_length(3);
  p.real("radius", 0.0, "radius; 0 takes particles.radius").at_least(0);
  p.real("density", 0.0, "density; 0 takes particles.density").at_least(0);
}

ParticleSystem::ParticleSystem(const Scene& scene) {
  const auto& s = scene.section("particles");
  domain_.dimension = static_cast<int>(s.integer("dimension"));
  domain_.lo = vec3(s.reals("box_lo"));
  domain_.hi = vec3(s.reals("box_hi"));
  for (int k = 0; k < domain_.dimension; ++k)
    if (domain_.hi[k] <= domain_.lo[k])
      s.fail("box_hi", "the box must have box_hi > box_lo along every axis");
  const char* axes[] = {"boundary_x", "boundary_y", "boundary_z"};
  for (int k = 0; k < 3; ++k) {
    const auto& faces = s.texts(axes[k]);
    const FaceKind lo = face_kind(faces[0]), hi = face_kind(faces[1]);
    if ((lo == FaceKind::kPeriodic) != (hi == FaceKind::kPeriodic))
      s.fail(axes[k], "a periodic face needs a periodic opposite face");
    domain_.face[static_cast<std::size_t>(k)] = {lo, hi};
  }
  for (int k = 0; k < domain_.dimension; ++k)
    if (domain_.face[static_cast<std::size_t>(k)][0] == FaceKind::kWall ||
        domain_.face[static_cast<std::size_t>(k)][1] == FaceKind::kWall)
      s.fail(axes[k], "wall faces need particle collisions, which this build does not have yet",
             "use periodic or open faces");
  gravity_ = vec3(s.reals("gravity"));
  if (domain_.dimension == 2 && gravity_.z() != 0)
    s.fail("gravity", "a 2D scene needs gravity with z = 0");
  place_initial_particles(scene);
  initial_count_ = global_count();
  initial_energy_ = kinetic_energy();
  initial_momentum_ = linear_momentum();
}

void ParticleSystem::place_initial_particles(const Scene& scene) {
  const auto& s = scene.section("particles");
  const int dim = domain_.dimension;
  const double radius = s.real("radius");
  const double density = s.real("density");
  const std::string placement = s.text("placement");
  const Vec3 L = domain_.length();
  std::vector<InitialParticle> all;

  if (placement == "list") {
    const auto& entries = scene.entries("particle");
    if (entries.empty())
      s.fail("placement", "placement = \"list\" needs [[particle]] entries");
    for (const auto& e : entries) {
      InitialParticle q{vec3(e.reals("position")), vec3(e.reals("velocity")),
                        vec3(e.reals("angular_velocity")),
                        e.real("radius") > 0 ? e.real("radius") : radius,
                        e.real("density") > 0 ? e.real("density") : density};
      for (int k = 0; k < dim; ++k)
        if (q.x[k] < domain_.lo[k] || q.x[k] > domain_.hi[k])
          e.fail("position", "particle lies outside the box");
      if (dim == 2 && (q.x.z() != 0 || q.v.z() != 0 || q.omega.x() != 0 || q.omega.y() != 0))
        e.fail("position", "a 2D particle needs z = 0, v_z = 0 and only omega_z");
      all.push_back(q);
    }
  } else if (placement == "cubic" || placement == "fcc") {
    // Lattice cells per axis: as many as fit, spacing = L / n (so the periodic image matches).
    const bool fcc = placement == "fcc";
    std::array<long, 3> n{1, 1, 1};
    const auto count = s.integer("count");
    if (!fcc) {
      if (count <= 0) s.fail("count", "placement = \"cubic\" needs count > 0");
      const double per_axis = std::ceil(std::pow(static_cast<double>(count), 1.0 / dim) - 1e-9);
      for (int k = 0; k < dim; ++k) n[static_cast<std::size_t>(k)] = static_cast<long>(per_axis);
    } else {
      // FCC fills the box with n^dim cells of (dim == 3 ? 4 : 2) particles; count fixes n.
      const int basis = dim == 3 ? 4 : 2;
      const double cells = std::round(std::pow(static_cast<double>(count) / basis, 1.0 / dim));
      if (count <= 0 || static_cast<long>(std::pow(cells, dim)) * basis != count)
        s.fail("count", fmt::format("placement = \"fcc\" needs count = {}*n^{}", basis, dim));
      for (int k = 0; k < dim; ++k) n[static_cast<std::size_t>(k)] = static_cast<long>(cells);
    }
    std::vector<Vec3> basis_points = {Vec3(0.25, 0.25, dim == 3 ? 0.25 : 0)};
    if (fcc) {
      basis_points = dim == 3 ? std::vector<Vec3>{{0.25, 0.25, 0.25},
                                                  {0.75, 0.75, 0.25},
                                                  {0.75, 0.25, 0.75},
                                                  {0.25, 0.75, 0.75}}
                              : std::vector<Vec3>{{0.25, 0.25, 0}, {0.75, 0.75, 0}};
    } else {
      basis_points = {Vec3(0.5, 0.5, dim == 3 ? 0.5 : 0)};
    }
    const long nz = dim == 3 ? n[2] : 1;
    for (long iz = 0; iz < nz; ++iz)
      for (long iy = 0; iy < n[1]; ++iy)
        for (long ix = 0; ix < n[0]; ++ix)
          for (const auto& b : basis_points) {
            if (!fcc && static_cast<long>(all.size()) >= count) break;
            Vec3 x = domain_.lo;
            x.x() += (static_cast<double>(ix) + b.x()) * L.x() / static_cast<double>(n[0]);
            x.y() += (static_cast<double>(iy) + b.y()) * L.y() / static_cast<double>(n[1]);
            if (dim == 3) x.z() += (static_cast<double>(iz) + b.z()) * L.z() / static_cast<double>(nz);
            else x.z() = 0;
            all.push_back({x, Vec3::Zero(), Vec3::Zero(), radius, density});
          }
    const double spacing = L.head(dim).minCoeff() / static_cast<double>(n[0]) / (fcc ? std::sqrt(2.0) : 1.0);
    if (spacing < 2 * radius)
      s.fail("radius", fmt::format("lattice spacing {:.4g} is smaller than a diameter", spacing));
  } else {
    // Random sequential addition with a cell grid: O(N) expected while far below saturation.
    const auto count = s.integer("count");
    if (count <= 0) s.fail("count", "placement = \"random\" needs count > 0");
    std::mt19937_64 rng(static_cast<std::uint64_t>(s.integer("seed")));
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double cell = 2 * radius;
    std::array<long, 3> cells{1, 1, 1};
    for (int k = 0; k < dim; ++k)
      cells[static_cast<std::size_t>(k)] = std::max(1L, static_cast<long>(L[k] / cell));
    std::unordered_map<long, std::vector<std::size_t>> grid;
    auto cell_of = [&](const Vec3& x, int k) {
      const auto c = static_cast<long>((x[k] - domain_.lo[k]) / L[k] * static_cast<double>(cells[static_cast<std::size_t>(k)]));
      return std::clamp(c, 0L, cells[static_cast<std::size_t>(k)] - 1);
    };
    auto key = [&](long cx, long cy, long cz) { return (cz * cells[1] + cy) * cells[0] + cx; };
    const long max_attempts = 1000 * count + 10000;
    long attempts = 0;
    while (static_cast<long>(all.size()) < count) {
      if (++attempts > max_attempts)
        s.fail("count", fmt::format("could not place {} non-overlapping particles at random "
                                    "(placed {}); lower count or radius",
                                    count, all.size()));
      Vec3 x = domain_.lo;
      for (int k = 0; k < dim; ++k) {
        // Keep clear of non-periodic faces so no particle starts cut by a wall.
        const double margin = domain_.periodic(k) ? 0.0 : radius;
        x[k] += margin + unit(rng) * (L[k] - 2 * margin);
      }
      const long cx = cell_of(x, 0), cy = cell_of(x, 1), cz = dim == 3 ? cell_of(x, 2) : 0;
      bool overlaps = false;
      for (long dz = (dim == 3 ? -1 : 0); dz <= (dim == 3 ? 1 : 0) && !overlaps; ++dz)
        for (long dy = -1; dy <= 1 && !overlaps; ++dy)
          for (long dx = -1; dx <= 1 && !overlaps; ++dx) {
            auto wrap_cell = [](long c, long n) { return ((c % n) + n) % n; };
            const auto it = grid.find(key(wrap_cell(cx + dx, cells[0]), wrap_cell(cy + dy, cells[1]),
                                          wrap_cell(cz + dz, cells[2])));
            if (it == grid.end()) continue;
            for (std::size_t j : it->second)
              if (domain_.separation(all[j].x, x).squaredNorm() < 4 * radius * radius) {
                overlaps = true;
                break;
              }
          }
      if (overlaps) continue;
      grid[key(cx, cy, cz)].push_back(all.size());
      all.push_back({x, Vec3::Zero(), Vec3::Zero(), radius, density});
    }
  }

  // Random velocities with zero net momentum (same on every rank: one global generator).
  const double vrms = s.real("velocity_rms");
  if (vrms > 0 && placement != "list") {
    std::mt19937_64 rng(static_cast<std::uint64_t>(s.integer("seed")) + 1);
    std::normal_distribution<double> normal(0.0, vrms / std::sqrt(static_cast<double>(dim)));
    Vec3 mean = Vec3::Zero();
    for (auto& q : all) {
      for (int k = 0; k < dim; ++k) q.v[k] = normal(rng);
      mean += q.v;
    }
    mean /= static_cast<double>(all.size());
    for (auto& q : all) q.v -= mean;
  }

  // Keep this rank's contiguous slice.
  const auto n = static_cast<std::int64_t>(all.size());
  const std::int64_t rank = mpi::rank(), ranks = mpi::size();
  const std::int64_t first = n * rank / ranks, last = n * (rank + 1) / ranks;
  store_.reserve(static_cast<std::size_t>(last - first));
  for (std::int64_t i = first; i < last; ++i) {
    const auto& q = all[static_cast<std::size_t>(i)];
    const double m = particle_mass(dim, q.radius, q.density);
    store_.add(i, q.x, q.v, q.omega, q.radius, m, solid_inertia(dim, m, q.radius));
  }
}

std::string ParticleSystem::describe() const {
  const char* names[] = {"periodic", "wall", "open"};
  std::string faces;
  for (int k = 0; k < domain_.dimension; ++k)
    faces += fmt::format("{}{}:{}/{}", k ? ", " : "", "xyz"[k],
                         names[static_cast<int>(domain_.face[static_cast<std::size_t>(k)][0])],
                         names[static_cast<int>(domain_.face[static_cast<std::size_t>(k)][1])]);
  return fmt::format("particles: {} {} in a {}D box ({}), free flight, gravity ({}, {}, {})",
                     global_count(), domain_.dimension == 3 ? "spheres" : "disks",
                     domain_.dimension, faces, gravity_.x(), gravity_.y(), gravity_.z());
}

double ParticleSystem::max_stable_dt() const { return std::numeric_limits<double>::infinity(); }

void ParticleSystem::advance(double /*t*/, double dt) {
  ScopedTimer timer(timers_, "free_flight");
  const std::size_t n = store_.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (store_.is_fixed(i)) continue;
    const Vec3 a = gravity_ + store_.force[i] / store_.mass[i];
    store_.position[i] += store_.velocity[i] * dt + 0.5 * a * dt * dt;
    store_.velocity[i] += a * dt;
    store_.angular_velocity[i] += store_.torque[i] / store_.inertia[i] * dt;
  }
  apply_boundaries();
}

void ParticleSystem::apply_boundaries() {
  for (std::size_t i = 0; i < store_.size();) {
    bool leaves = false;
    for (int k = 0; k < domain_.dimension; ++k) {
      const auto& f = domain_.face[static_cast<std::size_t>(k)];
      if ((f[0] == FaceKind::kOpen && store_.position[i][k] < domain_.lo[k]) ||
          (f[1] == FaceKind::kOpen && store_.position[i][k] > domain_.hi[k]))
        leaves = true;
    }
    if (leaves) {
      store_.remove(i);
      ++removed_;
      continue;
    }
    domain_.wrap(store_.position[i]);
    ++i;
  }
}

std::optional<std::string> ParticleSystem::check_state() const {
  for (std::size_t i = 0; i < store_.size(); ++i) {
    const bool finite = store_.position[i].allFinite() && store_.velocity[i].allFinite() &&
                        store_.angular_velocity[i].allFinite();
    if (!finite) {
      const Vec3& x = store_.position[i];
      return fmt::format("non-finite state of particle id {} (position ({}, {}, {}), velocity "
                         "({}, {}, {}))",
                         store_.id[i], x.x(), x.y(), x.z(), store_.velocity[i].x(),
                         store_.velocity[i].y(), store_.velocity[i].z());
    }
  }
  return std::nullopt;
}

std::int64_t ParticleSystem::global_count() const {
  return mpi::sum(static_cast<std::int64_t>(store_.size()));
}

double ParticleSystem::kinetic_energy() const {
  double e = 0;
  for (std::size_t i = 0; i < store_.size(); ++i)
    e += 0.5 * store_.mass[i] * store_.velocity[i].squaredNorm() +
         0.5 * store_.inertia[i] * store_.angular_velocity[i].squaredNorm();
  return mpi::sum(e);
}

Vec3 ParticleSystem::linear_momentum() const {
  Vec3 p = Vec3::Zero();
  for (std::size_t i = 0; i < store_.size(); ++i) p += store_.mass[i] * store_.velocity[i];
  return {mpi::sum(p.x()), mpi::sum(p.y()), mpi::sum(p.z())};
}

namespace {
/// This rank's slots sorted by particle id, so files are independent of the rank count.
std::vector<std::size_t> id_order(const ParticleStore& s) {
  std::vector<std::size_t> order(s.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return s.id[a] < s.id[b]; });
  return order;
}

/// Writes one per-particle array in `order`: 3 components for vectors, 1 for scalars.
template <class T>
void write_ordered(io::Hdf5Group& g, const std::string& name, const std::vector<T>& values,
                   const std::vector<std::size_t>& order) {
  constexpr bool is_vector = std::is_same_v<T, Vec3>;
  std::vector<double> flat;
  flat.reserve((is_vector ? 3 : 1) * order.size());
  for (auto i : order) {
    if constexpr (is_vector) flat.insert(flat.end(), {values[i].x(), values[i].y(), values[i].z()});
    else flat.push_back(values[i]);
  }
  g.write_rows(name, flat.data(), order.size(), is_vector ? 3 : 1);
}

void write_store(io::Hdf5Group& g, const ParticleStore& s, bool full) {
  const auto order = id_order(s);
  write_ordered(g, "position", s.position, order);
  write_ordered(g, "velocity", s.velocity, order);
  write_ordered(g, "angular_velocity", s.angular_velocity, order);
  write_ordered(g, "radius", s.radius, order);
  std::vector<std::int64_t> ids;
  for (auto i : order) ids.push_back(s.id[i]);
  g.write_rows("id", ids.data(), ids.size(), 1);
  if (full) {
    write_ordered(g, "mass", s.mass, order);
    write_ordered(g, "inertia", s.inertia, order);
    write_ordered(g, "force", s.force, order);
    write_ordered(g, "torque", s.torque, order);
    std::vector<std::int64_t> flags;
    for (auto i : order) flags.push_back(s.flags[i]);
    g.write_rows("flags", flags.data(), flags.size(), 1);
  }
}
}  // namespace

std::vector<io::OutputGrid> ParticleSystem::write_output(io::Hdf5File& file,
                                                         const std::string& file_name) {
  ScopedTimer timer(timers_, "output");
  auto g = file.root().create_group("particles");
  write_store(g, store_, false);
  const long n = static_cast<long>(global_count());
  g.set_attribute("count", static_cast<std::int64_t>(n));
  g.set_attribute("dimension", static_cast<std::int64_t>(domain_.dimension));
  const std::string base = file_name + ":/particles/";
  std::vector<io::XdmfArray> arrays = {{"radius", base + "radius", 1},
                                       {"velocity", base + "velocity", 3},
                                       {"angular_velocity", base + "angular_velocity", 3},
                                       {"id", base + "id", 1, "Int", 8}};
  return {{"particles", io::polyvertex_grid("particles", n, base + "position", arrays)}};
}

void ParticleSystem::write_checkpoint(io::Hdf5Group& group) {
  auto g = group.create_group("particles");
  write_store(g, store_, true);
  g.set_attribute("removed", removed_);
  g.set_attribute("initial_count", initial_count_);
  g.set_attribute("initial_energy", initial_energy_);
  for (int k = 0; k < 3; ++k)
    g.set_attribute(fmt::format("initial_momentum_{}", k), initial_momentum_[k]);
}

void ParticleSystem::read_checkpoint(const io::Hdf5Group& group) {
  const auto g = group.open_group("particles");
  const auto n = static_cast<std::int64_t>(g.shape("id")[0]);
  const std::int64_t rank = mpi::rank(), ranks = mpi::size();
  const auto first = static_cast<std::uint64_t>(n * rank / ranks);
  const auto count = static_cast<std::uint64_t>(n * (rank + 1) / ranks) - first;
  const auto x = g.read_rows_real("position", first, count);
  const auto v = g.read_rows_real("velocity", first, count);
  const auto w = g.read_rows_real("angular_velocity", first, count);
  const auto f = g.read_rows_real("force", first, count);
  const auto t = g.read_rows_real("torque", first, count);
  const auto r = g.read_rows_real("radius", first, count);
  const auto m = g.read_rows_real("mass", first, count);
  const auto inertia = g.read_rows_real("inertia", first, count);
  const auto ids = g.read_rows_integer("id", first, count);
  const auto flags = g.read_rows_integer("flags", first, count);
  store_.clear();
  for (std::size_t i = 0; i < count; ++i) {
    auto v3 = [&](const std::vector<double>& a) { return Vec3(a[3 * i], a[3 * i + 1], a[3 * i + 2]); };
    store_.add(ids[i], v3(x), v3(v), v3(w), r[i], m[i], inertia[i],
               static_cast<std::uint32_t>(flags[i]));
    store_.force.back() = v3(f);
    store_.torque.back() = v3(t);
  }
  removed_ = g.integer_attribute("removed");
  initial_count_ = g.integer_attribute("initial_count");
  initial_energy_ = g.real_attribute("initial_energy");
  for (int k = 0; k < 3; ++k)
    initial_momentum_[k] = g.real_attribute(fmt::format("initial_momentum_{}", k));
}

void ParticleSystem::report(io::Json& counts, io::Json& metrics, double step_wall_s,
                            long steps) const {
  const std::int64_t n = global_count();
  counts.set("particles", n);
  counts.set("particles_removed", mpi::sum(removed_));
  const double energy = kinetic_energy();
  metrics.set("kinetic_energy", energy);
  // Drifts are only defined for a closed system: no body force doing work, nobody leaving.
  if (gravity_.isZero() && mpi::sum(removed_) == 0) {
    metrics.set("momentum_abs_drift", (linear_momentum() - initial_momentum_).norm());
    metrics.set("energy_rel_drift",
                initial_energy_ > 0 ? (energy - initial_energy_) / initial_energy_ : 0.0);
  }
  const double particle_steps = static_cast<double>(n) * static_cast<double>(steps);
  metrics.set("particle_steps_per_s", step_wall_s > 0 ? particle_steps / step_wall_s : 0.0);
  metrics.set("bytes_per_particle", static_cast<double>(ParticleStore::bytes_per_particle()));
}

std::size_t ParticleSystem::memory_bytes() const {
  // The state and its last-good copy.
  return 2 * store_.size() * ParticleStore::bytes_per_particle();
}

std::string ParticleSystem::progress_note() const {
  return fmt::format("N {}", store_.size());
}

}  // namespace grainwave::particles
