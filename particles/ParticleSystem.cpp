#include "particles/ParticleSystem.hpp"

#include "particles/BoxParameters.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <sstream>
#include <type_traits>
#include <unordered_map>

#include "core/Mpi.hpp"
#include "io/AtomicFile.hpp"

namespace grainwave::particles {

namespace {


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
                           "Particles in a box: free flight under body forces, colliding as "
                           "hard spheres; builds the particle system.");
  declare_box(s, {});
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
  s.text("collisions", "auto",
         "hard-sphere collisions: none, retrospective (after each step; any forces), "
         "event_driven (equal accelerations only), or auto (event_driven when allowed)")
      .one_of({"none", "auto", "retrospective", "event_driven"});
  s.real("restitution", 1.0, "coefficient of restitution e (constant model)").in_range(0, 1);
  s.real("friction", 0.0, "Coulomb friction coefficient mu of the collisions").at_least(0);
  s.text("restitution_model", "constant",
         "constant e, or velocity_dependent (000 Eq. 2.62: elastic below the yield velocity)")
      .one_of({"constant", "velocity_dependent"});
  s.real("yield_stress", 1.0, "Y of the velocity-dependent restitution model").above(0);
  s.real("effective_modulus", 1.0, "E* of the velocity-dependent restitution model").above(0);
  s.real("overlap_tolerance", 1e-10,
         "largest overlap allowed after a step, relative to the smaller radius; deeper stops "
         "the run")
      .above(0);
  s.real("statistics_start", 0.0,
         "simulated time after which the collision frequency is measured (equilibration)")
      .at_least(0);
  s.flag("record_collisions", false,
         "write every collision (time, ids) to collisions.csv (small systems)");

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
  domain_ = read_box(s, gravity_);

  const std::string collisions = s.text("collisions");
  bool has_open = false, has_wall = false;
  for (int k = 0; k < domain_.dimension; ++k)
    for (auto f : domain_.face[static_cast<std::size_t>(k)]) {
      has_open = has_open || f == FaceKind::kOpen;
      has_wall = has_wall || f == FaceKind::kWall;
    }
  if (collisions == "none") {
    mode_ = CollisionMode::kNone;
    if (has_wall)
      s.fail("collisions", "wall faces need collisions", "set collisions = \"auto\"");
  } else if (collisions == "retrospective") {
    mode_ = CollisionMode::kRetrospective;
  } else {
    // Particles alone feel only gravity, so every acceleration is equal; open faces remove
    // particles mid-step, which the event calendar does not handle.
    if (collisions == "event_driven" && has_open)
      s.fail("collisions", "event_driven collisions do not support open faces",
             "use retrospective or auto");
    mode_ = has_open ? CollisionMode::kRetrospective : CollisionMode::kEventDriven;
  }
  replicated_ = mode_ != CollisionMode::kNone;
  law_.restitution = s.real("restitution");
  law_.friction = s.real("friction");
  law_.model = s.text("restitution_model") == "velocity_dependent"
                   ? hardsphere::RestitutionModel::kVelocityDependent
                   : hardsphere::RestitutionModel::kConstant;
  law_.plastic.yield_stress = s.real("yield_stress");
  law_.plastic.effective_modulus = s.real("effective_modulus");
  overlap_tolerance_ = s.real("overlap_tolerance");
  record_collisions_ = s.flag("record_collisions");
  statistics_start_ = s.real("statistics_start");
  if (mode_ == CollisionMode::kRetrospective) {
    hardsphere::RetrospectiveSettings settings;
    settings.law = law_;
    retrospective_ = std::make_unique<hardsphere::RetrospectiveCollider>(settings);
  } else if (mode_ == CollisionMode::kEventDriven) {
    hardsphere::EventDrivenSettings settings;
    settings.law = law_;
    event_driven_ = std::make_unique<hardsphere::EventDrivenCollider>(settings);
  }
  place_initial_particles(scene);
  if (mode_ != CollisionMode::kNone) {
    const double overlap = hardsphere::max_relative_overlap(store_, domain_, overlap_cells_);
    if (overlap > overlap_tolerance_)
      s.fail("placement", fmt::format("initial particles overlap by {:.3g} of a radius", overlap));
  }
  initial_count_ = global_count();
  initial_energy_ = kinetic_energy();
  initial_translational_energy_ = translational_energy();
  initial_momentum_ = linear_momentum();
  totals_csv_ =
      "step,t,kinetic_energy,px,py,pz,Lx,Ly,Lz,collisions,boundary_collisions,wall_hits,"
      "crossings\n";
  if (record_collisions_) collisions_csv_ = "t,id_a,id_b\n";
  record_totals(0, 0);
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
  const std::int64_t first = replicated_ ? 0 : n * rank / ranks;
  const std::int64_t last = replicated_ ? n : n * (rank + 1) / ranks;
  store_.reserve(static_cast<std::size_t>(last - first));
  for (std::int64_t i = first; i < last; ++i) {
    const auto& q = all[static_cast<std::size_t>(i)];
    const double m = particle_mass(dim, q.radius, q.density);
    store_.add(i, q.x, q.v, q.omega, q.radius, m, solid_inertia(dim, m, q.radius));
    store_.force.back() = m * gravity_;  // body force held constant over every step
  }
}

