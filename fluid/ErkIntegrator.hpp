#pragma once
// Explicit Runge-Kutta time integration of dy/dt = f(t, y), for a state whose length changes
// when the grid adapts. Two modes:
//   - fixed step (the default): one step of exactly the driver's dt (the CFL step), with
//     classical RK4 or the three-stage strong-stability-preserving RK3 of Shu & Osher (1988),
//     taken here on plain arrays: ARKODE's per-step work for error weights and norms, which a
//     fixed step does not use, cost 15-17% of a 2D run;
//   - error control: SUNDIALS ARKODE (ERKStep) with its embedded pair (Zonneveld 5(3)4) takes as
//     many internal steps as rtol/atol require to cover the driver's dt; the integrator is
//     created once and resized (ERKStepResize) when the number of local unknowns changes, reset
//     otherwise, never rebuilt.
// With error control the state is an N_Vector_Parallel over the run's communicator, so its norms
// are global and 1 and 2 ranks take the same internal steps; a fixed step is pointwise and needs
// no communication beyond the right-hand side's.
#include <mpi.h>

#include <cstddef>
#include <functional>
#include <span>
#include <string>

namespace grainwave::fluid {

enum class TimeScheme { kRk4, kSspRk3, kErrorControlled };

class ErkIntegrator {
 public:
  /// f(t, y, ydot): the right-hand side; it must not throw (errors are reported by return < 0).
  using Rhs = std::function<int(double, std::span<const double>, std::span<double>)>;

  ErkIntegrator(MPI_Comm comm, TimeScheme scheme, double rtol, double atol, Rhs rhs);
  ~ErkIntegrator();
  ErkIntegrator(const ErkIntegrator&) = delete;
  ErkIntegrator& operator=(const ErkIntegrator&) = delete;

  /// The state vector, sized for `local_size` unknowns on this rank (contents kept only if the
  /// size did not change). Fill it, then call step().
  std::span<double> state(std::size_t local_size);
  /// Advances the state from t to t + dt (after the caller filled state()); returns 0, or the
  /// right-hand side's or ARKODE's flag (< 0: failure), and leaves the result in state().
  int step(double t, double dt);
  /// Number of right-hand-side evaluations so far.
  long rhs_evaluations() const;
  std::string describe() const;

  struct Impl;  ///< state vectors and ARKODE's memory (opaque: keeps SUNDIALS headers out of this one)

 private:
  Impl* impl_;
};

}  // namespace grainwave::fluid
