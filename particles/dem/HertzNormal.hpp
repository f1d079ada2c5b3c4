#pragma once
// Hertz normal force with viscous damping (000 §2.2, Eq. 2.4 elastic part):
//   f_n = K δ^{3/2} − c sqrt(m* K) δ^{1/4} (v_ji · n),   K = (4/3) E* sqrt(R*),
//   1/E* = (1−ν²)/E + (1−ν²)/E (one material for particles and walls).
// With δ^{1/4} damping (Tsuji et al. 1992) the collision is self-similar in the impact speed, so
// the restitution depends on c alone. Writing δ = D x, t = T s with T = (m*²/(K² v₀))^{1/5},
// D = v₀ T gives x'' = −x^{3/2} − c x^{1/4} x', x(0) = 0, x'(0) = 1; the constructor integrates
// this once and bisects for the c that yields the requested e, and keeps the scaled duration s_c
// so that τ = s_c (m*²/(K² v_ref))^{1/5} for the time-step estimate at a reference speed.
// (000 Eq. 2.8 uses δ^{1/2} damping instead, whose restitution falls with impact speed.)
#include "particles/dem/ContactLaw.hpp"

#include <cmath>

namespace grainwave::particles::dem {

class HertzNormal final : public NormalLaw {
 public:
  /// Whether the law reads Contact::effective_radius (the fused pass computes it only then).
  static constexpr bool kReadsEffectiveRadius = true;
  struct Parameters {
    double youngs_modulus = 0.0;      ///< E [Pa]
    double poisson_ratio = 0.3;       ///< ν
    double restitution = 1.0;         ///< e in (0, 1]
    double reference_velocity = 1.0;  ///< impact speed the time step is sized for [m/s]
  };
  explicit HertzNormal(const Parameters& parameters);
  /// Reads "youngs_modulus", "poisson_ratio", "restitution", "reference_velocity".
  explicit HertzNormal(const LawParameters& parameters);

  /// Scaled damping c and scaled contact duration s_c of the self-similar collision.
  double damping_factor() const { return damping_factor_; }
  double scaled_duration() const { return scaled_duration_; }
  /// K of Eq. 2.4 for reduced radius R*.
  double stiffness(double effective_radius) const {
    return (4.0 / 3.0) * effective_modulus_ * std::sqrt(effective_radius);
  }

  double force(double overlap, double normal_speed, double effective_mass,
               double effective_radius) const {
    const double k = stiffness(effective_radius);
    const double root_quarter = std::sqrt(std::sqrt(overlap));  // δ^{1/4}
    const double sqrt_overlap = root_quarter * root_quarter;
    return k * overlap * sqrt_overlap -
           damping_factor_ * std::sqrt(effective_mass * k) * root_quarter * normal_speed;
  }

  double force(const Contact& c) const {
    return force(c.overlap, c.normal_speed(), c.effective_mass, c.effective_radius);
  }
  void evaluate(std::span<Contact> contacts) const override {
    for (Contact& c : contacts) c.normal_force = force(c);
  }
  double contact_duration(double effective_mass, double effective_radius) const override;

  /// Restitution and scaled duration of the scaled collision ODE for damping factor c.
  struct ScaledCollision {
    double restitution;
    double duration;
  };
  static ScaledCollision integrate_scaled_collision(double damping_factor);

 private:
  double effective_modulus_;
  double restitution_;
  double reference_velocity_;
  double damping_factor_ = 0.0;
  double scaled_duration_ = 0.0;
};

}  // namespace grainwave::particles::dem
