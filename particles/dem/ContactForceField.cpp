#include "particles/dem/ContactForceField.hpp"

#include "core/Error.hpp"
#include "particles/dem/CoulombSpring.hpp"
#include "particles/dem/HertzNormal.hpp"
#include "particles/dem/LinearSpringDashpot.hpp"
#include "particles/dem/Mindlin.hpp"
#include "particles/dem/StaticFriction.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace grainwave::particles::dem {

ContactForceField::ContactForceField(ContactModel model, const Domain& domain,
                                     ContactForceSettings settings)
    : model_(std::move(model)), domain_(domain), settings_(std::move(settings)) {
  if (!model_.normal || !model_.tangential)
    throw InputError({"contact model", 0}, "law", "needs both a normal and a tangential law");
  plane_walls_ = walls_from_domain(domain_);
}

template <bool kWithEffectiveRadius>
[[gnu::always_inline]] inline bool ContactForceField::particle_contact(const ParticleStore& store, std::uint32_t i, std::uint32_t j,
                                         const Vec3& d, double distance2, Contact& c) const {
  const double inverse_mass_sum = inverse_mass_[i] + inverse_mass_[j];
  if (inverse_mass_sum == 0.0 || distance2 == 0.0) return false;  // fixed pairs never interact
  if (has_ghosts_ && i >= owned_end_ && j >= owned_end_) return false;  // another rank's pair
  const double distance = std::sqrt(distance2);
  const double ri = store.radius[i], rj = store.radius[j];
  c.i = i;
  c.partner = j;
  c.is_wall = false;
  c.normal = d * (1.0 / distance);
  c.overlap = ri + rj - distance;
  const Vec3 spin = ri * store.angular_velocity[i] + rj * store.angular_velocity[j];
  c.relative_velocity = (store.velocity[j] - store.velocity[i]) - spin.cross(c.normal);
  c.effective_mass = 1.0 / inverse_mass_sum;
  c.effective_radius = kWithEffectiveRadius ? effective_radius(ri, rj) : std::numeric_limits<double>::quiet_NaN();
  c.history = nullptr;
  return true;
}

void ContactForceField::wall_contact(const ParticleStore& store, std::size_t i, std::size_t wall_index,
                                     const Vec3& wall_velocity, const Vec3& normal, double overlap,
                                     Contact& c) const {
  c.i = static_cast<std::uint32_t>(i);
  c.partner = static_cast<std::uint32_t>(wall_index);
  c.list_index = Contact::kNotListed;
  c.is_wall = true;
  c.normal = normal;
  c.overlap = overlap;
  c.relative_velocity = (wall_velocity - store.velocity[i]) -
                        (store.radius[i] * store.angular_velocity[i]).cross(normal);
  c.effective_mass = store.mass[i];
  c.effective_radius = store.radius[i];
  c.history = nullptr;
}

void ContactForceField::external_forces(const ParticleStore& store) {
  const std::size_t n = store.size();
  force_.resize(n);
  torque_.resize(n);
  for (std::size_t i = owned_end_; i < n; ++i) {  // ghosts: their owner sums their forces
    force_[i].setZero();
    torque_[i].setZero();
  }
  for (std::size_t i = 0; i < owned_end_; ++i) {
    force_[i] = store.force[i] + store.mass[i] * settings_.gravity;
    torque_[i] = store.torque[i];
    for (const RecyclingDragZone& zone : settings_.drag_zones)
      if (zone.contains(store.position[i]))
        force_[i] += recycling_drag(zone.coefficient_per_mass, store.mass[i], store.velocity[i]);
  }
}

[[gnu::always_inline]] inline void ContactForceField::apply(const ParticleStore& store, const Contact& c) {
  const Vec3 on_i = c.tangential_force - c.normal_force * c.normal;
  const Vec3 lever_cross_ft = c.normal.cross(c.tangential_force);
  force_[c.i] += on_i;
  torque_[c.i] += store.radius[c.i] * lever_cross_ft;
  if (!c.is_wall) {
    force_[c.partner] -= on_i;
    torque_[c.partner] += store.radius[c.partner] * lever_cross_ft;
  }
}

