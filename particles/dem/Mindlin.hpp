#pragma once
// Mindlin no-slip tangential stiffness with a Coulomb cap (000 §2.2, Eq. 2.5, whose OCR'd form
// is inverted): k_t = 8 G* a with contact radius a = sqrt(R* δ) and
// 1/G* = (2−ν)/G + (2−ν)/G, G = E/(2(1+ν)). The force is the Coulomb-limited spring of
// CoulombSpring with this overlap-dependent k_t applied to the stored displacement (the simple
// "total displacement" form; the loading/unloading hysteresis of Mindlin–Deresiewicz, 000
// Eq. 2.11, is not modelled). η_t = γ_t sqrt(m* k_t).
#include "particles/dem/TangentialSpring.hpp"

namespace grainwave::particles::dem {

class Mindlin final : public TangentialLaw {
 public:
  /// Whether the law reads Contact::effective_radius (the fused pass computes it only then).
  static constexpr bool kReadsEffectiveRadius = true;
  struct Parameters {
    double youngs_modulus = 0.0;  ///< E [Pa]
    double poisson_ratio = 0.3;   ///< ν
    double friction = 0.0;        ///< μ
    double damping_factor = 0.0;  ///< γ_t
  };
  explicit Mindlin(const Parameters& parameters);
  /// Reads "youngs_modulus", "poisson_ratio", "friction", "damping_factor".
  explicit Mindlin(const LawParameters& parameters);

  double stiffness(double overlap, double effective_radius) const {
    return 8.0 * effective_shear_modulus_ * std::sqrt(effective_radius * std::max(overlap, 0.0));
  }

  Vec3 spring_force(const Contact& c, const Vec3& tangential_velocity, Vec3& displacement) const {
    const double k = stiffness(c.overlap, c.effective_radius);
    if (k <= 0.0) {
      displacement.setZero();
      return Vec3::Zero();
    }
    const double damping = damping_factor_ * std::sqrt(c.effective_mass * k);
    return coulomb_limited_spring(k, damping, friction_, c.normal_force, tangential_velocity,
                                  displacement);
  }

  bool needs_history() const override { return true; }
  void evaluate(std::span<Contact> contacts, HistoryStage stage, double dt) const override {
    evaluate_with_history(*this, contacts, stage, dt);
  }

 private:
  double effective_shear_modulus_;
  double friction_;
  double damping_factor_;
};

}  // namespace grainwave::particles::dem
