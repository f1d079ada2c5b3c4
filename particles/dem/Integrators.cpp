#include "particles/dem/Integrators.hpp"

#include "core/Mpi.hpp"
#include "particles/dem/SlabDecomposition.hpp"

#include <algorithm>
#include <limits>

namespace grainwave::particles::dem {

double stable_time_step(const ParticleStore& store, const NormalLaw& law, int steps_per_collision) {
  double tau = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < store.size(); ++i) {
    if (store.is_fixed(i)) continue;
    const double m = store.mass[i], r = store.radius[i];
    tau = std::min({tau, law.contact_duration(0.5 * m, 0.5 * r), law.contact_duration(m, r)});
  }
  return tau / steps_per_collision;
}

namespace {
/// The ghosts (if a hook is given), then the forces.
void evaluate_forces(ParticleStore& store, ContactForceField& field, HistoryStage stage, double dt,
                     const BeforeEvaluation& before_evaluation) {
  if (before_evaluation) before_evaluation(store);
  field.evaluate(store, stage, dt);
}
}  // namespace

void VelocityVerlet::prime(ParticleStore& store, ContactForceField& field, double dt,
                           const BeforeEvaluation& before_evaluation) {
  const std::size_t n = store.size();
  // Forces at t_n without advancing the tangential history (no time has passed yet).
  evaluate_forces(store, field, HistoryStage::kPredict, dt, before_evaluation);
  force_.assign(field.force().begin(), field.force().begin() + static_cast<std::ptrdiff_t>(n));
  torque_.assign(field.torque().begin(), field.torque().begin() + static_cast<std::ptrdiff_t>(n));
  have_forces_ = true;
}

void VelocityVerlet::displacement_ahead(const ParticleStore& store, double dt, std::vector<Vec3>& out) const {
  // The drift of step(), written the same way.
  const std::size_t n = std::min(store.size(), force_.size());
  out.resize(n);
  // Through local pointers, as in step().
  Vec3* const drift = out.data();
  const Vec3* const v = store.velocity.data();
  const Vec3* const f = force_.data();
  for (std::size_t i = 0; i < n; ++i) {
    const double inv_m = store.inverse_mass(i);
    drift[i] = inv_m == 0.0 ? Vec3::Zero() : Vec3(dt * (v[i] + (0.5 * dt * inv_m) * f[i]));
  }
}

void RungeKutta2::displacement_ahead(const ParticleStore& store, double dt, std::vector<Vec3>& out) {
  out.resize(store.size());
  for (std::size_t i = 0; i < store.size(); ++i)
    out[i] = store.inverse_mass(i) == 0.0 ? Vec3::Zero() : Vec3(dt * store.velocity[i]);
}

void VelocityVerlet::step(ParticleStore& store, ContactForceField& field, double dt,
                          const BeforeEvaluation& before_evaluation) {
  // The slots this step moves: those held before any ghost is appended.
  const std::size_t n = store.size();
  auto evaluate = [&](HistoryStage stage) { evaluate_forces(store, field, stage, dt, before_evaluation); };
  if (!have_forces_ || force_.size() != n) {
    prime(store, field, dt, before_evaluation);
  }
  // Kick and drift, then a second kick with the old forces: the velocities seen by the force
  // evaluation are the prediction v_n + Δt a_n of v_{n+1} rather than the half-step velocity,
  // so velocity-dependent forces (dashpots, drag) are second-order accurate; the final kick
  // swaps the old half of the acceleration for the new one. One fused loop.
  // force_ and torque_ keep the old forces until the second kick has used them.
  inverse_mass_.resize(n);
  dt_over_inertia_.resize(n);
  const Domain& domain = field.domain();
  const Domain::WrapFreeBox stays = domain.wrap_free_box();
  // The arrays through pointers held in registers: Eigen's vector stores may alias anything, so
  // the compiler would otherwise load every array's address again after each of them.
  double* const inverse_mass = inverse_mass_.data();
  double* const dt_over_inertia = dt_over_inertia_.data();
  Vec3* const kept_force = force_.data();
  Vec3* const kept_torque = torque_.data();
  {
    Vec3* const x = store.position.data();
    Vec3* const v = store.velocity.data();
    Vec3* const w = store.angular_velocity.data();
    const double* const inertia = store.inertia.data();
    for (std::size_t i = 0; i < n; ++i) {
      const double inv_m = store.inverse_mass(i);
      inverse_mass[i] = inv_m;
      if (inv_m == 0.0) continue;
      const Vec3 half_kick = (0.5 * dt * inv_m) * kept_force[i];
      x[i] += dt * (v[i] + half_kick);
      if (stays.outside(x[i])) domain.wrap(x[i]);
      v[i] += 2.0 * half_kick;
      dt_over_inertia[i] = dt / inertia[i];
      w[i] += dt_over_inertia[i] * kept_torque[i];
    }
  }
  evaluate(HistoryStage::kSingle);
  // The evaluation may append ghosts to the store, moving its arrays: their addresses again.
  Vec3* const v = store.velocity.data();
  Vec3* const w = store.angular_velocity.data();
  const Vec3* const f = field.force().data();
  const Vec3* const t = field.torque().data();
  for (std::size_t i = 0; i < n; ++i) {
    // The evaluation keeps the first n slots as they were, so the step's own 1/m and dt/I
    // still belong to them. (0.5 dt) / I is 0.5 (dt / I) exactly: halving rounds nothing.
    const double inv_m = inverse_mass[i];
    if (inv_m != 0.0) {
      v[i] += (0.5 * dt * inv_m) * (f[i] - kept_force[i]);
      w[i] += (0.5 * dt_over_inertia[i]) * (t[i] - kept_torque[i]);
    }
    kept_force[i] = f[i];
    kept_torque[i] = t[i];
  }
}

