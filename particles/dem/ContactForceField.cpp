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
  c.history = touch_listed_history(store.id[c.i], other, c.list_index);
}

ContactHistoryEntry* ContactForceField::touch_listed_history(std::int64_t a, std::int64_t b, std::uint32_t list_index) {
  return list_index < history_.pinned_count() ? history_.touch_pinned(list_index, a, b) : history_.touch(a, b);
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

/// Three components, one contact per lane.
struct Lanes3 {
  Lanes x, y, z;
};
[[gnu::always_inline]] inline Lanes dot(const Lanes3& a, const Lanes3& b) {  // Eigen's order
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
[[gnu::always_inline]] inline Lanes3 cross(const Lanes3& a, const Lanes3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
[[gnu::always_inline]] inline Lanes3 scaled(Lanes s, const Lanes3& a) { return {s * a.x, s * a.y, s * a.z}; }
[[gnu::always_inline]] inline Lanes3 minus(const Lanes3& a, const Lanes3& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
/// Per lane, `when` ? a : b.
template <class Mask>
[[gnu::always_inline]] inline Lanes3 select(Mask when, const Lanes3& a, const Lanes3& b) {
  return {when ? a.x : b.x, when ? a.y : b.y, when ? a.z : b.z};
}
/// rotate_into_plane per lane (its branches as selections).
[[gnu::always_inline]] inline Lanes3 lanes_rotate_into_plane(const Lanes3& v, const Lanes3& normal) {
  const Lanes length2 = dot(v, v);
  const Lanes3 projected = minus(v, scaled(dot(v, normal), normal));
  const Lanes projected2 = dot(projected, projected);
  const Lanes3 rotated = scaled(lanes_sqrt(length2 / projected2), projected);
  const Lanes zero{};
  return select(length2 == 0.0, v, select(projected2 <= 1e-24 * length2, Lanes3{zero, zero, zero}, rotated));
}

/// Touching pairs of one batch, then their forces (structure of arrays).
struct PairBatch {
  static constexpr int kSize = 64;  // a multiple of kLanes
  int count = 0;
  std::uint32_t i[kSize], j[kSize];  // as listed
  alignas(64) double dx[kSize], dy[kSize], dz[kSize], distance2[kSize];
  // History laws: -1 where the canonical orientation (touch_history) reverses the listed pair,
  // else +1; and the pair's history entry.
  alignas(64) double orientation[kSize];
  ContactHistoryEntry* entry[kSize];
  ContactHistoryEntry pad_entry;  ///< written by the lane that pads an odd batch (then unused)
  // Out: the force on i (on_i), n × F_t (lever), the overlap; i and j of the oriented contact.
  alignas(64) double fx[kSize], fy[kSize], fz[kSize], lx[kSize], ly[kSize], lz[kSize], overlap[kSize];
};

/// What the lanes read of the store and the normal law.
struct LaneInputs {
  const Vec3* velocity;
  const Vec3* angular_velocity;
  const double* radius;
  const double* inverse_mass;
  double stiffness, damping_factor;
};

/// A lane pair's contact as particle_contact and LinearSpringDashpot::force compute it (in the
/// listed orientation), operation for operation (Eigen's cross, dot and norm in their
/// coefficient order).
struct LaneContact {
  Lanes3 normal, relative_velocity;
  Lanes overlap, effective_mass, normal_speed, normal_force;
};
[[gnu::always_inline]] inline LaneContact lane_contact(const PairBatch& b, int l, const LaneInputs& in) {
  const std::uint32_t* I = b.i + l;
  const std::uint32_t* J = b.j + l;
  LaneContact c;
  const Lanes distance = lanes_sqrt(lanes_load(b.distance2 + l));
  const Lanes inverse_distance = 1.0 / distance;
  c.normal = {lanes_load(b.dx + l) * inverse_distance, lanes_load(b.dy + l) * inverse_distance,
              lanes_load(b.dz + l) * inverse_distance};
  const Lanes ri = gather(in.radius, I), rj = gather(in.radius, J);
  c.overlap = ri + rj - distance;
  const Lanes3 spin{ri * gather(in.angular_velocity, I, 0) + rj * gather(in.angular_velocity, J, 0),
                    ri * gather(in.angular_velocity, I, 1) + rj * gather(in.angular_velocity, J, 1),
                    ri * gather(in.angular_velocity, I, 2) + rj * gather(in.angular_velocity, J, 2)};
  const Lanes3 velocity_difference{gather(in.velocity, J, 0) - gather(in.velocity, I, 0),
                                   gather(in.velocity, J, 1) - gather(in.velocity, I, 1),
                                   gather(in.velocity, J, 2) - gather(in.velocity, I, 2)};
  c.relative_velocity = minus(velocity_difference, cross(spin, c.normal));
  c.effective_mass = 1.0 / (gather(in.inverse_mass, I) + gather(in.inverse_mass, J));
  c.normal_speed = dot(c.relative_velocity, c.normal);
  const Lanes eta = in.damping_factor * lanes_sqrt(c.effective_mass * in.stiffness);
  c.normal_force = in.stiffness * c.overlap - eta * c.normal_speed;
  return c;
}

/// The lanes' forces as apply() forms them: on_i = F_t - f_n n and the lever n × F_t.
[[gnu::always_inline]] inline void store_lane_forces(PairBatch& b, int l, const Lanes3& normal, Lanes normal_force,
                                                     const Lanes3& tangential_force, Lanes overlap) {
  const Lanes3 on_i = minus(tangential_force, scaled(normal_force, normal));
  const Lanes3 lever = cross(normal, tangential_force);
  lanes_store(b.fx + l, on_i.x);
  lanes_store(b.fy + l, on_i.y);
  lanes_store(b.fz + l, on_i.z);
  lanes_store(b.lx + l, lever.x);
  lanes_store(b.ly + l, lever.y);
  lanes_store(b.lz + l, lever.z);
  lanes_store(b.overlap + l, overlap);
}

/// StaticFriction::force per lane.
struct StaticFrictionLanes {
  static constexpr bool kKeepsHistory = false;
  double mu, regularization_speed;
  explicit StaticFrictionLanes(const StaticFriction& law)
      : mu(law.friction()), regularization_speed(law.regularization_speed()) {}
  [[gnu::always_inline]] void operator()(PairBatch& b, int l, const LaneContact& c) const {
    const Lanes3 vt = minus(c.relative_velocity, scaled(c.normal_speed, c.normal));
    const Lanes speed = lanes_sqrt(dot(vt, vt));
    const Lanes magnitude = mu * lanes_max(c.normal_force, Lanes{} + 0.0);
    const Lanes scale = magnitude / lanes_max(speed, Lanes{} + regularization_speed);
    const auto sliding = (speed != 0.0) & (magnitude != 0.0);  // else F_t = 0 exactly
    const Lanes zero{};
    store_lane_forces(b, l, c.normal, c.normal_force, select(sliding, scaled(scale, vt), Lanes3{zero, zero, zero}),
                      c.overlap);
  }
};

/// CoulombSpring with advance_history's kSingle stage (velocity Verlet) per lane, in the
/// canonical orientation (touch_history), reading and writing the pairs' history entries.
struct CoulombSpringLanes {
  static constexpr bool kKeepsHistory = true;  // reads b.orientation and b.entry
  double stiffness, friction, damping_factor, half_dt;
  CoulombSpringLanes(const CoulombSpring& law, double dt)
      : stiffness(law.stiffness()), friction(law.friction()), damping_factor(law.damping_factor()),
        half_dt(0.5 * dt) {}
  [[gnu::always_inline]] void operator()(PairBatch& b, int l, const LaneContact& c) const {
    // touch_history's reversal: -n and -v_ji (exact); v_ji · n is unchanged by it, bit for bit.
    const Lanes orientation = lanes_load(b.orientation + l);
    const Lanes3 normal = scaled(orientation, c.normal);
    const Lanes3 relative_velocity = scaled(orientation, c.relative_velocity);
    const Lanes3 vt = minus(relative_velocity, scaled(c.normal_speed, normal));
    ContactHistoryEntry* const e0 = b.entry[l];
    ContactHistoryEntry* const e1 = b.entry[l + 1];
    const Lanes3 displacement{Lanes{e0->displacement.x(), e1->displacement.x()},
                              Lanes{e0->displacement.y(), e1->displacement.y()},
                              Lanes{e0->displacement.z(), e1->displacement.z()}};
    const Lanes3 stage_velocity{Lanes{e0->stage_velocity.x(), e1->stage_velocity.x()},
                                Lanes{e0->stage_velocity.y(), e1->stage_velocity.y()},
                                Lanes{e0->stage_velocity.z(), e1->stage_velocity.z()}};
    using Mask = decltype(Lanes{} < Lanes{});
    const Mask is_new{e0->is_new ? -1 : 0, e1->is_new ? -1 : 0};
    Lanes3 xi = lanes_rotate_into_plane(displacement, normal);
    const Lanes3 vt_old = select(is_new, vt, lanes_rotate_into_plane(stage_velocity, normal));
    const Lanes3 increment{half_dt * (vt_old.x + vt.x), half_dt * (vt_old.y + vt.y), half_dt * (vt_old.z + vt.z)};
    xi = {xi.x + increment.x, xi.y + increment.y, xi.z + increment.z};
    // coulomb_limited_spring
    const Lanes damping = damping_factor * lanes_sqrt(c.effective_mass * stiffness);
    Lanes3 force{stiffness * xi.x + damping * vt.x, stiffness * xi.y + damping * vt.y,
                 stiffness * xi.z + damping * vt.z};
    const Lanes limit = friction * lanes_max(c.normal_force, Lanes{} + 0.0);
    const Lanes force2 = dot(force, force);
    const auto slips = force2 > limit * limit;
    if (slips[0] || slips[1]) [[unlikely]] {  // ~3 % of lane pairs in a dense flowing bed
      const Lanes3 capped = scaled(limit / lanes_sqrt(force2), force);
      const Lanes3 damping_part = scaled(damping, vt);
      const Lanes3 slipped_xi{(capped.x - damping_part.x) / stiffness, (capped.y - damping_part.y) / stiffness,
                              (capped.z - damping_part.z) / stiffness};
      force = select(slips, capped, force);
      xi = select(slips, slipped_xi, xi);
    }
    ContactHistoryEntry* const entries[kLanes] = {e0, e1};
    for (int k = 0; k < kLanes; ++k) {
      entries[k]->displacement = Vec3(xi.x[k], xi.y[k], xi.z[k]);
      entries[k]->stage_velocity = Vec3(vt.x[k], vt.y[k], vt.z[k]);
      entries[k]->is_new = false;
    }
    store_lane_forces(b, l, normal, c.normal_force, force, c.overlap);
  }
};

}  // namespace

template <class TangentialLanes>
void ContactForceField::add_listed_pairs_linear(const ParticleStore& store, const LinearSpringDashpot& normal,
                                                const TangentialLanes& tangential) {
  constexpr bool keeps_history = TangentialLanes::kKeepsHistory;
  const LaneInputs in{store.velocity.data(), store.angular_velocity.data(), store.radius.data(),
                      inverse_mass_.data(), normal.stiffness(), normal.damping_factor()};
  const double* radius = store.radius.data();
  PairBatch b;
  auto flush = [&] {
    for (int k = b.count; k % kLanes != 0; ++k) {  // pad with a copy of the first contact
      b.i[k] = b.i[0];
      b.j[k] = b.j[0];
      b.dx[k] = b.dx[0];
      b.dy[k] = b.dy[0];
      b.dz[k] = b.dz[0];
      b.distance2[k] = b.distance2[0];
      if constexpr (keeps_history) {
        b.orientation[k] = b.orientation[0];
        b.entry[k] = &b.pad_entry;  // not the first contact's: it may have been advanced already
      }
    }
    for (int l = 0; l < b.count; l += kLanes) tangential(b, l, lane_contact(b, l, in));
    Contact c;  // for note_depth
    c.is_wall = false;
    for (int k = 0; k < b.count; ++k) {
      std::uint32_t i = b.i[k], j = b.j[k];
      if constexpr (keeps_history)
        if (b.orientation[k] < 0.0) std::swap(i, j);
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
  const double* inverse_mass = inverse_mass_.data();
  const std::int64_t* id = store.id.data();
  verlet_.for_each_touching_pair(store, [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2,
                                            std::uint32_t list_index) {
    // The pairs particle_contact turns away (the list holds no pair of two ghosts).
    if (inverse_mass[i] + inverse_mass[j] == 0.0 || distance2 == 0.0) return;
    if constexpr (keeps_history) {
      // Entries move when room is made: the batch's entries are used up first.
      if (history_.nearly_full()) {
        if (b.count > 0) flush();
        history_.make_room();
      }
    }
    const int k = b.count++;
    b.i[k] = i;
    b.j[k] = j;
    b.dx[k] = d.x();
    b.dy[k] = d.y();
    b.dz[k] = d.z();
    b.distance2[k] = distance2;
    if constexpr (keeps_history) {
      const bool reversed = id[i] > id[j];
      b.orientation[k] = reversed ? -1.0 : 1.0;
      const std::int64_t first = reversed ? id[j] : id[i], second = reversed ? id[i] : id[j];
      b.entry[k] = touch_listed_history(first, second, list_index);
    }
    if (b.count == PairBatch::kSize) flush();
  });
  if (b.count > 0) flush();
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
  if constexpr (std::is_same_v<Normal, LinearSpringDashpot> &&
                (std::is_same_v<Tangential, StaticFriction> || std::is_same_v<Tangential, CoulombSpring>)) {
    if (use_list_ && settings_.batched && (!keeps_history || stage == HistoryStage::kSingle)) {
      if constexpr (keeps_history) add_listed_pairs_linear(store, normal, CoulombSpringLanes(tangential, dt));
      else add_listed_pairs_linear(store, normal, StaticFrictionLanes(tangential));
      Contact c;
      for_each_wall_contact(store, c, contact_forces);
      return;
    }
  }
  constexpr bool reads_radius = Normal::kReadsEffectiveRadius || Tangential::kReadsEffectiveRadius;
  for_each_contact<reads_radius>(store, contact_forces);
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
    if (use_list_ && model_.tangential->needs_history() &&
        (pinned_build_ != verlet_.builds() || pinned_generation_ != history_.pin_generation())) {
      pin_keys_.resize(verlet_.pair_count());
      for (std::size_t k = 0; k < pin_keys_.size(); ++k) {
        const auto [i, j] = verlet_.pair(k);
        pin_keys_[k] = {store.id[i], store.id[j]};
      }
      history_.pin(pin_keys_);
      pinned_build_ = verlet_.builds();
      pinned_generation_ = history_.pin_generation();
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
