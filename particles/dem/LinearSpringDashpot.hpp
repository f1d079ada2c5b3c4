#pragma once
// Linear spring–dashpot normal force, 002 Eq. 3.5:  f_n = k_n δ − η_n (v_ji · n),
// with the damping from the restitution coefficient e, Eq. 3.10,
//   η_n = −2 ln e sqrt(m* k_n) / sqrt(π² + ln² e),
// and the contact duration of Eq. 3.17, τ = sqrt((π² + ln² e) m*/k_n). The force is not clipped
// at zero: the damped-oscillator solution behind Eqs 3.10 and 3.17 ends the contact when δ
// returns to 0, which includes a short slightly attractive phase.
#include "particles/dem/ContactLaw.hpp"

#include <cmath>

namespace grainwave::particles::dem {

class LinearSpringDashpot final : public NormalLaw {
 public:
  /// Whether the law reads Contact::effective_radius (the fused pass computes it only then).
  static constexpr bool kReadsEffectiveRadius = false;
  struct Parameters {
    double stiffness = 0.0;    ///< k_n [N/m]
    double restitution = 1.0;  ///< e in (0, 1]
  };
  explicit LinearSpringDashpot(const Parameters& parameters);
  /// Reads "stiffness" and "restitution".
  explicit LinearSpringDashpot(const LawParameters& parameters);

  /// η_n / sqrt(m* k_n), fixed by e alone.
  double damping_factor() const { return damping_factor_; }
  double stiffness() const { return stiffness_; }

  double force(double overlap, double normal_speed, double effective_mass) const {
    const double eta = damping_factor_ * std::sqrt(effective_mass * stiffness_);
    return stiffness_ * overlap - eta * normal_speed;
  }

  double force(const Contact& c) const { return force(c.overlap, c.normal_speed(), c.effective_mass); }
  void evaluate(std::span<Contact> contacts) const override {
    for (Contact& c : contacts) c.normal_force = force(c);
  }
  double contact_duration(double effective_mass, double /*effective_radius*/) const override;

 private:
  double stiffness_;
  double restitution_;
  double damping_factor_;
};

}  // namespace grainwave::particles::dem