void RungeKutta2::step(ParticleStore& store, ContactForceField& field, double dt,
                       const BeforeEvaluation& before_evaluation) {
  const std::size_t n = store.size();
  auto evaluate = [&](HistoryStage stage) { evaluate_forces(store, field, stage, dt, before_evaluation); };
  x0_.assign(store.position.begin(), store.position.end());
  v0_.assign(store.velocity.begin(), store.velocity.end());
  w0_.assign(store.angular_velocity.begin(), store.angular_velocity.end());
  a0_.resize(n);
  alpha0_.resize(n);

  evaluate(HistoryStage::kPredict);
  for (std::size_t i = 0; i < n; ++i) {
    const double inv_m = store.inverse_mass(i);
    if (inv_m == 0.0) continue;
    a0_[i] = inv_m * field.force()[i];
    alpha0_[i] = field.torque()[i] / store.inertia[i];
    store.position[i] = x0_[i] + dt * v0_[i];
    store.velocity[i] = v0_[i] + dt * a0_[i];
    store.angular_velocity[i] = w0_[i] + dt * alpha0_[i];
  }
  // The predicted positions are evaluated unwrapped: separations use the minimum image and the
  // cells wrap indices, so a centre slightly outside a periodic box is found correctly.
  evaluate(HistoryStage::kCorrect);
  const Domain& domain = field.domain();
  const Domain::WrapFreeBox stays = domain.wrap_free_box();
  for (std::size_t i = 0; i < n; ++i) {
    const double inv_m = store.inverse_mass(i);
    if (inv_m == 0.0) continue;
    store.position[i] = x0_[i] + 0.5 * dt * (v0_[i] + store.velocity[i]);
    store.velocity[i] = v0_[i] + (0.5 * dt) * (a0_[i] + inv_m * field.force()[i]);
    store.angular_velocity[i] =
        w0_[i] + (0.5 * dt) * (alpha0_[i] + field.torque()[i] / store.inertia[i]);
    if (stays.outside(store.position[i])) domain.wrap(store.position[i]);
  }
}

long prepare_listed_step(ParticleStore& store, ContactForceField& field, VelocityVerlet* verlet,
                         double dt, bool collective, const std::function<void()>& rebuild,
                         const BeforeEvaluation& refresh, std::vector<Vec3>& ahead) {
  auto everywhere = [collective](bool local) { return collective ? mpi::any(local) : local; };
  if (verlet && everywhere(!verlet->has_forces())) {
    rebuild();
    verlet->prime(store, field, dt, refresh);
    SlabDecomposition::strip_ghosts(store);  // those the priming evaluation appended
  }
  long why = VerletList::kValid;
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (verlet) verlet->displacement_ahead(store, dt, ahead);
    else RungeKutta2::displacement_ahead(store, dt, ahead);
    why = field.list_stale_ahead(store, ahead);
    if (!everywhere(why != VerletList::kValid)) return VerletList::kValid;
    if (attempt == 0) rebuild();
  }
  return why >= 0 ? why : VerletList::kValid;
}

}  // namespace grainwave::particles::dem