std::string ParticleSystem::describe() const {
  const char* names[] = {"periodic", "wall", "open"};
  std::string faces;
  for (int k = 0; k < domain_.dimension; ++k)
    faces += fmt::format("{}{}:{}/{}", k ? ", " : "", "xyz"[k],
                         names[static_cast<int>(domain_.face[static_cast<std::size_t>(k)][0])],
                         names[static_cast<int>(domain_.face[static_cast<std::size_t>(k)][1])]);
  const char* mode = mode_ == CollisionMode::kNone            ? "free flight, no collisions"
                     : mode_ == CollisionMode::kEventDriven ? "event-driven hard spheres"
                                                            : "retrospective hard spheres";
  return fmt::format("particles: {} {} in a {}D box ({}), {}{}{}, gravity ({}, {}, {})",
                     global_count(), domain_.dimension == 3 ? "spheres" : "disks",
                     domain_.dimension, faces, mode, mode_ == CollisionMode::kNone ? "" : " (",
                     mode_ == CollisionMode::kNone ? "" : hardsphere::describe(law_) + ")",
                     gravity_.x(), gravity_.y(), gravity_.z());
}

double ParticleSystem::max_stable_dt() const { return std::numeric_limits<double>::infinity(); }

double ParticleSystem::total(double local) const { return replicated_ ? local : mpi::sum(local); }

void ParticleSystem::save_good_state() {
  good_ = store_;
  good_tally_ = tally_;
}

void ParticleSystem::restore_good_state() {
  store_ = good_;
  tally_ = good_tally_;
  step_overlap_.reset();
  events_continue_ = false;
}

void ParticleSystem::free_flight(double dt) {
  const std::size_t n = store_.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (store_.is_fixed(i)) continue;
    const Vec3 a = store_.force[i] / store_.mass[i];
    store_.position[i] += store_.velocity[i] * dt + 0.5 * a * dt * dt;
    store_.velocity[i] += a * dt;
    store_.angular_velocity[i] += store_.torque[i] / store_.inertia[i] * dt;
  }
}

