#pragma once
// Time integration of m dv/dt = F, I dω/dt = T (002 Eqs 3.1–3.2) for the DEM.
//   VelocityVerlet   kick–drift–kick, one force evaluation per step, symplectic for
//                    position-dependent forces: the method for long elastic runs. Forces are
//                    evaluated with the predicted velocity v_n + Δt a_n so dashpots stay 2nd order.
//   RungeKutta2      Heun's second-order Runge–Kutta of 002 §3.2.3: predictor at t_n, corrector
//                    at the predicted state, trapezoidal average; two evaluations per step.
// The step is Δt = τ/N with the contact duration τ of 002 Eq. 3.17 (or the Hertz equivalent)
// for the stiffest, lightest pair and N >= 50 by default (stable_time_step). Fixed particles
// (kFixed) never move. Positions are wrapped into the box on periodic axes after each step.
//
// Domain decomposition: `before_evaluation`, when given, is called right before every force
// evaluation with the state of that moment (the drifted or predicted positions); it appends the
// ghosts the evaluation needs to the end of the store. The integrators move only the slots the
// store held when the step began, and keep their forces; the caller strips the ghosts after.
#include "particles/ParticleStore.hpp"
#include "particles/dem/ContactForceField.hpp"

#include <functional>
#include <vector>

namespace grainwave::particles::dem {

/// Called before each force evaluation of a step (ghost exchange); may append slots.
using BeforeEvaluation = std::function<void(ParticleStore&)>;

/// τ/N where τ is the shortest binary contact duration among the movable particles: each paired
/// with an identical particle (m*/2, R*/2) and with a wall (m, R).
double stable_time_step(const ParticleStore& store, const NormalLaw& law,
                        int steps_per_collision = 50);

class VelocityVerlet {
 public:
  void step(ParticleStore& store, ContactForceField& field, double dt,
            const BeforeEvaluation& before_evaluation = {});
  /// Call after particles were added or removed: forces are recomputed before the next kick.
  void reset() { have_forces_ = false; }
  /// Evaluates the forces at t_n now, as step() otherwise does first when it has none (a
  /// caller that plans the step ahead, ContactForceField::list_stale_ahead, needs them before).
  void prime(ParticleStore& store, ContactForceField& field, double dt,
             const BeforeEvaluation& before_evaluation = {});
  /// How far the coming step moves each slot: its displacement from now to the positions the
  /// step evaluates the forces at (zero for fixed particles). Needs has_forces().
  void displacement_ahead(const ParticleStore& store, double dt, std::vector<Vec3>& out) const;

  /// The forces and torques at the start of the next step (those of the last evaluation), kept
  /// by the integrator so that a restart or a removal of particles can put them back exactly
  /// instead of re-evaluating them (which would differ from the uninterrupted run in the last
  /// bits: the evaluation saw the predicted velocities).
  bool has_forces() const { return have_forces_; }
  const std::vector<Vec3>& forces() const { return force_; }
  const std::vector<Vec3>& torques() const { return torque_; }
  /// The same, to be rearranged with the store's slots (migration between ranks).
  std::vector<Vec3>& stored_forces() { return force_; }
  std::vector<Vec3>& stored_torques() { return torque_; }
  void restore_forces(std::vector<Vec3> force, std::vector<Vec3> torque) {
    force_ = std::move(force);
    torque_ = std::move(torque);
    have_forces_ = true;
  }

 private:
  bool have_forces_ = false;
  std::vector<Vec3> force_, torque_;
  // Per slot, from the first loop of step() for its second: 1/m and dt/I (each division once).
  std::vector<double> inverse_mass_, dt_over_inertia_;
};

class RungeKutta2 {
 public:
  void step(ParticleStore& store, ContactForceField& field, double dt,
            const BeforeEvaluation& before_evaluation = {});
  /// As VelocityVerlet::displacement_ahead: the corrector's evaluation is at x + Δt v (the
  /// predictor's at x itself).
  static void displacement_ahead(const ParticleStore& store, double dt, std::vector<Vec3>& out);

 private:
  std::vector<Vec3> x0_, v0_, w0_, a0_, alpha0_;
};

/// Before a step with a caller-managed Verlet list (ContactForceSettings::verlet_managed): the
/// forces of velocity Verlet at t_n when it has none (`verlet`; null for RK2), on a list
/// rebuilt first; then a rebuild unless the list serves every evaluation of the coming step
/// (ContactForceField::list_stale_ahead with the integrator's displacement_ahead). With
/// `collective`, every decision is taken over all MPI ranks at once, so all rebuild at the
/// steps the serial run does. `rebuild` does it (when distributed: migration and a full ghost
/// exchange around ContactForceField::build_list, the store left without ghosts); `refresh`
/// brings the ghosts up to date before the priming evaluation. Returns VerletList::kValid, or
/// the slot of a particle that moves more than half the skin within the step even on a fresh
/// list (the caller reports it: the step might miss a contact). `ahead` is scratch.
long prepare_listed_step(ParticleStore& store, ContactForceField& field, VelocityVerlet* verlet,
                         double dt, bool collective, const std::function<void()>& rebuild,
                         const BeforeEvaluation& refresh, std::vector<Vec3>& ahead);

}  // namespace grainwave::particles::dem
