#pragma once
// The compressible flow solver on the wavelet-adaptive grid as a runnable system, built from a
// scene's [fluid] section: the compressible Navier-Stokes equations of 002 Eqs 2.1-2.7 (Euler
// when the scene sets no Reynolds number) with the inviscid terms in the flux form of the split
// of SplitConvection.hpp (localised shock capturing, positivity limiter), the viscous terms of
// ViscousTerms.hpp, both as per-block kernels (BlockKernels.hpp), boundary conditions of
// FluidBoundaries.hpp, explicit RK or ARKODE's IMEX in time (TimeIntegrator.hpp), and the AWCM
// cycle of 002 §2.2.2 every step (or every adapt_every steps), on the conserved variables (rho,
// rho u, E), each group normalised by its global max: the initial grid gets its safety zone
// (significant blocks refined, their adjacent zone), then each cycle is step -> coarsen ->
// refine, the safety zone kept where the refine pass would add it again
// (AdaptiveGrid::adapt_cycle).
#include <memory>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"

namespace grainwave::fluid {

class FluidSystem {
 public:
  /// Declares the [fluid] section.
  static void declare(SceneSchema& schema);
  /// Builds the system of the scene's dimension.
  static std::unique_ptr<io::System> create(const Scene& scene);
};

}  // namespace grainwave::fluid
