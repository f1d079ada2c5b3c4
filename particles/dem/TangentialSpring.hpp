#pragma once
// Shared machinery of the tangential laws that store a displacement (002 Eqs 3.12 and 3.15):
// the Coulomb-limited spring itself, the rotation of the stored displacement into the current
// contact plane (3D contacts roll and the plane turns between steps, 002 §3.2.2 / ref. [83]),
// and how the history advances: trapezoidal in v_t in both velocity Verlet (one evaluation per
// step, v_t of the previous step kept in the entry) and RK2 (Heun applied to δ_t as to x).
#include "particles/dem/ContactHistory.hpp"
#include "particles/dem/ContactLaw.hpp"

#include <algorithm>
#include <cmath>

namespace grainwave::particles::dem {

/// Tangential spring force on i, k_t δ_t + η_t v_t, capped at μ max(f_n, 0). When the cap acts,
/// δ_t is shortened so that the spring alone would give the capped force (the contact slips and
/// the stored elastic displacement is what the Coulomb limit allows).
inline Vec3 coulomb_limited_spring(double stiffness, double damping, double friction,
                                   double normal_force, const Vec3& tangential_velocity,
                                   Vec3& displacement) {
  Vec3 f = stiffness * displacement + damping * tangential_velocity;
  const double limit = friction * std::max(normal_force, 0.0);
  const double f2 = f.squaredNorm();
  if (f2 > limit * limit) {
    f *= limit / std::sqrt(f2);
    displacement = (f - damping * tangential_velocity) / stiffness;
  }
  return f;
}

/// Projects a stored tangential vector onto the plane normal to n and restores its length.
inline Vec3 rotate_into_plane(const Vec3& v, const Vec3& normal) {
  const double length2 = v.squaredNorm();
  if (length2 == 0.0) return v;
  const Vec3 projected = v - v.dot(normal) * normal;
  const double projected2 = projected.squaredNorm();
  if (projected2 <= 1e-24 * length2) return Vec3::Zero();
  return projected * std::sqrt(length2 / projected2);
}

/// Advances one contact's history and sets its tangential force. `Law` provides
///   Vec3 spring_force(const Contact&, const Vec3& v_t, Vec3& displacement) const
/// (inline, may shorten the displacement at the Coulomb limit). c.history is set and
/// c.normal_force written.
template <class Law>
inline void advance_history(const Law& law, Contact& c, HistoryStage stage, double dt) {
  ContactHistoryEntry& h = *c.history;
  const Vec3 vt = c.tangential_velocity();
  Vec3 xi = rotate_into_plane(h.displacement, c.normal);
  if (stage == HistoryStage::kSingle) {
    // Trapezoidal δ_t(n+1) = δ_t(n) + Δt/2 (v_t(n) + v_t(n+1)); a new contact has no v_t(n).
    const Vec3 vt_old = h.is_new ? vt : rotate_into_plane(h.stage_velocity, c.normal);
    xi += 0.5 * dt * (vt_old + vt);
    c.tangential_force = law.spring_force(c, vt, xi);
    h.displacement = xi;
    h.stage_velocity = vt;
  } else if (stage == HistoryStage::kPredict) {
    c.tangential_force = law.spring_force(c, vt, xi);
    h.displacement = xi;
    h.stage_velocity = vt;
  } else {
    const Vec3 vt_first = h.is_new ? vt : rotate_into_plane(h.stage_velocity, c.normal);
    Vec3 predicted = xi + dt * vt_first;
    c.tangential_force = law.spring_force(c, vt, predicted);
    Vec3 committed = xi + 0.5 * dt * (vt_first + vt);
    law.spring_force(c, vt, committed);  // apply the Coulomb limit to the committed value
    h.displacement = committed;
  }
  h.is_new = false;
}

/// Drives a history law over a batch (advance_history per contact).
template <class Law>
void evaluate_with_history(const Law& law, std::span<Contact> contacts, HistoryStage stage,
                           double dt) {
  for (Contact& c : contacts) advance_history(law, c, stage, dt);
}

}  // namespace grainwave::particles::dem