[[gnu::always_inline]] inline void ContactForceField::note_depth(const ParticleStore& store, const Contact& c) {
  // A pair of an owned particle and a ghost is found on both ranks: the rank owning the smaller
  // id counts it, so the counts of all ranks add up to the serial count.
  if (!has_ghosts_ || c.is_wall || (c.i < owned_end_ && c.partner < owned_end_)) {
    ++contact_count_;
  } else {
    const bool i_owned = c.i < owned_end_;
    const std::int64_t owned_id = store.id[i_owned ? c.i : c.partner];
    const std::int64_t ghost_id = store.id[i_owned ? c.partner : c.i];
    if (owned_id < ghost_id) ++contact_count_;
  }
  // Compared without a division per contact (the quotient is formed only for a new deepest).
  const double r = c.is_wall ? store.radius[c.i] : std::min(store.radius[c.i], store.radius[c.partner]);
  if (c.overlap > deepest_.overlap_over_radius * r) {
    const double depth = c.overlap / r;
    if (depth > deepest_.overlap_over_radius)
      deepest_ = DeepestContact{depth, c.i, c.partner, c.is_wall, store.id[c.i]};
  }
}

// Flattened: the pair test, the contact's geometry and the caller's force law become one loop
// body, so the contact's fields stay in registers and consecutive contacts' long-latency
// chains (square roots, divisions) overlap (12 % fewer instructions for the dense bed). Not
// under AddressSanitizer, whose instrumentation of the flattened bodies takes the compiler
// many minutes; the arithmetic, and so every result, is the same either way.
#if defined(__SANITIZE_ADDRESS__)
#define GRAINWAVE_FLATTEN
#else
#define GRAINWAVE_FLATTEN [[gnu::flatten]]
#endif
template <bool kWithEffectiveRadius, class ContactFunction>
GRAINWAVE_FLATTEN void ContactForceField::for_each_contact(const ParticleStore& store, ContactFunction&& f) {
  Contact c;
  auto pair = [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2,
                  std::uint32_t list_index = Contact::kNotListed) {
    if (!particle_contact<kWithEffectiveRadius>(store, i, j, d, distance2, c)) return;
    c.list_index = list_index;
    f(c);
  };
  if (use_list_) verlet_.for_each_touching_pair(store, pair);
  else cells_.for_each_touching_pair(pair);
  for_each_wall_contact(store, c, f);
}

template <class ContactFunction>
void ContactForceField::for_each_wall_contact(const ParticleStore& store, Contact& c, ContactFunction&& f) {
  const std::size_t n = owned_end_;  // walls act on owned particles only
  for (std::size_t w = 0; w < plane_walls_.size(); ++w) {
    const PlaneWall& wall = plane_walls_[w];
    if (!wall.enabled) continue;
    for (std::size_t i = 0; i < n; ++i) {
      if (store.is_fixed(i)) continue;
      const double overlap = store.radius[i] - wall.distance(store.position[i]);
      if (overlap <= 0.0) continue;
      wall_contact(store, i, w, wall.velocity, -wall.normal, overlap, c);
      f(c);
    }
  }
  for (std::size_t w = 0; w < finite_walls_.size(); ++w) {
    const FiniteWall& wall = finite_walls_[w];
    if (!wall.enabled) continue;
    for (std::size_t i = 0; i < n; ++i) {
      if (store.is_fixed(i)) continue;
      const Vec3 p = wall.closest_point(store.position[i]);
      const Vec3 d = p - store.position[i];
      const double distance2 = d.squaredNorm();
      const double r = store.radius[i];
      if (distance2 >= r * r || distance2 == 0.0) continue;
      const double distance = std::sqrt(distance2);
      wall_contact(store, i, plane_walls_.size() + w, wall.velocity, d / distance, r - distance, c);
      f(c);
    }
  }
}

void ContactForceField::touch_history(const ParticleStore& store, Contact& c) {
  if (!c.is_wall && store.id[c.i] > store.id[c.partner]) {
    // Canonical orientation (see the header): the same contact seen from the other side.
    std::swap(c.i, c.partner);
    c.normal = -c.normal;
    c.relative_velocity = -c.relative_velocity;
  }
  const std::int64_t other = c.is_wall ? ContactHistory::wall_key(c.partner) : store.id[c.partner];
  c.history = c.list_index < history_hints_.size()
                  ? history_.touch(store.id[c.i], other, history_hints_[c.list_index])
                  : history_.touch(store.id[c.i], other);
}