void ParticleSystem::advance(double t, double dt) {
  // Positions before the step, to count periodic crossings (jumps of over half the box).
  std::vector<Vec3>& before = scratch_position_;
  before = store_.position;
  std::vector<std::int64_t>& ids_before = scratch_ids_;
  ids_before = store_.id;
  long step_collisions = 0;
  step_log_.clear();
  step_overlap_.reset();
  if (mode_ == CollisionMode::kNone) {
    ScopedTimer timer(timers_, "free_flight");
    free_flight(dt);
    apply_boundaries();
  } else if (mode_ == CollisionMode::kRetrospective) {
    ScopedTimer timer(timers_, "collisions");
    retrospective_->record_collisions(&step_log_);
    const auto stats = retrospective_->step(store_, domain_, dt);
    step_collisions = stats.collisions;
    tally_.wall_hits += stats.wall_hits;
    tally_.removed += stats.removed;
  } else {
    ScopedTimer timer(timers_, "collisions");
    // The events go on from where the last step left them when the collider holds this very
    // state; after a restart, from the checkpoint's schedule. Predicting every event afresh
    // at each step cost as much as the collisions themselves (1372 spheres, a step of about
    // 0.8 collisions each), and a restart without the schedule would then not be exact.
    const bool goes_on = events_continue_ && event_driven_->time() == t;
    if (!goes_on && resume_schedule_ && resume_schedule_->time == t)
      event_driven_->resume(store_, domain_, *resume_schedule_);
    else if (!goes_on)
      event_driven_->initialize(store_, domain_, t);
    resume_schedule_.reset();
    events_continue_ = false;  // until advance_to has written the state back
    event_driven_->record_collisions(&step_log_);
    const auto stats = event_driven_->advance_to(store_, domain_, t + dt);
    events_continue_ = true;
    step_collisions = stats.collisions;
    tally_.wall_hits += stats.wall_hits;
  }
  tally_.collisions += step_collisions;
  if (tally_.time >= statistics_start_ * (1 - 1e-12)) {
    tally_.measured_collisions += step_collisions;
    tally_.measured_time += dt;
  }
  tally_.time += dt;
  if (record_collisions_)
    for (const auto& c : step_log_)
      collisions_csv_ += fmt::format("{},{},{}\n",
                                     mode_ == CollisionMode::kRetrospective ? t + c.time : c.time,
                                     c.id_a, c.id_b);
  // Collisions of a pair whose centres lie on opposite sides of a periodic boundary (seen at
  // the end of the step): their impulse changes the angular momentum about the origin, like a
  // crossing does (002 App. A), so they are counted apart for the conservation check.
  long boundary_collisions = 0;
  if (!step_log_.empty()) {
    auto& slot = scratch_slot_of_id_;
    std::int64_t max_id = 0;
    for (auto id : store_.id) max_id = std::max(max_id, id);
    slot.assign(static_cast<std::size_t>(max_id + 1), -1);
    for (std::size_t i = 0; i < store_.size(); ++i)
      slot[static_cast<std::size_t>(store_.id[i])] = static_cast<std::int64_t>(i);
    for (const auto& c : step_log_) {
      if (c.id_b < 0 || c.id_a > max_id || c.id_b > max_id) continue;  // walls, removed
      const auto a = slot[static_cast<std::size_t>(c.id_a)], b = slot[static_cast<std::size_t>(c.id_b)];
      if (a < 0 || b < 0) continue;
      const Vec3 d = store_.position[static_cast<std::size_t>(a)] - store_.position[static_cast<std::size_t>(b)];
      for (int k = 0; k < domain_.dimension; ++k)
        if (domain_.periodic(k) && std::abs(d[k]) > 0.5 * domain_.length()[k]) {
          ++boundary_collisions;
          break;
        }
    }
  }
  if (store_.id == ids_before)
    for (std::size_t i = 0; i < store_.size(); ++i)
      for (int k = 0; k < domain_.dimension; ++k)
        if (domain_.periodic(k) &&
            std::abs(store_.position[i][k] - before[i][k]) > 0.5 * domain_.length()[k])
          ++tally_.crossings;
  if (mode_ != CollisionMode::kNone) {
    ScopedTimer timer(timers_, "overlap_check");
    step_overlap_ = hardsphere::max_relative_overlap(store_, domain_, overlap_cells_);
    tally_.max_overlap = std::max(tally_.max_overlap, *step_overlap_);
  }
  record_totals(step_collisions, boundary_collisions);
}

