#include "fluid/TimeIntegrator.hpp"

#include <arkode/arkode_arkstep.h>
#include <arkode/arkode_erkstep.h>
#include <nvector/nvector_parallel.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_spgmr.h>

#include <stdexcept>
#include <vector>

namespace grainwave::fluid {

struct TimeIntegrator::Impl {
  MPI_Comm comm;
  TimeScheme scheme;
  double rtol, atol;
  Rhs rhs;
  Implicit implicit;
  SUNContext context = nullptr;
  N_Vector y = nullptr;
  void* memory = nullptr;           // ERKStep (error control) or ARKStep (IMEX)
  SUNLinearSolver krylov = nullptr;  // IMEX: GMRES on vectors of the current length
  std::size_t size = 0;
  bool size_changed = true;
  long evaluations = 0;
  // Fixed step: the state and stage vectors, stepped here (no N_Vector).
  std::vector<double> state{}, stage{}, k1{}, k2{}, k3{};
};

namespace {

void check(int flag, const char* what) {
  if (flag < 0) throw std::runtime_error(std::string("ARKODE: ") + what + " failed (flag " + std::to_string(flag) + ")");
}

}  // namespace

TimeIntegrator::TimeIntegrator(MPI_Comm comm, TimeScheme scheme, double rtol, double atol, Rhs rhs, Implicit implicit)
    : impl_(new Impl{comm, scheme, rtol, atol, std::move(rhs), std::move(implicit)}) {
  if (scheme == TimeScheme::kImex && !impl_->implicit.rhs) throw std::invalid_argument("IMEX needs an implicit part");
  check(SUNContext_Create(&impl_->comm, &impl_->context), "SUNContext_Create");
}

TimeIntegrator::~TimeIntegrator() {
  if (impl_->memory) {
    if (impl_->scheme == TimeScheme::kImex)
      ARKStepFree(&impl_->memory);
    else
      ERKStepFree(&impl_->memory);
  }
  if (impl_->krylov) SUNLinSolFree(impl_->krylov);
  if (impl_->y) N_VDestroy(impl_->y);
  SUNContext_Free(&impl_->context);
  delete impl_;
}

namespace {
std::span<const double> view(N_Vector v) {
  return {N_VGetArrayPointer_Parallel(v), static_cast<std::size_t>(N_VGetLocalLength_Parallel(v))};
}
std::span<double> mutable_view(N_Vector v) {
  return {N_VGetArrayPointer_Parallel(v), static_cast<std::size_t>(N_VGetLocalLength_Parallel(v))};
}

int arkode_rhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  auto* impl = static_cast<TimeIntegrator::Impl*>(user);
  ++impl->evaluations;
  try {
    return impl->rhs(t, view(y), mutable_view(ydot));
  } catch (...) {  // never unwind through ARKODE's C frames
    return -1;
  }
}

int arkode_implicit_rhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  auto* impl = static_cast<TimeIntegrator::Impl*>(user);
  try {
    return impl->implicit.rhs(t, view(y), mutable_view(ydot));
  } catch (...) {
    return -1;
  }
}

int arkode_preconditioner_solve(realtype t, N_Vector y, N_Vector, N_Vector r, N_Vector z, realtype gamma, realtype,
                                int, void* user) {
  auto* impl = static_cast<TimeIntegrator::Impl*>(user);
  try {
    return impl->implicit.solve(t, view(y), view(r), mutable_view(z), gamma);
  } catch (...) {
    return -1;
  }
}
}  // namespace

std::span<double> TimeIntegrator::state(std::size_t local_size) {
  Impl& m = *impl_;
  if (takes_fixed_steps()) {
    if (m.state.size() != local_size) {
      for (auto* v : {&m.state, &m.stage, &m.k1, &m.k2, &m.k3}) v->assign(local_size, 0.0);
    }
    return {m.state.data(), m.state.size()};
  }
  // Collective: every rank resizes when any rank's share changed, so all take the same ARKODE
  // path (ERKStep/ARKStep Resize or Reset) and its global reductions stay matched.
  int changed = (!m.y || local_size != m.size) ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_LOR, m.comm);
  if (changed) {
    if (m.y) N_VDestroy(m.y);
    const auto local = static_cast<sunindextype>(local_size);
    sunindextype global = 0;
    MPI_Allreduce(&local, &global, 1, MPI_INT64_T, MPI_SUM, m.comm);
    m.y = N_VNew_Parallel(m.comm, local, global, m.context);
    if (!m.y) throw std::runtime_error("ARKODE: cannot allocate the state vector");
    m.size = local_size;
    m.size_changed = true;
  }
  return {N_VGetArrayPointer_Parallel(m.y), m.size};
}