template <class Normal, class Tangential>
void ContactForceField::evaluate_fused(const ParticleStore& store, const Normal& normal,
                                       const Tangential& tangential, HistoryStage stage, double dt) {
  // The batched path adds the external forces first and then the contacts in list order, which
  // is the order they are found in: the same sums in the same order here. A history law's
  // entry is looked up and advanced where the contact is found; each contact uses its entry
  // at once, so room can be made between contacts (entries move, none is held).
  constexpr bool keeps_history = !std::is_same_v<Tangential, StaticFriction>;
  if constexpr (keeps_history) history_.prepare();
  external_forces(store);
  auto contact_forces = [&](Contact& c) {
    if constexpr (keeps_history) {
      if (history_.nearly_full()) history_.make_room();
      touch_history(store, c);
    }
    c.normal_force = normal.force(c);
    if constexpr (keeps_history) advance_history(tangential, c, stage, dt);
    else c.tangential_force = tangential.force(c);
    note_depth(store, c);
    apply(store, c);
  };
  if constexpr (std::is_same_v<Normal, LinearSpringDashpot> && std::is_same_v<Tangential, StaticFriction>) {
    if (use_list_ && settings_.batched) {
      add_listed_pairs_linear_static(store, normal, tangential);
      Contact c;
      for_each_wall_contact(store, c, contact_forces);
      return;
    }
  }
  constexpr bool reads_radius = Normal::kReadsEffectiveRadius || Tangential::kReadsEffectiveRadius;
  for_each_contact<reads_radius>(store, contact_forces);
}

namespace {

// Two contacts at a time in the two lanes of a vector (GCC/Clang vector extensions; SSE2 on
// x86-64). The element-wise operators round each lane as the scalar operation would, and nothing
// is contracted or reassociated, so a lane holds exactly what the contact-by-contact code
// computes. Four lanes (split into two SSE2 halves by the compiler) measured 25% slower.
constexpr int kLanes = 2;
using Lanes = double __attribute__((vector_size(kLanes * sizeof(double))));

[[gnu::always_inline]] inline Lanes lanes_sqrt(Lanes a) {
#if defined(__SSE2__)
  return _mm_sqrt_pd(a);
#else
  return Lanes{std::sqrt(a[0]), std::sqrt(a[1])};
#endif
}
/// std::max(a, b) per lane (a when a < b is false, NaN included).
[[gnu::always_inline]] inline Lanes lanes_max(Lanes a, Lanes b) { return a < b ? b : a; }
[[gnu::always_inline]] inline Lanes lanes_load(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::always_inline]] inline void lanes_store(double* p, Lanes v) { std::memcpy(p, &v, sizeof v); }
/// Component k of the Vec3s at slots s[0], s[1].
[[gnu::always_inline]] inline Lanes gather(const Vec3* v, const std::uint32_t* s, int k) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r[l] = v[s[l]][k];
  return r;
}
[[gnu::always_inline]] inline Lanes gather(const double* v, const std::uint32_t* s) {
  Lanes r;
  for (int l = 0; l < kLanes; ++l) r[l] = v[s[l]];
  return r;
}

/// Touching pairs of one batch, then their forces (structure of arrays).
struct PairBatch {
  static constexpr int kSize = 64;  // a multiple of kLanes
  int count = 0;
  std::uint32_t i[kSize], j[kSize];
  alignas(64) double dx[kSize], dy[kSize], dz[kSize], distance2[kSize];
  // Out: the force on i (on_i), n × F_t (lever), the overlap.
  alignas(64) double fx[kSize], fy[kSize], fz[kSize], lx[kSize], ly[kSize], lz[kSize], overlap[kSize];
};

}  // namespace