void ParticleSystem::record_totals(long step_collisions, long boundary_collisions) {
  const double k = kinetic_energy();
  const Vec3 p = linear_momentum(), l = angular_momentum();
  const long step = static_cast<long>(temperature_history_.size());
  totals_csv_ += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{}\n", step, tally_.time, k,
                             p.x(), p.y(), p.z(), l.x(), l.y(), l.z(), step_collisions,
                             boundary_collisions, tally_.wall_hits, tally_.crossings);
  temperature_history_.emplace_back(tally_.time, translational_energy());
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
      ++tally_.removed;
      continue;
    }
    domain_.wrap(store_.position[i]);
    ++i;
  }
}

std::optional<std::string> ParticleSystem::check_state() const {
  if (const std::size_t i = store_.first_non_finite(); i < store_.size()) {
    const Vec3& x = store_.position[i];
    return fmt::format("non-finite state of particle id {} (position ({}, {}, {}), velocity "
                       "({}, {}, {}))",
                       store_.id[i], x.x(), x.y(), x.z(), store_.velocity[i].x(),
                       store_.velocity[i].y(), store_.velocity[i].z());
  }
  if (mode_ != CollisionMode::kNone) {
    // The step has just measured it on this same state (check_state follows advance).
    const double overlap =
        step_overlap_ ? *step_overlap_ : hardsphere::max_relative_overlap(store_, domain_, overlap_cells_);
    if (overlap > overlap_tolerance_)
      return fmt::format("particles overlap by {:.3g} of a radius (tolerance {:.3g})", overlap,
                         overlap_tolerance_);
  }
  return std::nullopt;
}

std::int64_t ParticleSystem::global_count() const {
  return replicated_ ? static_cast<std::int64_t>(store_.size())
                     : mpi::sum(static_cast<std::int64_t>(store_.size()));
}

double ParticleSystem::kinetic_energy() const {
  double e = 0;
  for (std::size_t i = 0; i < store_.size(); ++i)
    e += 0.5 * store_.mass[i] * store_.velocity[i].squaredNorm() +
         0.5 * store_.inertia[i] * store_.angular_velocity[i].squaredNorm();
  return total(e);
}

double ParticleSystem::translational_energy() const {
  double e = 0;
  for (std::size_t i = 0; i < store_.size(); ++i)
    e += 0.5 * store_.mass[i] * store_.velocity[i].squaredNorm();
  return total(e);
}

Vec3 ParticleSystem::linear_momentum() const {
  Vec3 p = Vec3::Zero();
  for (std::size_t i = 0; i < store_.size(); ++i) p += store_.mass[i] * store_.velocity[i];
  return {total(p.x()), total(p.y()), total(p.z())};
}

