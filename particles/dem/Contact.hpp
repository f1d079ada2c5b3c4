#pragma once
// One active contact between particle i and a partner j (another particle or a wall), as the
// contact laws see it. Conventions follow 002 §3.2.2 with the signs derived here, because the
// OCR'd Eqs 3.5/3.8/3.12 mix "force on i" and "force on j":
//   n      unit normal from the centre of i towards the partner                (Eq. 3.7)
//   δ      overlap R_i + R_j − |r_j − r_i|, > 0 in contact                      (Eq. 3.6)
//   v_ji   velocity of j's surface point relative to i's at the contact:
//          v_ji = (v_j − v_i) − (R_i ω_i + R_j ω_j) × n        (Eq. 3.8, sign fixed by
//          differentiating r_i + R_i n and r_j − R_j n)
//   f_n    repulsive normal force magnitude; the force on i is −f_n n + F_t, on j the opposite.
//   F_t    tangential force on i; it drags i along v_t (j's surface sliding past i's).
//   m*     (1/m_i + 1/m_j)^-1 (Eq. 3.11), R* = (1/R_i + 1/R_j)^-1 with a wall of infinite radius.
#include "particles/ParticleStore.hpp"

#include <Eigen/Geometry>

#include <cstdint>

namespace grainwave::particles::dem {

struct ContactHistoryEntry;

struct Contact {
  static constexpr std::uint32_t kNotListed = 0xffffffffu;
  std::uint32_t i = 0;
  std::uint32_t partner = 0;  ///< slot of j, or wall index when is_wall
  /// Index of the Verlet-list pair the contact was found from (its history lookup is cached
  /// per pair), or kNotListed (a cell search, a wall).
  std::uint32_t list_index = kNotListed;
  bool is_wall = false;
  Vec3 normal = Vec3::Zero();
  double overlap = 0.0;
  Vec3 relative_velocity = Vec3::Zero();  ///< v_ji at the contact point
  double effective_mass = 0.0;
  double effective_radius = 0.0;
  double normal_force = 0.0;  ///< written by the normal law
  Vec3 tangential_force = Vec3::Zero();  ///< written by the tangential law
  ContactHistoryEntry* history = nullptr;  ///< set only when the tangential law keeps history

  /// Component of v_ji along n (negative while approaching).
  double normal_speed() const { return relative_velocity.dot(normal); }
  Vec3 tangential_velocity() const { return relative_velocity - normal_speed() * normal; }
};

/// m* of Eq. 3.11 from inverse masses (0 for fixed particles and walls).
inline double effective_mass(double inverse_mass_i, double inverse_mass_j) {
  return 1.0 / (inverse_mass_i + inverse_mass_j);
}

/// Reduced radius; radius_j <= 0 means a flat partner (wall) of infinite radius of curvature.
inline double effective_radius(double radius_i, double radius_j) {
  return radius_j > 0.0 ? radius_i * radius_j / (radius_i + radius_j) : radius_i;
}

}  // namespace grainwave::particles::dem
