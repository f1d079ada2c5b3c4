#pragma once
// The one particle store shared by the hard-sphere collider, the DEM and the fluid coupling.
//
// Structure of arrays: each property is its own contiguous array indexed by the particle's local
// slot, so a kernel streams only the fields it touches. Vectors are always 3-component; 2D scenes
// (disks = cylinders of unit depth in the x-y plane) keep z = 0 and use only angular_velocity.z().
// Slots are not stable: remove() moves the last particle into the hole. `id` is the stable,
// globally unique name of a particle and is what output, restart and error messages use.
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

namespace grainwave::particles {

using Vec3 = Eigen::Vector3d;

/// Bit flags carried by every particle.
enum ParticleFlag : std::uint32_t {
  kFixed = 1u << 0,  ///< immovable (infinite mass), e.g. a rough-wall particle
  kGhost = 1u << 1,  ///< copy of a particle owned by another rank or a periodic image
};

/// Moment of inertia of a homogeneous solid sphere (dim 3) or disk (dim 2) about its centre.
inline double solid_inertia(int dimension, double mass, double radius) {
  return (dimension == 2 ? 0.5 : 0.4) * mass * radius * radius;
}

/// to = from for arrays of Vec3 as one block copy. Eigen's vectors are not trivially copyable, so
/// std::vector's assignment copies them one by one, several times slower; the DEM keeps a copy
/// of its state every step (the last good state), where that was 10% of a curtain run.
inline void copy_vec3(std::vector<Vec3>& to, const std::vector<Vec3>& from) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double) && std::is_standard_layout_v<Vec3>);
  to.resize(from.size());
  if (!from.empty()) std::memcpy(static_cast<void*>(to.data()), static_cast<const void*>(from.data()), from.size() * sizeof(Vec3));
}

/// Keeps the entries i of a per-slot array with keep[i] != 0, in their order (stable compaction).
template <class T>
void keep_slots(std::vector<T>& v, const std::vector<std::uint8_t>& keep) {
  std::size_t out = 0;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (keep[i]) v[out++] = v[i];
  v.resize(out);
}

/// Rearranges a per-slot array so that entry k holds old entry order[k] (a permutation).
template <class T>
void permute_slots(std::vector<T>& v, const std::vector<std::uint32_t>& order) {
  const std::vector<T> old(v);
  for (std::size_t k = 0; k < order.size(); ++k) v[k] = old[order[k]];
}

struct ParticleStore {
  ParticleStore() = default;
  ParticleStore(const ParticleStore&) = default;
  ParticleStore(ParticleStore&&) = default;
  ParticleStore& operator=(ParticleStore&&) = default;
  /// Member-wise, with the Vec3 arrays as block copies (copy_vec3).
  ParticleStore& operator=(const ParticleStore& other);

  std::vector<Vec3> position;
  std::vector<Vec3> velocity;
  std::vector<Vec3> angular_velocity;
  std::vector<Vec3> force;   ///< external force held constant over a step (fluid, gravity, ...)
  std::vector<Vec3> torque;  ///< external torque held constant over a step
  std::vector<double> radius;
  std::vector<double> mass;
  std::vector<double> inertia;  ///< scalar moment of inertia (spheres/disks are isotropic)
  std::vector<std::int64_t> id;
  std::vector<std::uint32_t> flags;

  std::size_t size() const { return id.size(); }
  /// Slots before the ghosts (ghost copies, flagged kGhost, trail a store's own particles).
  std::size_t owned_size() const {
    std::size_t n = size();
    while (n > 0 && (flags[n - 1] & kGhost) != 0) --n;
    return n;
  }
  bool empty() const { return id.empty(); }

  void reserve(std::size_t n);
  void clear();
  /// Appends one particle with zero force and torque; returns its slot.
  std::size_t add(std::int64_t particle_id, const Vec3& x, const Vec3& v, const Vec3& omega,
                  double r, double m, double moment_of_inertia, std::uint32_t particle_flags = 0);
  /// Removes slot i by moving the last particle into it (order is not preserved).
  void remove(std::size_t i);
  /// Appends slot i of `other`.
  void append_from(const ParticleStore& other, std::size_t i);
  /// Drops every slot from n on (ghost copies are kept at the end of a store).
  void truncate(std::size_t n);
  /// Keeps the slots with keep[i] != 0, in their order (a stable compaction).
  void keep_where(const std::vector<std::uint8_t>& keep);
  /// Rearranges the slots so that new slot k holds old slot order[k] (a permutation).
  void permute(const std::vector<std::uint32_t>& order);

  bool is_fixed(std::size_t i) const { return (flags[i] & kFixed) != 0; }
  /// The first slot whose position, velocity or angular velocity holds a NaN or an infinity, or
  /// size() when all are finite. Runs check it after every step: one pass without branches over
  /// the three arrays, and a search only when it finds something.
  std::size_t first_non_finite() const;
  /// Inverse mass, zero for fixed particles (so impulses and forces leave them unmoved).
  double inverse_mass(std::size_t i) const { return is_fixed(i) ? 0.0 : 1.0 / mass[i]; }
  double inverse_inertia(std::size_t i) const { return is_fixed(i) ? 0.0 : 1.0 / inertia[i]; }

  /// Bytes held per particle by the arrays above (for memory estimates and benchmarks).
  static constexpr std::size_t bytes_per_particle() {
    return 5 * sizeof(Vec3) + 3 * sizeof(double) + sizeof(std::int64_t) + sizeof(std::uint32_t);
  }
};

}  // namespace grainwave::particles
