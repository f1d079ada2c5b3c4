#pragma once
// Static (sliding-only) friction, 002 Eq. 3.16: F_t = μ f_n t with t = v_t/|v_t|, here on i and
// along the slip of j's surface past i's. No history. Optionally regularised below a slip speed
// ε as F_t = μ f_n v_t/ε (000 §2.2 friction regularisation, Eq. 2.66 with the v/ε correction),
// which removes the sign chatter of the bare law near rolling; ε = 0 gives Eq. 3.16 exactly.
#include "particles/dem/ContactLaw.hpp"

#include <algorithm>
#include <cmath>

namespace grainwave::particles::dem {

class StaticFriction final : public TangentialLaw {
 public:
  /// Whether the law reads Contact::effective_radius (the fused pass computes it only then).
  static constexpr bool kReadsEffectiveRadius = false;
  struct Parameters {
    double friction = 0.0;              ///< μ
    double regularization_speed = 0.0;  ///< ε [m/s]
  };
  explicit StaticFriction(const Parameters& parameters);
  /// Reads "friction" and "regularization_speed".
  explicit StaticFriction(const LawParameters& parameters);

  double friction() const { return friction_; }
  double regularization_speed() const { return regularization_speed_; }

  Vec3 force(double normal_force, const Vec3& tangential_velocity) const {
    const double speed = tangential_velocity.norm();
    const double magnitude = friction_ * std::max(normal_force, 0.0);
    if (speed == 0.0 || magnitude == 0.0) return Vec3::Zero();
    return (magnitude / std::max(speed, regularization_speed_)) * tangential_velocity;
  }

  /// From the contact's normal force (written by the normal law).
  Vec3 force(const Contact& c) const { return force(c.normal_force, c.tangential_velocity()); }

  bool needs_history() const override { return false; }
  void evaluate(std::span<Contact> contacts, HistoryStage, double) const override {
    for (Contact& c : contacts) c.tangential_force = force(c);
  }

 private:
  double friction_;
  double regularization_speed_;
};

}  // namespace grainwave::particles::dem