void ContactForceField::add_listed_pairs_linear_static(const ParticleStore& store, const LinearSpringDashpot& normal,
                                                       const StaticFriction& friction) {
  const double stiffness = normal.stiffness(), damping_factor = normal.damping_factor();
  const double mu = friction.friction(), regularization_speed = friction.regularization_speed();
  const Vec3* velocity = store.velocity.data();
  const Vec3* angular_velocity = store.angular_velocity.data();
  const double* radius = store.radius.data();
  const double* inverse_mass = inverse_mass_.data();
  PairBatch b;
  // Each lane as particle_contact, LinearSpringDashpot::force, StaticFriction::force and apply
  // compute it, operation for operation (Eigen's cross, dot and norm in their coefficient order).
  auto compute = [&](int l) {
    const std::uint32_t* I = b.i + l;
    const std::uint32_t* J = b.j + l;
    const Lanes distance = lanes_sqrt(lanes_load(b.distance2 + l));
    const Lanes inverse_distance = 1.0 / distance;
    const Lanes nx = lanes_load(b.dx + l) * inverse_distance, ny = lanes_load(b.dy + l) * inverse_distance,
                nz = lanes_load(b.dz + l) * inverse_distance;
    const Lanes ri = gather(radius, I), rj = gather(radius, J);
    const Lanes overlap = ri + rj - distance;
    const Lanes sx = ri * gather(angular_velocity, I, 0) + rj * gather(angular_velocity, J, 0);
    const Lanes sy = ri * gather(angular_velocity, I, 1) + rj * gather(angular_velocity, J, 1);
    const Lanes sz = ri * gather(angular_velocity, I, 2) + rj * gather(angular_velocity, J, 2);
    const Lanes vx = (gather(velocity, J, 0) - gather(velocity, I, 0)) - (sy * nz - sz * ny);
    const Lanes vy = (gather(velocity, J, 1) - gather(velocity, I, 1)) - (sz * nx - sx * nz);
    const Lanes vz = (gather(velocity, J, 2) - gather(velocity, I, 2)) - (sx * ny - sy * nx);
    const Lanes effective_mass = 1.0 / (gather(inverse_mass, I) + gather(inverse_mass, J));
    const Lanes normal_speed = vx * nx + vy * ny + vz * nz;
    const Lanes eta = damping_factor * lanes_sqrt(effective_mass * stiffness);
    const Lanes normal_force = stiffness * overlap - eta * normal_speed;
    const Lanes tx = vx - normal_speed * nx, ty = vy - normal_speed * ny, tz = vz - normal_speed * nz;
    const Lanes speed = lanes_sqrt(tx * tx + ty * ty + tz * tz);
    const Lanes magnitude = mu * lanes_max(normal_force, Lanes{} + 0.0);
    const Lanes scale = magnitude / lanes_max(speed, Lanes{} + regularization_speed);
    const auto sliding = (speed != 0.0) & (magnitude != 0.0);  // else F_t = 0 exactly
    const Lanes zero{};
    const Lanes ftx = sliding ? scale * tx : zero, fty = sliding ? scale * ty : zero,
                ftz = sliding ? scale * tz : zero;
    lanes_store(b.fx + l, ftx - normal_force * nx);
    lanes_store(b.fy + l, fty - normal_force * ny);
    lanes_store(b.fz + l, ftz - normal_force * nz);
    lanes_store(b.lx + l, ny * ftz - nz * fty);
    lanes_store(b.ly + l, nz * ftx - nx * ftz);
    lanes_store(b.lz + l, nx * fty - ny * ftx);
    lanes_store(b.overlap + l, overlap);
  };
  auto flush = [&] {
    for (int k = b.count; k % kLanes != 0; ++k) {  // pad with a copy of the first contact
      b.i[k] = b.i[0];
      b.j[k] = b.j[0];
      b.dx[k] = b.dx[0];
      b.dy[k] = b.dy[0];
      b.dz[k] = b.dz[0];
      b.distance2[k] = b.distance2[0];
    }
    for (int l = 0; l < b.count; l += kLanes) compute(l);
    Contact c;  // for note_depth
    c.is_wall = false;
    for (int k = 0; k < b.count; ++k) {
      const std::uint32_t i = b.i[k], j = b.j[k];
      const Vec3 on_i(b.fx[k], b.fy[k], b.fz[k]);
      const Vec3 lever(b.lx[k], b.ly[k], b.lz[k]);
      force_[i] += on_i;
      torque_[i] += radius[i] * lever;
      force_[j] -= on_i;
      torque_[j] += radius[j] * lever;
      c.i = i;
      c.partner = j;
      c.overlap = b.overlap[k];
      note_depth(store, c);
    }
    b.count = 0;
  };
  verlet_.for_each_touching_pair(store, [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2,
                                            std::uint32_t) {
    // The pairs particle_contact turns away (the list holds no pair of two ghosts).
    if (inverse_mass[i] + inverse_mass[j] == 0.0 || distance2 == 0.0) return;
    const int k = b.count++;
    b.i[k] = i;
    b.j[k] = j;
    b.dx[k] = d.x();
    b.dy[k] = d.y();
    b.dz[k] = d.z();
    b.distance2[k] = distance2;
    if (b.count == PairBatch::kSize) flush();
  });
  if (b.count > 0) flush();
}

template <class Normal>
bool ContactForceField::try_fused(const ParticleStore& store, const Normal& normal, HistoryStage stage,
                                  double dt) {
  const TangentialLaw* law = model_.tangential.get();
  if (const auto* friction = dynamic_cast<const StaticFriction*>(law)) {
    evaluate_fused(store, normal, *friction, stage, dt);
    return true;
  }
  if (const auto* spring = dynamic_cast<const CoulombSpring*>(law)) {
    evaluate_fused(store, normal, *spring, stage, dt);
    return true;
  }
  if (const auto* mindlin = dynamic_cast<const Mindlin*>(law)) {
    evaluate_fused(store, normal, *mindlin, stage, dt);
    return true;
  }
  return false;
}

