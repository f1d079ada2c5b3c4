#pragma once
// Coulomb-limited linear tangential spring with stored displacement, 002 Eqs 3.12 and 3.15
// (Cundall & Strack; 000 Eq. 2.14 plus damping): F_t = k_t δ_t + η_t v_t on i, |F_t| ≤ μ f_n,
// δ_t = ∫ v_t dt kept per contact and rotated into the current contact plane every step.
// In the slip branch the force keeps the direction of the trial spring force (rather than t_ji
// of Eq. 3.12), so that sticking and slipping join continuously. η_t = γ_t sqrt(m* k_t).
#include "particles/dem/TangentialSpring.hpp"

namespace grainwave::particles::dem {

class CoulombSpring final : public TangentialLaw {
 public:
  /// Whether the law reads Contact::effective_radius (the fused pass computes it only then).
  static constexpr bool kReadsEffectiveRadius = false;
  struct Parameters {
    double stiffness = 0.0;       ///< k_t [N/m]
    double friction = 0.0;        ///< μ
    double damping_factor = 0.0;  ///< γ_t
  };
  explicit CoulombSpring(const Parameters& parameters);
  /// Reads "stiffness", "friction", "damping_factor".
  explicit CoulombSpring(const LawParameters& parameters);

  Vec3 spring_force(const Contact& c, const Vec3& tangential_velocity, Vec3& displacement) const {
    const double damping = damping_factor_ * std::sqrt(c.effective_mass * stiffness_);
    return coulomb_limited_spring(stiffness_, damping, friction_, c.normal_force,
                                  tangential_velocity, displacement);
  }

  double stiffness() const { return stiffness_; }
  double friction() const { return friction_; }
  double damping_factor() const { return damping_factor_; }

  bool needs_history() const override { return true; }
  void evaluate(std::span<Contact> contacts, HistoryStage stage, double dt) const override {
    evaluate_with_history(*this, contacts, stage, dt);
  }

 private:
  double stiffness_;
  double friction_;
  double damping_factor_;
};

}  // namespace grainwave::particles::dem