namespace {

/// One fixed step of classical RK4 or SSP-RK3 on m.state. Pointwise, so no reduction and no
/// message: ranks only meet in the right-hand side. The stage values follow the Butcher tables
/// (RK4: c = 0, 1/2, 1/2, 1; SSP-RK3 in Shu-Osher form: y1 = y + dt f(y),
/// y2 = 3/4 y + 1/4 (y1 + dt f(y1)), y + = 1/3 y + 2/3 (y2 + dt f(y2))).
int fixed_step(TimeIntegrator::Impl& m, double t, double dt) {
  const std::size_t n = m.state.size();
  double* y = m.state.data();
  double* z = m.stage.data();
  double* k1 = m.k1.data();
  double* k2 = m.k2.data();
  double* k3 = m.k3.data();
  auto f = [&](double time, const double* from, double* to) {
    ++m.evaluations;
    return m.rhs(time, std::span<const double>(from, n), std::span<double>(to, n));
  };
  int flag = 0;
  if (m.scheme == TimeScheme::kRk4) {
    if ((flag = f(t, y, k1)) != 0) return flag;
    for (std::size_t i = 0; i < n; ++i) z[i] = y[i] + 0.5 * dt * k1[i];
    if ((flag = f(t + 0.5 * dt, z, k2)) != 0) return flag;
    for (std::size_t i = 0; i < n; ++i) z[i] = y[i] + 0.5 * dt * k2[i];
    if ((flag = f(t + 0.5 * dt, z, k3)) != 0) return flag;
    for (std::size_t i = 0; i < n; ++i) {
      z[i] = y[i] + dt * k3[i];
      k1[i] += 2 * (k2[i] + k3[i]);  // k1 + 2 k2 + 2 k3: k2 and k3 are free again
    }
    if ((flag = f(t + dt, z, k2)) != 0) return flag;
    for (std::size_t i = 0; i < n; ++i) y[i] += dt / 6 * (k1[i] + k2[i]);
    return 0;
  }
  if ((flag = f(t, y, k1)) != 0) return flag;
  for (std::size_t i = 0; i < n; ++i) z[i] = y[i] + dt * k1[i];
  if ((flag = f(t + dt, z, k2)) != 0) return flag;
  for (std::size_t i = 0; i < n; ++i) z[i] = 0.75 * y[i] + 0.25 * (z[i] + dt * k2[i]);
  if ((flag = f(t + 0.5 * dt, z, k3)) != 0) return flag;
  for (std::size_t i = 0; i < n; ++i) y[i] = y[i] / 3 + 2.0 / 3 * (z[i] + dt * k3[i]);
  return 0;
}

}  // namespace

namespace {

/// One IMEX step of exactly dt by ARKStep (created on first use, resized or reset after).
int imex_step(TimeIntegrator::Impl& m, double t, double dt) {
  auto attach_krylov = [&] {
    // GMRES's Krylov vectors have the state's length: a new solver after every resize.
    if (m.krylov) SUNLinSolFree(m.krylov);
    m.krylov = SUNLinSol_SPGMR(m.y, m.implicit.solve ? SUN_PREC_LEFT : SUN_PREC_NONE, 10, m.context);
    if (!m.krylov) throw std::runtime_error("ARKODE: cannot create the GMRES solver");
    // 10 Krylov vectors (each as long as the state), restarted up to 5 times: stiff implicit
    // terms without an exact preconditioner (diffusion) get up to 60 iterations.
    check(SUNLinSol_SPGMRSetMaxRestarts(m.krylov, 5), "SUNLinSol_SPGMRSetMaxRestarts");
    check(ARKStepSetLinearSolver(m.memory, m.krylov, nullptr), "ARKStepSetLinearSolver");
    if (m.implicit.solve) check(ARKStepSetPreconditioner(m.memory, nullptr, arkode_preconditioner_solve), "ARKStepSetPreconditioner");
  };
  if (!m.memory) {
    m.memory = ARKStepCreate(arkode_rhs, arkode_implicit_rhs, t, m.y, m.context);
    if (!m.memory) throw std::runtime_error("ARKODE: ARKStepCreate failed");
    check(ARKStepSetUserData(m.memory, &m), "ARKStepSetUserData");
    check(ARKStepSetMaxNumSteps(m.memory, 100000), "ARKStepSetMaxNumSteps");
    check(ARKStepSetTableNum(m.memory, ARKODE_ARK436L2SA_DIRK_6_3_4, ARKODE_ARK436L2SA_ERK_6_3_4), "ARKStepSetTableNum");
    // The tolerances weight the Newton and GMRES convergence tests (the step itself is fixed).
    check(ARKStepSStolerances(m.memory, m.rtol, m.atol), "ARKStepSStolerances");
    // f_I at a solved stage follows from the stage equation itself: one f_I call less per stage.
    check(ARKStepSetDeduceImplicitRhs(m.memory, SUNTRUE), "ARKStepSetDeduceImplicitRhs");
    attach_krylov();
  } else if (m.size_changed) {
    check(ARKStepResize(m.memory, m.y, 1.0, t, nullptr, nullptr), "ARKStepResize");
    attach_krylov();
  } else {
    check(ARKStepReset(m.memory, t, m.y), "ARKStepReset");
  }
  m.size_changed = false;
  check(ARKStepSetFixedStep(m.memory, dt), "ARKStepSetFixedStep");
  check(ARKStepSetStopTime(m.memory, t + dt), "ARKStepSetStopTime");
  double reached = t;
  return ARKStepEvolve(m.memory, t + dt, m.y, &reached, ARK_NORMAL);
}

}  // namespace