Vec3 ParticleSystem::angular_momentum() const {
  Vec3 l = Vec3::Zero();
  for (std::size_t i = 0; i < store_.size(); ++i)
    l += store_.inertia[i] * store_.angular_velocity[i] +
         store_.position[i].cross(store_.mass[i] * store_.velocity[i]);
  return {total(l.x()), total(l.y()), total(l.z())};
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

/// `local_rows`: false on ranks that hold a replica written by rank 0 (collective all the same).
void write_store(io::Hdf5Group& g, const ParticleStore& s, bool full, bool local_rows) {
  const auto order = local_rows ? id_order(s) : std::vector<std::size_t>{};
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
  const bool local_rows = !replicated_ || mpi::is_root();
  {
    auto g = file.root().create_group("particles");
    write_store(g, store_, false, local_rows);
    g.set_attribute("count", global_count());
    g.set_attribute("dimension", static_cast<std::int64_t>(domain_.dimension));
  }
  // The per-step totals (and the collision log) as CSV beside the HDF5 files.
  if (mpi::is_root()) {
    const auto folder = file.path().parent_path();
    io::write_text_atomically(folder / "totals.csv", totals_csv_);
    if (record_collisions_) io::write_text_atomically(folder / "collisions.csv", collisions_csv_);
  }
  const long n = static_cast<long>(global_count());
  const std::string base = file_name + ":/particles/";
  std::vector<io::XdmfArray> arrays = {{"radius", base + "radius", 1},
                                       {"velocity", base + "velocity", 3},
                                       {"angular_velocity", base + "angular_velocity", 3},
                                       {"id", base + "id", 1, "Int", 8}};
  return {{"particles", io::polyvertex_grid("particles", n, base + "position", arrays)}};
}

void ParticleSystem::write_checkpoint(io::Hdf5Group& group) {
  auto g = group.create_group("particles");
  write_store(g, store_, true, !replicated_ || mpi::is_root());
  g.set_attribute("removed", tally_.removed);
  g.set_attribute("collisions", tally_.collisions);
  g.set_attribute("wall_hits", tally_.wall_hits);
  g.set_attribute("crossings", tally_.crossings);
  g.set_attribute("elapsed", tally_.time);
  g.set_attribute("max_overlap", tally_.max_overlap);
  g.set_attribute("measured_collisions", tally_.measured_collisions);
  g.set_attribute("measured_time", tally_.measured_time);
  g.set_attribute("initial_count", initial_count_);
  g.set_attribute("initial_energy", initial_energy_);
  g.set_attribute("initial_translational_energy", initial_translational_energy_);
  for (int k = 0; k < 3; ++k)
    g.set_attribute(fmt::format("initial_momentum_{}", k), initial_momentum_[k]);
  g.write_text("totals_csv", totals_csv_);
  g.write_text("collisions_csv", collisions_csv_);
  write_event_schedule(g);
  std::vector<double> history;
  for (const auto& [t, k] : temperature_history_) history.insert(history.end(), {t, k});
  g.write_rows("temperature_history", history.data(),
               mpi::is_root() ? temperature_history_.size() : 0, 2);
}

void ParticleSystem::write_event_schedule(io::Hdf5Group& particles) const {
  // Only a schedule of the state being written, and in the order the store is written (by id;
  // the event-driven store never reorders, its ids ascending from placement).
  const bool in_id_order = std::is_sorted(store_.id.begin(), store_.id.end());
  const bool current = mode_ == CollisionMode::kEventDriven && events_continue_ && in_id_order;
  particles.set_attribute("event_schedule", static_cast<std::int64_t>(current ? 1 : 0));
  if (!current) return;
  const hardsphere::EventSchedule s = event_driven_->schedule();
  auto g = particles.create_group("event_schedule");
  g.set_attribute("time", s.time);
  const bool local_rows = !replicated_ || mpi::is_root();  // replicated: rank 0 writes
  auto write = [&](const char* name, const auto& values, std::size_t per_row) {
    g.write_rows(name, values.data(), local_rows ? values.size() / per_row : 0, per_row);
  };
  for (const auto& column : hardsphere::kEventScheduleReals) write(column.name, s.*column.values, column.per_particle);
  for (const auto& column : hardsphere::kEventScheduleIntegers) write(column.name, s.*column.values, column.per_particle);
  write("head", s.head, 1);
}

void ParticleSystem::read_event_schedule(const io::Hdf5Group& particles) {
  if (!particles.has_attribute("event_schedule") || particles.integer_attribute("event_schedule") == 0) return;
  const auto g = particles.open_group("event_schedule");
  hardsphere::EventSchedule s;
  s.time = g.real_attribute("time");
  auto rows = [&](const char* name) { return g.shape(name)[0]; };  // every rank reads all
  for (const auto& column : hardsphere::kEventScheduleReals)
    s.*column.values = g.read_rows_real(column.name, 0, rows(column.name));
  for (const auto& column : hardsphere::kEventScheduleIntegers)
    s.*column.values = g.read_rows_integer(column.name, 0, rows(column.name));
  s.head = g.read_rows_integer("head", 0, rows("head"));
  resume_schedule_ = std::move(s);
}

void ParticleSystem::read_checkpoint(const io::Hdf5Group& group) {
  const auto g = group.open_group("particles");
  const auto n = static_cast<std::int64_t>(g.shape("id")[0]);
  const std::int64_t rank = mpi::rank(), ranks = mpi::size();
  const auto first = replicated_ ? 0 : static_cast<std::uint64_t>(n * rank / ranks);
  const auto count = replicated_ ? static_cast<std::uint64_t>(n)
                                 : static_cast<std::uint64_t>(n * (rank + 1) / ranks) - first;
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
  step_overlap_.reset();
  events_continue_ = false;
  resume_schedule_.reset();
  for (std::size_t i = 0; i < count; ++i) {
    auto v3 = [&](const std::vector<double>& a) {
      return Vec3(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
    };
    store_.add(ids[i], v3(x), v3(v), v3(w), r[i], m[i], inertia[i],
               static_cast<std::uint32_t>(flags[i]));
    store_.force.back() = v3(f);
    store_.torque.back() = v3(t);
  }
  tally_.removed = g.integer_attribute("removed");
  tally_.collisions = g.integer_attribute("collisions");
  tally_.wall_hits = g.integer_attribute("wall_hits");
  tally_.crossings = g.integer_attribute("crossings");
  tally_.time = g.real_attribute("elapsed");
  tally_.max_overlap = g.real_attribute("max_overlap");
  tally_.measured_collisions = g.integer_attribute("measured_collisions");
  tally_.measured_time = g.real_attribute("measured_time");
  initial_count_ = g.integer_attribute("initial_count");
  initial_energy_ = g.real_attribute("initial_energy");
  initial_translational_energy_ = g.real_attribute("initial_translational_energy");
  for (int k = 0; k < 3; ++k)
    initial_momentum_[k] = g.real_attribute(fmt::format("initial_momentum_{}", k));
  totals_csv_ = g.read_text("totals_csv");
  collisions_csv_ = g.read_text("collisions_csv");
  read_event_schedule(g);
  const auto rows = g.shape("temperature_history")[0];
  const auto history = g.read_rows_real("temperature_history", 0, rows);
  temperature_history_.clear();
  for (std::size_t i = 0; i < rows; ++i)
    temperature_history_.emplace_back(history[2 * i], history[2 * i + 1]);
}

void ParticleSystem::report(io::Json& counts, io::Json& metrics, double step_wall_s,
                            long steps) const {
  const std::int64_t n = global_count();
  const std::int64_t removed = replicated_ ? tally_.removed : mpi::sum(tally_.removed);
  counts.set("particles", n);
  counts.set("particles_removed", removed);
  const double energy = kinetic_energy();
  metrics.set("kinetic_energy", energy);
  // Drifts are only defined for a closed system: no body force doing work, nobody leaving.
  const bool closed = gravity_.isZero() && removed == 0;
  bool walls = false;
  for (int k = 0; k < domain_.dimension; ++k)
    walls = walls || domain_.face[static_cast<std::size_t>(k)][0] == FaceKind::kWall;
  if (closed) {
    if (!walls) metrics.set("momentum_abs_drift", (linear_momentum() - initial_momentum_).norm());
    metrics.set("energy_rel_drift",
                initial_energy_ > 0 ? (energy - initial_energy_) / initial_energy_ : 0.0);
  }
  const double particle_steps = static_cast<double>(n) * static_cast<double>(steps);
  metrics.set("particle_steps_per_s", step_wall_s > 0 ? particle_steps / step_wall_s : 0.0);
  metrics.set("bytes_per_particle", static_cast<double>(ParticleStore::bytes_per_particle()));
  if (mode_ == CollisionMode::kNone) return;

  counts.set("collisions", tally_.collisions);
  counts.set("wall_hits", tally_.wall_hits);
  counts.set("periodic_crossings", tally_.crossings);
  metrics.set("collisions", static_cast<double>(tally_.collisions));
  metrics.set("max_overlap_over_radius", tally_.max_overlap);
  metrics.set("collisions_per_s",
              step_wall_s > 0 ? static_cast<double>(tally_.collisions + tally_.wall_hits) / step_wall_s
                              : 0.0);
  if (tally_.measured_time > 0 && n > 0)
    metrics.set("collision_frequency", 2.0 * static_cast<double>(tally_.measured_collisions) /
                                           (static_cast<double>(n) * tally_.measured_time));

  // Enskog's collision frequency for a monodisperse periodic gas (reference README):
  // Gamma = 4 n sigma^2 sqrt(pi kT/m) g(sigma), g = (1 - eta/2)/(1 - eta)^3 (Carnahan-Starling),
  // with kT/m = 2 K_trans / (3 N m) and K_trans averaged over the run (constant when elastic).
  bool monodisperse = n > 0 && domain_.dimension == 3 && gravity_.isZero() && !walls;
  for (std::size_t i = 1; i < store_.size() && monodisperse; ++i)
    monodisperse = store_.radius[i] == store_.radius[0] && store_.mass[i] == store_.mass[0];
  for (int k = 0; k < 3; ++k) monodisperse = monodisperse && domain_.periodic(k);
  if (monodisperse && !temperature_history_.empty()) {
    const double sigma = 2 * store_.radius[0], mass = store_.mass[0];
    const double volume = domain_.length().prod();
    const double number_density = static_cast<double>(n) / volume;
    const double eta = number_density * std::numbers::pi / 6 * sigma * sigma * sigma;
    const double g_contact = (1 - eta / 2) / std::pow(1 - eta, 3);
    double mean_k = 0, samples = 0;
    for (const auto& [t, k] : temperature_history_)
      if (t > statistics_start_ * (1 - 1e-12)) {
        mean_k += k;
        samples += 1;
      }
    mean_k = samples > 0 ? mean_k / samples : temperature_history_.back().second;
    const double kT_over_m = 2 * mean_k / (3 * static_cast<double>(n) * mass);
    metrics.set("packing_fraction", eta);
    // Enskog applies to an equilibrium (elastic) gas only.
    if (law_.restitution == 1 && law_.model == hardsphere::RestitutionModel::kConstant)
      metrics.set("collision_frequency_enskog", 4 * number_density * sigma * sigma *
                                                    std::sqrt(std::numbers::pi * kT_over_m) *
                                                    g_contact);

    // Haff's law for a cooling gas: T(t) = T0 / (1 + t/t0)^2, t0 = 6 / ((1 - e^2) omega0),
    // omega0 = the measured collision frequency over the first steps (temperature barely
    // changed yet). Compared at every step while the run lasts.
    const double e = law_.restitution;
    if (e < 1 && law_.friction == 0 && law_.model == hardsphere::RestitutionModel::kConstant &&
        temperature_history_.size() > 20) {
      const auto& h = temperature_history_;
      // omega0 from the collision rate of the first 5% of the recorded steps (at least 10).
      const std::size_t window = std::max<std::size_t>(10, h.size() / 20);
      std::int64_t early = 0;
      std::istringstream lines(totals_csv_);
      std::string line;
      std::getline(lines, line);  // header
      for (std::size_t row = 0; std::getline(lines, line) && row <= window; ++row) {
        if (row == 0) continue;
        std::istringstream cells(line);
        std::string cell;
        for (int c = 0; c < 10 && std::getline(cells, cell, ','); ++c)
          if (c == 9) early += std::stoll(cell);
      }
      const double omega0 =
          2.0 * static_cast<double>(early) / (static_cast<double>(n) * h[window].first);
      const double t0 = 6.0 / ((1 - e * e) * omega0);
      double worst = 0;
      for (const auto& [t, k] : h) {
        const double haff = h.front().second / std::pow(1 + t / t0, 2);
        worst = std::max(worst, std::abs(k / haff - 1));
      }
      metrics.set("haff_t0", t0);
      metrics.set("haff_max_rel_dev", worst);
      metrics.set("temperature_final_over_initial", h.back().second / h.front().second);
    }
  }
}

std::size_t ParticleSystem::memory_bytes() const {
  // The state and its last-good copy.
  return 2 * store_.size() * ParticleStore::bytes_per_particle();
}

std::string ParticleSystem::progress_note() const {
  if (mode_ == CollisionMode::kNone) return fmt::format("N {}", store_.size());
  return fmt::format("N {}  collisions {}", store_.size(), tally_.collisions);
}

}  // namespace grainwave::particles
