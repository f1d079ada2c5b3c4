#pragma once
// The listed particle pairs of the linear spring–dashpot (002 Eqs 3.5–3.11) with static friction
// (Eq. 3.16) or the Coulomb-limited spring with history (Eqs 3.12, 3.15; velocity Verlet's single
// stage), computed W contacts at a time in the lanes of a vector: the kernel of
// ContactForceField's batched pass (include it from ContactForceField.cpp only).
//
// Bitwise contract. Each lane does the operations of the contact-by-contact code
// (particle_contact, LinearSpringDashpot::force, StaticFriction::force, CoulombSpring's
// advance_history) in the same order: GCC/Clang vector extensions round every lane as the
// scalar operation would, and nothing is contracted (the file that includes this is built with
// -ffp-contract=off) or reassociated. So the lane width changes the speed, never a bit of the
// result: W = 2 is SSE2 (any x86-64), W = 4 AVX2 and W = 8 AVX-512F, chosen at run time
// (lane_width_supported), each in a function compiled for its instruction set.
//
// The wide vectors never cross a function boundary: every helper is always_inline into one of
// the three batch_lane_forces_* entry points. GCC's -Wpsabi note (a 32- or 64-byte vector
// passed by value would change the calling convention without AVX) is therefore moot, and the
// including file is built with -Wno-psabi.
#include "core/KernelClones.hpp"
#include "particles/dem/ContactHistory.hpp"
#include "particles/dem/CoulombSpring.hpp"
#include "particles/dem/StaticFriction.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__)
#define GRAINWAVE_WIDE_LANES 1
#else
#define GRAINWAVE_WIDE_LANES 0
#endif

