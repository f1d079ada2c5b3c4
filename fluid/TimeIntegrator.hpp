#pragma once
// Runge-Kutta time integration of dy/dt = f_E(t, y) + f_I(t, y), for a state whose length
// changes when the grid adapts. Modes:
//   - fixed step (the default): one step of exactly the driver's dt (the CFL step), with
//     classical RK4 or the three-stage strong-stability-preserving RK3 of Shu & Osher (1988),
//     taken here on plain arrays: ARKODE's per-step work for error weights and norms, which a
//     fixed step does not use, cost 15-17% of a 2D run;
//   - error control: SUNDIALS ARKODE (ERKStep) with its embedded pair (Zonneveld 5(3)4) takes as
//     many internal steps as rtol/atol require to cover the driver's dt;
//   - IMEX: SUNDIALS ARKODE (ARKStep) with the additive pair ARK4(3)6L[2]SA of Kennedy &
//     Carpenter (Appl. Numer. Math. 44, 2003): f_E explicit, the stiff f_I by its L-stable
//     diagonally implicit stages, one step of the driver's dt. Each stage's nonlinear system
//     y - gamma f_I(y) = rhs is solved by Newton's method (ARKODE's default), the linear systems
//     by matrix-free GMRES (SUNLinSol_SPGMR, Jacobian-vector products by ARKODE's difference
//     quotients of f_I) with the caller's preconditioner, an approximate solve of
//     (I - gamma J_I) z = r. With a pointwise f_I (the Brinkman relaxation) the preconditioner
//     is the exact block-diagonal inverse and GMRES converges in one iteration; implicit viscous
//     terms are not in the preconditioner, and GMRES (10 vectors, up to 5 restarts) iterates.
// ARKODE's integrators are created once and resized (ERKStepResize/ARKStepResize, with a new
// Krylov solver of the new length) when the number of local unknowns changes, reset otherwise,
// never rebuilt. Under ARKODE the state is an N_Vector_Parallel over the run's communicator, so
// its norms are global and 1 and 2 ranks take the same internal steps and iterations; a fixed
// step is pointwise and needs no communication beyond the right-hand side's.
#include <mpi.h>

#include <cstddef>
#include <functional>
#include <span>
#include <string>

namespace grainwave::fluid {

enum class TimeScheme { kRk4, kSspRk3, kErrorControlled, kImex };

class TimeIntegrator {
 public:
  /// f(t, y, ydot): a right-hand side; it must not throw (errors are reported by return < 0).
  using Rhs = std::function<int(double, std::span<const double>, std::span<double>)>;
  /// The implicit part of an IMEX scheme: f_I, and solve(t, y, r, z, gamma), an approximate
  /// solution of (I - gamma df_I/dy) z = r used as GMRES's preconditioner (empty: none).
  struct Implicit {
    Rhs rhs;
    std::function<int(double, std::span<const double>, std::span<const double>, std::span<double>, double)> solve;
  };

  /// rhs: the whole right-hand side, or the explicit part f_E under kImex (implicit: f_I then).
  TimeIntegrator(MPI_Comm comm, TimeScheme scheme, double rtol, double atol, Rhs rhs, Implicit implicit = {});
  ~TimeIntegrator();
  TimeIntegrator(const TimeIntegrator&) = delete;
  TimeIntegrator& operator=(const TimeIntegrator&) = delete;

  /// The state vector, sized for `local_size` unknowns on this rank (contents kept only if the
  /// size did not change). Fill it, then call step().
  std::span<double> state(std::size_t local_size);
  /// Advances the state from t to t + dt (after the caller filled state()); returns 0, or the
  /// right-hand side's or ARKODE's flag (< 0: failure), and leaves the result in state().
  /// Under kRk4 and kSspRk3 the first call of the right-hand side is f(t, y) with y the very
  /// span state() returned, unchanged since the caller filled it (FluidSystem relies on this to
  /// skip unpacking it); ARKODE's schemes call it on vectors of their own.
  int step(double t, double dt);
  /// Number of evaluations of the (explicit) right-hand side so far.
  long rhs_evaluations() const;
  /// IMEX: evaluations of f_I, Newton iterations and GMRES iterations so far (zeros otherwise).
  struct ImplicitCounts {
    long rhs_evaluations = 0, newton_iterations = 0, linear_iterations = 0;
  };
  ImplicitCounts implicit_counts() const;
  TimeScheme scheme() const;
  /// kRk4 or kSspRk3: fixed CFL steps taken here, not by ARKODE (see step()).
  bool takes_fixed_steps() const { return scheme() == TimeScheme::kRk4 || scheme() == TimeScheme::kSspRk3; }
  std::string describe() const;

  struct Impl;  ///< state vectors and ARKODE's memory (opaque: keeps SUNDIALS headers out of this one)

 private:
  Impl* impl_;
};

}  // namespace grainwave::fluid