void ContactForceField::prepare_slots(const ParticleStore& store) {
  const std::size_t n = store.size();
  inverse_mass_.resize(n);
  for (std::size_t i = 0; i < n; ++i) inverse_mass_[i] = store.inverse_mass(i);
  owned_end_ = store.owned_size();
  has_ghosts_ = owned_end_ < n;
}

void ContactForceField::merge_visit_order(const ParticleStore& store) {
  const std::size_t n = store.size();
  if (has_ghosts_) {
    // Both ranges are in id order (SlabDecomposition keeps them so): merge them by id.
    visit_order_.resize(n);
    std::uint32_t a = 0, b = static_cast<std::uint32_t>(owned_end_);
    const auto owned = static_cast<std::uint32_t>(owned_end_), all = static_cast<std::uint32_t>(n);
    for (std::size_t k = 0; k < n; ++k)
      visit_order_[k] = (b == all || (a < owned && store.id[a] < store.id[b])) ? a++ : b++;
  }
}

double ContactForceField::search_cell_width(const ParticleStore& store, double skin) const {
  double cell_width = settings_.cell_width;
  if (cell_width <= 0.0) {
    double largest = 0.0;
    for (double r : store.radius) largest = std::max(largest, r);
    cell_width = 2.0 * largest;
  }
  return cell_width + skin;
}

long ContactForceField::list_stale_ahead(const ParticleStore& store, std::span<const Vec3> ahead) const {
  return verlet_.stale_ahead(store, store.owned_size(), ahead);
}

void ContactForceField::build_list(const ParticleStore& store) {
  prepare_slots(store);
  merge_visit_order(store);
  const double skin = std::max(settings_.verlet_skin, 0.0);
  verlet_.build(store, domain_, search_cell_width(store, skin), skin, settings_.grid_particles,
                has_ghosts_ ? &visit_order_ : nullptr, owned_end_);
}

void ContactForceField::evaluate(const ParticleStore& store, HistoryStage stage, double dt) {
  const std::size_t n = store.size();
  if (stage != HistoryStage::kCorrect) history_.begin_step();

  contacts_.clear();
  contact_count_ = 0;
  deepest_ = DeepestContact{};
  prepare_slots(store);
  if (n > 0) {
    // A self-managed list would see renewed ghosts at every evaluation: with ghosts, only a
    // caller-managed list stays valid.
    const double skin = std::max(settings_.verlet_skin, 0.0);
    use_list_ = skin > 0.0 && (settings_.verlet_managed || !has_ghosts_);
    if (use_list_ && settings_.verlet_managed) {
      if (verlet_.skin() < 0.0)
        throw std::logic_error("ContactForceField: a managed Verlet list evaluated before build_list");
    } else if (!use_list_) {
      merge_visit_order(store);
      cells_.build(store, domain_, search_cell_width(store, 0.0), settings_.grid_particles,
                   has_ghosts_ ? &visit_order_ : nullptr);
    } else if (verlet_.stale(store, domain_)) {
      verlet_.build(store, domain_, search_cell_width(store, skin), skin);
    }
    if (use_list_ && model_.tangential->needs_history() && history_hints_build_ != verlet_.builds()) {
      history_hints_.assign(verlet_.pair_count(), Contact::kNotListed);  // no hint: probe
      history_hints_build_ = verlet_.builds();
    }
    if (settings_.fused) {
      if (const auto* law = dynamic_cast<const LinearSpringDashpot*>(model_.normal.get());
          law && try_fused(store, *law, stage, dt))
        return;
      if (const auto* law = dynamic_cast<const HertzNormal*>(model_.normal.get());
          law && try_fused(store, *law, stage, dt))
        return;
    }
    for_each_contact(store, [&](const Contact& c) { contacts_.push_back(c); });
  }

  if (model_.tangential->needs_history()) {
    history_.prepare();
    for (std::size_t k = 0; k < contacts_.size(); ++k) {
      if (history_.nearly_full()) {
        history_.make_room();  // entries moved: look up the contacts done so far again
        k = 0;
      }
      touch_history(store, contacts_[k]);
    }
  }
  model_.normal->evaluate(contacts_);
  model_.tangential->evaluate(contacts_, stage, dt);

  external_forces(store);
  for (const Contact& c : contacts_) {
    note_depth(store, c);
    apply(store, c);
  }
}

}  // namespace grainwave::particles::dem
