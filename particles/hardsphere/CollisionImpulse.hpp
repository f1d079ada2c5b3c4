#pragma once
// Impulse of an instantaneous binary collision between two rigid spheres (3D) or disks (2D) with
// restitution e and Coulomb friction mu (hard-sphere model of Goetsch 2015, 002 §2.3.2,
// Eqs 2.14–2.25, after Crowe, Sommerfeld & Tsuji; Mukherjee 2013, 000 §2.3, stick/slip).
//
// n is the unit normal from body 1 to body 2, P the impulse acting on body 1 (-P on body 2):
//   v1' = v1 + w1 P,          v2' = v2 - w2 P,             (w = 1/m)
//   w1' = w1 + k1 r1 n x P,   w2' = w2 + k2 r2 n x P,      (k = 1/I)
// Relative contact velocity (Eq. 2.15) Gc = v1 - v2 + r1 w1 x n + r2 w2 x n changes by
//   dGc_n = W_n P_n,  dGc_t = W_t P_t,  W_n = w1 + w2,  W_t = w1 + w2 + k1 r1^2 + k2 r2^2.
// Normal (Newton restitution): P_n = -(1 + e) (n.G) / W_n.
// Stick (tangential contact velocity brought to zero): P_t = -Gc_t / W_t.
// Slide (stick would need more than Coulomb allows): P_t = -mu |P_n| t, t = Gc_t / |Gc_t|.
// The sliding criterion (replacing the garbled 002 Eq. 2.17) follows from |P_t,stick| > mu |P_n|:
//   n.G / |Gc_t| < (W_n / W_t) / (mu (1 + e)),
// which for solid spheres (I = 2/5 m r^2, W_t = 7/2 W_n) is Crowe's 2 / (7 mu (1 + e)); the 2/7
// and 5/2 of 002 are special cases of W_n/W_t and k r. A wall is a partner with w = k = r = 0.
//
// Velocity-dependent restitution (000 Eq. 2.62, elastic–plastic impact after Johnson):
//   e = 1.88 alpha^(5/8) sqrt(Y/E*) (m* v_n^2 / (2 Y R*^3))^(-1/8), clamped to [0, 1],
// with m* = 1/W_n and R* = r1 r2 / (r1 + r2) (R* = r of the sphere against a wall).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace grainwave::particles::hardsphere {

using Vec3 = Eigen::Vector3d;

enum class RestitutionModel {
  kConstant,           ///< e = CollisionLaw::restitution
  kVelocityDependent,  ///< e(v_n) from 000 Eq. 2.62
};

/// Material constants of 000 Eq. 2.62.
struct PlasticImpact {
  double yield_stress = 1.0;         ///< Y
  double effective_modulus = 1.0;    ///< E* = 1 / ((1-nu1^2)/E1 + (1-nu2^2)/E2)
  double pressure_factor = 3.0;      ///< alpha: mean contact pressure p_m = alpha Y (3 for metals)
};

struct CollisionLaw {
  double restitution = 1.0;  ///< e, used when model == kConstant
  double friction = 0.0;     ///< Coulomb mu
  RestitutionModel model = RestitutionModel::kConstant;
  PlasticImpact plastic{};
};

/// Throws grainwave::InputError naming `key_prefix` when a law parameter is out of range.
void validate(const CollisionLaw& law, const std::string& key_prefix = "collision");
/// One line for a start-up summary, e.g. "hard sphere: e = 0.9, mu = 0.1".
std::string describe(const CollisionLaw& law);

/// Kinematic and inertial state of one collision partner. A wall: zero inverse mass, inertia, radius.
struct Body {
  Vec3 velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
  double inverse_mass = 0.0;
  double inverse_inertia = 0.0;
  double radius = 0.0;
};

struct CollisionImpulse {
  Vec3 impulse = Vec3::Zero();  ///< acts on body 1; body 2 receives -impulse
  double restitution = 1.0;     ///< e actually used
  bool sliding = false;         ///< Coulomb limit reached (slides throughout the contact)
  bool approaching = false;     ///< false: bodies already separate along n, impulse is zero
};