namespace grainwave::particles::dem::lanes {

template <int W>
struct VectorOf;
// vector_size cannot depend on a template parameter in GCC: one typedef per width.
template <>
struct VectorOf<2> {
  typedef double type __attribute__((vector_size(2 * sizeof(double))));
};
template <>
struct VectorOf<4> {
  typedef double type __attribute__((vector_size(4 * sizeof(double))));
};
template <>
struct VectorOf<8> {
  typedef double type __attribute__((vector_size(8 * sizeof(double))));
};
template <int W>
using Lanes = typename VectorOf<W>::type;
/// The number of lanes of a vector type.
template <class V>
constexpr int kWidth = static_cast<int>(sizeof(V) / sizeof(double));
/// The widest lane count the batched pass may use (PairBatch pads to a multiple of it).
constexpr int kMaxWidth = 8;

/// sqrt per lane. The loop is one vector square root where the width's instruction set is
/// enabled (the including file is built with -fno-math-errno, so no lane needs a libm call);
/// the intrinsic would not be inlinable into the width-generic helpers.
template <class V>
[[gnu::always_inline]] inline V lanes_sqrt(V a) {
  V r;
  for (int l = 0; l < kWidth<V>; ++l) r[l] = std::sqrt(a[l]);
  return r;
}

/// std::max(a, b) per lane (a when a < b is false, NaN included).
template <class V>
[[gnu::always_inline]] inline V lanes_max(V a, V b) {
  return a < b ? b : a;
}
template <class V>
[[gnu::always_inline]] inline V lanes_load(const double* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V>
[[gnu::always_inline]] inline void lanes_store(double* p, V v) {
  std::memcpy(p, &v, sizeof v);
}
/// Component k of the Vec3s at slots s[0..W).
template <class V>
[[gnu::always_inline]] inline V gather(const Vec3* v, const std::uint32_t* s, int k) {
  V r;
  for (int l = 0; l < kWidth<V>; ++l) r[l] = v[s[l]][k];
  return r;
}
template <class V>
[[gnu::always_inline]] inline V gather(const double* v, const std::uint32_t* s) {
  V r;
  for (int l = 0; l < kWidth<V>; ++l) r[l] = v[s[l]];
  return r;
}
/// Whether any lane of a comparison's mask is set.
template <class Mask>
[[gnu::always_inline]] inline bool any_lane(Mask m) {
  bool any = false;
  for (int l = 0; l < static_cast<int>(sizeof(Mask) / sizeof(m[0])); ++l) any |= m[l] != 0;
  return any;
}

/// Three components, one contact per lane.
template <class V>
struct Lanes3 {
  V x, y, z;
};
template <class V>
[[gnu::always_inline]] inline V dot(const Lanes3<V>& a, const Lanes3<V>& b) {  // Eigen's order
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class V>
[[gnu::always_inline]] inline Lanes3<V> cross(const Lanes3<V>& a, const Lanes3<V>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class V>
[[gnu::always_inline]] inline Lanes3<V> scaled(V s, const Lanes3<V>& a) {
  return {s * a.x, s * a.y, s * a.z};
}
template <class V>
[[gnu::always_inline]] inline Lanes3<V> minus(const Lanes3<V>& a, const Lanes3<V>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
/// Per lane, `when` ? a : b.
template <class Mask, class V>
[[gnu::always_inline]] inline Lanes3<V> select(Mask when, const Lanes3<V>& a, const Lanes3<V>& b) {
  return {when ? a.x : b.x, when ? a.y : b.y, when ? a.z : b.z};
}
/// rotate_into_plane per lane (its branches as selections).
template <class V>
[[gnu::always_inline]] inline Lanes3<V> rotate_into_plane(const Lanes3<V>& v, const Lanes3<V>& normal) {
  const V length2 = dot(v, v);
  const Lanes3<V> projected = minus(v, scaled(dot(v, normal), normal));
  const V projected2 = dot(projected, projected);
  const Lanes3<V> rotated = scaled(lanes_sqrt(length2 / projected2), projected);
  const V zero{};
  return select(length2 == 0.0, v, select(projected2 <= 1e-24 * length2, Lanes3<V>{zero, zero, zero}, rotated));
}
/// Component k of the history entries' Vec3 member `field`, one entry per lane.
template <class V>
[[gnu::always_inline]] inline Lanes3<V> gather_entries(ContactHistoryEntry* const* entry,
                                                       Vec3 ContactHistoryEntry::*field) {
  Lanes3<V> r;
  for (int l = 0; l < kWidth<V>; ++l) {
    const Vec3& v = entry[l]->*field;
    r.x[l] = v.x();
    r.y[l] = v.y();
    r.z[l] = v.z();
  }
  return r;
}

/// Touching pairs of one batch, then their forces (structure of arrays).
struct PairBatch {
  static constexpr int kSize = 64;
  static_assert(kSize % kMaxWidth == 0, "a full batch needs no padding at any width");
  int count = 0;
  std::uint32_t i[kSize], j[kSize];  // as listed
  alignas(64) double dx[kSize], dy[kSize], dz[kSize], distance2[kSize];
  // History laws: -1 where the canonical orientation (touch_history) reverses the listed pair,
  // else +1; and the pair's history entry.
  alignas(64) double orientation[kSize];
  ContactHistoryEntry* entry[kSize];
  ContactHistoryEntry pad_entry;  ///< written by the lanes that pad a short batch (then unused)
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

/// A lane group's contacts as particle_contact and LinearSpringDashpot::force compute them (in
/// the listed orientation), operation for operation (Eigen's cross, dot and norm in their
/// coefficient order).
template <class V>
struct LaneContact {
  Lanes3<V> normal, relative_velocity;
  V overlap, effective_mass, normal_speed, normal_force;
};
template <class V>
[[gnu::always_inline]] inline LaneContact<V> lane_contact(const PairBatch& b, int l, const LaneInputs& in) {
  const std::uint32_t* I = b.i + l;
  const std::uint32_t* J = b.j + l;
  LaneContact<V> c;
  const V distance = lanes_sqrt(lanes_load<V>(b.distance2 + l));
  const V inverse_distance = 1.0 / distance;
  c.normal = {lanes_load<V>(b.dx + l) * inverse_distance, lanes_load<V>(b.dy + l) * inverse_distance,
              lanes_load<V>(b.dz + l) * inverse_distance};
  const V ri = gather<V>(in.radius, I), rj = gather<V>(in.radius, J);
  c.overlap = ri + rj - distance;
  const Lanes3<V> spin{ri * gather<V>(in.angular_velocity, I, 0) + rj * gather<V>(in.angular_velocity, J, 0),
                       ri * gather<V>(in.angular_velocity, I, 1) + rj * gather<V>(in.angular_velocity, J, 1),
                       ri * gather<V>(in.angular_velocity, I, 2) + rj * gather<V>(in.angular_velocity, J, 2)};
  const Lanes3<V> velocity_difference{gather<V>(in.velocity, J, 0) - gather<V>(in.velocity, I, 0),
                                      gather<V>(in.velocity, J, 1) - gather<V>(in.velocity, I, 1),
                                      gather<V>(in.velocity, J, 2) - gather<V>(in.velocity, I, 2)};
  c.relative_velocity = minus(velocity_difference, cross(spin, c.normal));
  c.effective_mass = 1.0 / (gather<V>(in.inverse_mass, I) + gather<V>(in.inverse_mass, J));
  c.normal_speed = dot(c.relative_velocity, c.normal);
  const V eta = in.damping_factor * lanes_sqrt(c.effective_mass * in.stiffness);
  c.normal_force = in.stiffness * c.overlap - eta * c.normal_speed;
  return c;
}

/// The lanes' forces as apply() forms them: on_i = F_t - f_n n and the lever n × F_t.
template <class V>
[[gnu::always_inline]] inline void store_lane_forces(PairBatch& b, int l, const Lanes3<V>& normal, V normal_force,
                                                     const Lanes3<V>& tangential_force, V overlap) {
  const Lanes3<V> on_i = minus(tangential_force, scaled(normal_force, normal));
  const Lanes3<V> lever = cross(normal, tangential_force);
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
  /// The width taken by default where the CPU runs it: on the dense bed of bench_dem (AMD
  /// EPYC, Zen 5) 4 lanes ran 10 % faster than 8 and 16 % faster than 2.
  static constexpr int kPreferredWidth = 4;
  double mu, regularization_speed;
  explicit StaticFrictionLanes(const StaticFriction& law)
      : mu(law.friction()), regularization_speed(law.regularization_speed()) {}
  template <class V>
  [[gnu::always_inline]] void operator()(PairBatch& b, int l, const LaneContact<V>& c) const {
    const Lanes3<V> vt = minus(c.relative_velocity, scaled(c.normal_speed, c.normal));
    const V speed = lanes_sqrt(dot(vt, vt));
    const V magnitude = mu * lanes_max(c.normal_force, V{} + 0.0);
    const V scale = magnitude / lanes_max(speed, V{} + regularization_speed);
    const auto sliding = (speed != 0.0) & (magnitude != 0.0);  // else F_t = 0 exactly
    const V zero{};
    store_lane_forces(b, l, c.normal, c.normal_force,
                      select(sliding, scaled(scale, vt), Lanes3<V>{zero, zero, zero}), c.overlap);
  }
};

/// CoulombSpring with advance_history's kSingle stage (velocity Verlet) per lane, in the
/// canonical orientation (touch_history), reading and writing the pairs' history entries.
struct CoulombSpringLanes {
  static constexpr bool kKeepsHistory = true;  // reads b.orientation and b.entry
  /// As StaticFrictionLanes::kPreferredWidth: 8 lanes ran 6 % faster than 4 (its longer
  /// arithmetic per contact gains more from the width than the gathers lose).
  static constexpr int kPreferredWidth = 8;
  double stiffness, friction, damping_factor, half_dt;
  CoulombSpringLanes(const CoulombSpring& law, double dt)
      : stiffness(law.stiffness()), friction(law.friction()), damping_factor(law.damping_factor()),
        half_dt(0.5 * dt) {}
  template <class V>
  [[gnu::always_inline]] void operator()(PairBatch& b, int l, const LaneContact<V>& c) const {
    constexpr int W = kWidth<V>;
    // touch_history's reversal: -n and -v_ji (exact); v_ji · n is unchanged by it, bit for bit.
    const V orientation = lanes_load<V>(b.orientation + l);
    const Lanes3<V> normal = scaled(orientation, c.normal);
    const Lanes3<V> relative_velocity = scaled(orientation, c.relative_velocity);
    const Lanes3<V> vt = minus(relative_velocity, scaled(c.normal_speed, normal));
    ContactHistoryEntry* const* entry = b.entry + l;
    const Lanes3<V> displacement = gather_entries<V>(entry, &ContactHistoryEntry::displacement);
    const Lanes3<V> stage_velocity = gather_entries<V>(entry, &ContactHistoryEntry::stage_velocity);
    using Mask = decltype(V{} < V{});
    Mask is_new;
    for (int k = 0; k < W; ++k) is_new[k] = entry[k]->is_new ? -1 : 0;
    Lanes3<V> xi = rotate_into_plane(displacement, normal);
    const Lanes3<V> vt_old = select(is_new, vt, rotate_into_plane(stage_velocity, normal));
    const Lanes3<V> increment{half_dt * (vt_old.x + vt.x), half_dt * (vt_old.y + vt.y), half_dt * (vt_old.z + vt.z)};
    xi = {xi.x + increment.x, xi.y + increment.y, xi.z + increment.z};
    // coulomb_limited_spring
    const V damping = damping_factor * lanes_sqrt(c.effective_mass * stiffness);
    Lanes3<V> force{stiffness * xi.x + damping * vt.x, stiffness * xi.y + damping * vt.y,
                    stiffness * xi.z + damping * vt.z};
    const V limit = friction * lanes_max(c.normal_force, V{} + 0.0);
    const V force2 = dot(force, force);
    const auto slips = force2 > limit * limit;
    if (any_lane(slips)) [[unlikely]] {  // ~3 % of contacts in a dense flowing bed
      const Lanes3<V> capped = scaled(limit / lanes_sqrt(force2), force);
      const Lanes3<V> damping_part = scaled(damping, vt);
      const Lanes3<V> slipped_xi{(capped.x - damping_part.x) / stiffness, (capped.y - damping_part.y) / stiffness,
                                 (capped.z - damping_part.z) / stiffness};
      force = select(slips, capped, force);
      xi = select(slips, slipped_xi, xi);
    }
    for (int k = 0; k < W; ++k) {
      entry[k]->displacement = Vec3(xi.x[k], xi.y[k], xi.z[k]);
      entry[k]->stage_velocity = Vec3(vt.x[k], vt.y[k], vt.z[k]);
      entry[k]->is_new = false;
    }
    store_lane_forces(b, l, normal, c.normal_force, force, c.overlap);
  }
};

/// The forces of the batch's first `count` contacts (a multiple of W, padded), W at a time.
template <int W, class TangentialLanes>
[[gnu::always_inline]] inline void forces_in_lanes_of(PairBatch& b, int count, const LaneInputs& in,
                                                      const TangentialLanes& tangential) {
  for (int l = 0; l < count; l += W) tangential(b, l, lane_contact<Lanes<W>>(b, l, in));
}
template <class TangentialLanes>
void batch_lane_forces_sse2(PairBatch& b, int count, const LaneInputs& in, const TangentialLanes& tangential) {
  forces_in_lanes_of<2>(b, count, in, tangential);
}
#if GRAINWAVE_WIDE_LANES
template <class TangentialLanes>
[[gnu::target("avx2")]] void batch_lane_forces_avx2(PairBatch& b, int count, const LaneInputs& in,
                                                    const TangentialLanes& tangential) {
  forces_in_lanes_of<4>(b, count, in, tangential);
}
template <class TangentialLanes>
[[gnu::target("avx512f")]] void batch_lane_forces_avx512(PairBatch& b, int count, const LaneInputs& in,
                                                        const TangentialLanes& tangential) {
  forces_in_lanes_of<8>(b, count, in, tangential);
}
#endif

/// The forces of the batch's first `count` contacts at `width` lanes (2, 4 or 8, a width that
/// lane_width_supported accepts; count a multiple of it).
template <class TangentialLanes>
void batch_lane_forces(int width, PairBatch& b, int count, const LaneInputs& in,
                       const TangentialLanes& tangential) {
#if GRAINWAVE_WIDE_LANES
  if (width == 8) return batch_lane_forces_avx512(b, count, in, tangential);
  if (width == 4) return batch_lane_forces_avx2(b, count, in, tangential);
#endif
  (void)width;
  batch_lane_forces_sse2(b, count, in, tangential);
}

/// Whether this machine runs the batched pass at `width` lanes (2: always; 4: AVX2; 8: AVX-512F).
inline bool lane_width_supported(int width) {
#if GRAINWAVE_WIDE_LANES
  if (width == 8) return cpu_has_avx512f();
  if (width == 4) return __builtin_cpu_supports("avx2");
#endif
  return width == 2;
}
/// The widest supported width up to `preferred`.
inline int supported_width_up_to(int preferred) {
  for (int width = preferred; width > 2; width /= 2)
    if (lane_width_supported(width)) return width;
  return 2;
}

}  // namespace grainwave::particles::dem::lanes
