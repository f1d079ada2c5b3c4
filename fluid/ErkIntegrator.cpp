#include "fluid/ErkIntegrator.hpp"

#include <arkode/arkode_erkstep.h>
#include <nvector/nvector_parallel.h>
#include <sundials/sundials_context.h>

#include <stdexcept>
#include <vector>

namespace grainwave::fluid {

struct ErkIntegrator::Impl {
  MPI_Comm comm;
  TimeScheme scheme;
  double rtol, atol;
  Rhs rhs;
  SUNContext context = nullptr;
  N_Vector y = nullptr;
  void* memory = nullptr;
  ARKodeButcherTable table = nullptr;
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

/// Butcher tableau of classical RK4 or SSP-RK3 (ARKODE ships neither as a named ERK table).
ARKodeButcherTable fixed_step_table(TimeScheme scheme) {
  if (scheme == TimeScheme::kRk4) {
    double c[4] = {0, 0.5, 0.5, 1};
    double A[16] = {0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 1, 0};
    double b[4] = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6};
    return ARKodeButcherTable_Create(4, 4, 0, c, A, b, nullptr);
  }
  double c[3] = {0, 1, 0.5};
  double A[9] = {0, 0, 0, 1, 0, 0, 0.25, 0.25, 0};
  double b[3] = {1.0 / 6, 1.0 / 6, 2.0 / 3};
  return ARKodeButcherTable_Create(3, 3, 0, c, A, b, nullptr);
}

}  // namespace

ErkIntegrator::ErkIntegrator(MPI_Comm comm, TimeScheme scheme, double rtol, double atol, Rhs rhs)
    : impl_(new Impl{comm, scheme, rtol, atol, std::move(rhs)}) {
  check(SUNContext_Create(&impl_->comm, &impl_->context), "SUNContext_Create");
}

ErkIntegrator::~ErkIntegrator() {
  if (impl_->memory) ERKStepFree(&impl_->memory);
  if (impl_->table) ARKodeButcherTable_Free(impl_->table);
  if (impl_->y) N_VDestroy(impl_->y);
  SUNContext_Free(&impl_->context);
  delete impl_;
}

namespace {
int arkode_rhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  auto* impl = static_cast<ErkIntegrator::Impl*>(user);
  const auto n = static_cast<std::size_t>(N_VGetLocalLength_Parallel(y));
  ++impl->evaluations;
  try {
    return impl->rhs(t, std::span<const double>(N_VGetArrayPointer_Parallel(y), n),
                     std::span<double>(N_VGetArrayPointer_Parallel(ydot), n));
  } catch (...) {  // never unwind through ARKODE's C frames
    return -1;
  }
}
}  // namespace

std::span<double> ErkIntegrator::state(std::size_t local_size) {
  Impl& m = *impl_;
  if (m.scheme != TimeScheme::kErrorControlled) {
    if (m.state.size() != local_size) {
      for (auto* v : {&m.state, &m.stage, &m.k1, &m.k2, &m.k3}) v->assign(local_size, 0.0);
    }
    return {m.state.data(), m.state.size()};
  }
  // Collective: every rank resizes when any rank's share changed, so all take the same ARKODE
  // path (ERKStepResize or ERKStepReset) and its global reductions stay matched.
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
int fixed_step(ErkIntegrator::Impl& m, double t, double dt) {
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

int ErkIntegrator::step(double t, double dt) {
  Impl& m = *impl_;
  if (m.scheme != TimeScheme::kErrorControlled) {
    // ARKODE's per-step overhead for a fixed step (error weights, norms and vector reductions
    // it does not need here) was 15-17% of a 2D run: fixed steps are taken here instead.
    try {
      return fixed_step(m, t, dt);
    } catch (...) {
      return -1;  // as through ARKODE: the caller reports a failed step
    }
  }
  if (!m.memory) {
    m.memory = ERKStepCreate(arkode_rhs, t, m.y, m.context);
    if (!m.memory) throw std::runtime_error("ARKODE: ERKStepCreate failed");
    check(ERKStepSetUserData(m.memory, &m), "ERKStepSetUserData");
    check(ERKStepSetMaxNumSteps(m.memory, 100000), "ERKStepSetMaxNumSteps");
    if (m.scheme == TimeScheme::kErrorControlled) {
      check(ERKStepSetTableNum(m.memory, ARKODE_ZONNEVELD_5_3_4), "ERKStepSetTableNum");
      check(ERKStepSStolerances(m.memory, m.rtol, m.atol), "ERKStepSStolerances");
    } else {
      m.table = fixed_step_table(m.scheme);
      check(ERKStepSetTable(m.memory, m.table), "ERKStepSetTable");
    }
  } else if (m.size_changed) {
    // The grid adapted: same integrator, vectors of the new length.
    check(ERKStepResize(m.memory, m.y, 1.0, t, nullptr, nullptr), "ERKStepResize");
  } else {
    check(ERKStepReset(m.memory, t, m.y), "ERKStepReset");
  }
  m.size_changed = false;
  if (m.scheme != TimeScheme::kErrorControlled) check(ERKStepSetFixedStep(m.memory, dt), "ERKStepSetFixedStep");
  check(ERKStepSetStopTime(m.memory, t + dt), "ERKStepSetStopTime");
  double reached = t;
  return ERKStepEvolve(m.memory, t + dt, m.y, &reached, ARK_NORMAL);
}

long ErkIntegrator::rhs_evaluations() const { return impl_->evaluations; }

std::string ErkIntegrator::describe() const {
  switch (impl_->scheme) {
    case TimeScheme::kRk4: return "classical RK4, CFL step";
    case TimeScheme::kSspRk3: return "SSP-RK3 (Shu-Osher), CFL step";
    default:
      return "ARKODE ERKStep, Zonneveld 5(3)4 with error control (rtol " + std::to_string(impl_->rtol) + ", atol " +
             std::to_string(impl_->atol) + ")";
  }
}

}  // namespace grainwave::fluid