/// 000 Eq. 2.62 for a normal approach speed v_n >= 0.
inline double plastic_restitution(const PlasticImpact& p, double effective_mass,
                                  double effective_radius, double normal_speed) {
  const double kinetic = 0.5 * effective_mass * normal_speed * normal_speed;
  if (kinetic <= 0.0) return 1.0;
  const double reference = p.yield_stress * effective_radius * effective_radius * effective_radius;
  const double e = 1.88 * std::pow(p.pressure_factor, 0.625) *
                   std::sqrt(p.yield_stress / p.effective_modulus) *
                   std::pow(kinetic / reference, -0.125);
  return std::clamp(e, 0.0, 1.0);
}

inline double effective_radius(double r1, double r2) {
  if (r1 <= 0.0) return r2;
  if (r2 <= 0.0) return r1;
  return r1 * r2 / (r1 + r2);
}

inline double restitution_for(const CollisionLaw& law, const Body& a, const Body& b,
                              double normal_speed) {
  if (law.model == RestitutionModel::kConstant) return law.restitution;
  const double normal_compliance = a.inverse_mass + b.inverse_mass;
  return plastic_restitution(law.plastic, 1.0 / normal_compliance,
                             effective_radius(a.radius, b.radius), normal_speed);
}

/// Relative velocity of the contact points, body 1 minus body 2 (002 Eq. 2.15).
inline Vec3 contact_velocity(const Body& a, const Body& b, const Vec3& n) {
  return a.velocity - b.velocity + a.radius * a.angular_velocity.cross(n) +
         b.radius * b.angular_velocity.cross(n);
}

/// The collision impulse for unit normal n (from body 1 to body 2). Zero if they separate.
inline CollisionImpulse collision_impulse(const Body& a, const Body& b, const Vec3& n,
                                          const CollisionLaw& law) {
  CollisionImpulse out;
  const double approach_speed = n.dot(a.velocity - b.velocity);  // n.G, > 0 when approaching
  if (!(approach_speed > 0.0)) return out;
  out.approaching = true;
  const double normal_compliance = a.inverse_mass + b.inverse_mass;
  const double tangential_compliance = normal_compliance +
                                       a.inverse_inertia * a.radius * a.radius +
                                       b.inverse_inertia * b.radius * b.radius;
  out.restitution = restitution_for(law, a, b, approach_speed);
  const double normal_impulse = (1.0 + out.restitution) * approach_speed / normal_compliance;
  const Vec3 gc = contact_velocity(a, b, n);
  const Vec3 slip = gc - gc.dot(n) * n;
  const Vec3 stick_impulse = -slip / tangential_compliance;
  const double friction_limit = law.friction * normal_impulse;
  Vec3 tangential = stick_impulse;
  const double stick_norm = stick_impulse.norm();
  if (stick_norm > friction_limit) {
    out.sliding = true;
    tangential = stick_impulse * (friction_limit / stick_norm);
  }
  out.impulse = -normal_impulse * n + tangential;
  return out;
}

/// Applies impulse P (on body 1, -P on body 2) with the normal n it was computed for.
inline void apply_impulse(Body& a, Body& b, const Vec3& n, const Vec3& impulse) {
  const Vec3 moment = n.cross(impulse);
  a.velocity += a.inverse_mass * impulse;
  b.velocity -= b.inverse_mass * impulse;
  a.angular_velocity += a.inverse_inertia * a.radius * moment;
  b.angular_velocity += b.inverse_inertia * b.radius * moment;
}

/// Computes and applies the collision impulse; returns it.
inline CollisionImpulse collide(Body& a, Body& b, const Vec3& n, const CollisionLaw& law) {
  const CollisionImpulse result = collision_impulse(a, b, n, law);
  if (result.approaching) apply_impulse(a, b, n, result.impulse);
  return result;
}

}  // namespace grainwave::particles::hardsphere
