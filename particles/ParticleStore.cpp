#include "particles/ParticleStore.hpp"

#include <bit>
#include <cstdint>

#include "core/KernelClones.hpp"

namespace grainwave::particles {

ParticleStore& ParticleStore::operator=(const ParticleStore& other) {
  // Ten arrays: a new one must be copied here too (this size check fails when one is added).
  static_assert(sizeof(ParticleStore) == 10 * sizeof(std::vector<double>));
  if (this == &other) return *this;
  copy_vec3(position, other.position);
  copy_vec3(velocity, other.velocity);
  copy_vec3(angular_velocity, other.angular_velocity);
  copy_vec3(force, other.force);
  copy_vec3(torque, other.torque);
  radius = other.radius;
  mass = other.mass;
  inertia = other.inertia;
  id = other.id;
  flags = other.flags;
  return *this;
}

void ParticleStore::reserve(std::size_t n) {
  position.reserve(n);
  velocity.reserve(n);
  angular_velocity.reserve(n);
  force.reserve(n);
  torque.reserve(n);
  radius.reserve(n);
  mass.reserve(n);
  inertia.reserve(n);
  id.reserve(n);
  flags.reserve(n);
}

void ParticleStore::clear() {
  position.clear();
  velocity.clear();
  angular_velocity.clear();
  force.clear();
  torque.clear();
  radius.clear();
  mass.clear();
  inertia.clear();
  id.clear();
  flags.clear();
}

std::size_t ParticleStore::add(std::int64_t particle_id, const Vec3& x, const Vec3& v,
                               const Vec3& omega, double r, double m, double moment_of_inertia,
                               std::uint32_t particle_flags) {
  position.push_back(x);
  velocity.push_back(v);
  angular_velocity.push_back(omega);
  force.push_back(Vec3::Zero());
  torque.push_back(Vec3::Zero());
  radius.push_back(r);
  mass.push_back(m);
  inertia.push_back(moment_of_inertia);
  id.push_back(particle_id);
  flags.push_back(particle_flags);
  return id.size() - 1;
}

namespace {
/// Whether any component of `v` has the exponent of a NaN or an infinity: an OR over the bits,
/// which the compiler turns into vector code where it has 64-bit compares (AVX2).
GRAINWAVE_CLONES_AVX2 bool any_non_finite(const std::vector<Vec3>& v) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "the Vec3 arrays are read as doubles");
  constexpr std::uint64_t kExponent = 0x7ff0000000000000ull;
  const double* x = v.empty() ? nullptr : v.front().data();
  const std::size_t n = 3 * v.size();
  std::uint64_t found = 0;
  for (std::size_t k = 0; k < n; ++k) found |= (std::bit_cast<std::uint64_t>(x[k]) & kExponent) == kExponent ? 1u : 0u;
  return found != 0;
}

template <class T>
void move_last_into(std::vector<T>& a, std::size_t i) {
  a[i] = a.back();
  a.pop_back();
}
}  // namespace

void ParticleStore::remove(std::size_t i) {
  move_last_into(position, i);
  move_last_into(velocity, i);
  move_last_into(angular_velocity, i);
  move_last_into(force, i);
  move_last_into(torque, i);
  move_last_into(radius, i);
  move_last_into(mass, i);
  move_last_into(inertia, i);
  move_last_into(id, i);
  move_last_into(flags, i);
}

std::size_t ParticleStore::first_non_finite() const {
  if (!any_non_finite(position) && !any_non_finite(velocity) && !any_non_finite(angular_velocity))
    return size();
  for (std::size_t i = 0; i < size(); ++i)
    if (!position[i].allFinite() || !velocity[i].allFinite() || !angular_velocity[i].allFinite()) return i;
  return size();
}

void ParticleStore::append_from(const ParticleStore& other, std::size_t i) {
  add(other.id[i], other.position[i], other.velocity[i], other.angular_velocity[i],
      other.radius[i], other.mass[i], other.inertia[i], other.flags[i]);
  force.back() = other.force[i];
  torque.back() = other.torque[i];
}

void ParticleStore::truncate(std::size_t n) {
  if (n >= size()) return;
  position.resize(n);
  velocity.resize(n);
  angular_velocity.resize(n);
  force.resize(n);
  torque.resize(n);
  radius.resize(n);
  mass.resize(n);
  inertia.resize(n);
  id.resize(n);
  flags.resize(n);
}

void ParticleStore::keep_where(const std::vector<std::uint8_t>& keep) {
  keep_slots(position, keep);
  keep_slots(velocity, keep);
  keep_slots(angular_velocity, keep);
  keep_slots(force, keep);
  keep_slots(torque, keep);
  keep_slots(radius, keep);
  keep_slots(mass, keep);
  keep_slots(inertia, keep);
  keep_slots(id, keep);
  keep_slots(flags, keep);
}

void ParticleStore::permute(const std::vector<std::uint32_t>& order) {
  permute_slots(position, order);
  permute_slots(velocity, order);
  permute_slots(angular_velocity, order);
  permute_slots(force, order);
  permute_slots(torque, order);
  permute_slots(radius, order);
  permute_slots(mass, order);
  permute_slots(inertia, order);
  permute_slots(id, order);
  permute_slots(flags, order);
}

}  // namespace grainwave::particles