int TimeIntegrator::step(double t, double dt) {
  Impl& m = *impl_;
  if (takes_fixed_steps()) {
    // ARKODE's per-step overhead for a fixed step (error weights, norms and vector reductions
    // it does not need here) was 15-17% of a 2D run: fixed steps are taken here instead.
    try {
      return fixed_step(m, t, dt);
    } catch (...) {
      return -1;  // as through ARKODE: the caller reports a failed step
    }
  }
  if (m.scheme == TimeScheme::kImex) return imex_step(m, t, dt);
  if (!m.memory) {
    m.memory = ERKStepCreate(arkode_rhs, t, m.y, m.context);
    if (!m.memory) throw std::runtime_error("ARKODE: ERKStepCreate failed");
    check(ERKStepSetUserData(m.memory, &m), "ERKStepSetUserData");
    check(ERKStepSetMaxNumSteps(m.memory, 100000), "ERKStepSetMaxNumSteps");
    check(ERKStepSetTableNum(m.memory, ARKODE_ZONNEVELD_5_3_4), "ERKStepSetTableNum");
    check(ERKStepSStolerances(m.memory, m.rtol, m.atol), "ERKStepSStolerances");
  } else if (m.size_changed) {
    // The grid adapted: same integrator, vectors of the new length.
    check(ERKStepResize(m.memory, m.y, 1.0, t, nullptr, nullptr), "ERKStepResize");
  } else {
    check(ERKStepReset(m.memory, t, m.y), "ERKStepReset");
  }
  m.size_changed = false;
  check(ERKStepSetStopTime(m.memory, t + dt), "ERKStepSetStopTime");
  double reached = t;
  return ERKStepEvolve(m.memory, t + dt, m.y, &reached, ARK_NORMAL);
}

long TimeIntegrator::rhs_evaluations() const { return impl_->evaluations; }

TimeIntegrator::ImplicitCounts TimeIntegrator::implicit_counts() const {
  ImplicitCounts counts;
  if (impl_->scheme != TimeScheme::kImex || !impl_->memory) return counts;
  long explicit_calls = 0, implicit_calls = 0;
  ARKStepGetNumRhsEvals(impl_->memory, &explicit_calls, &implicit_calls);
  ARKStepGetNumNonlinSolvIters(impl_->memory, &counts.newton_iterations);
  ARKStepGetNumLinIters(impl_->memory, &counts.linear_iterations);
  counts.rhs_evaluations = implicit_calls;
  return counts;
}

TimeScheme TimeIntegrator::scheme() const { return impl_->scheme; }

std::string TimeIntegrator::describe() const {
  switch (impl_->scheme) {
    case TimeScheme::kRk4: return "classical RK4, CFL step";
    case TimeScheme::kSspRk3: return "SSP-RK3 (Shu-Osher), CFL step";
    case TimeScheme::kImex:
      return "ARKODE ARKStep IMEX, ARK4(3)6L[2]SA, CFL step; implicit stages by Newton + preconditioned GMRES";
    default:
      return "ARKODE ERKStep, Zonneveld 5(3)4 with error control (rtol " + std::to_string(impl_->rtol) + ", atol " +
             std::to_string(impl_->atol) + ")";
  }
}

}  // namespace grainwave::fluid
