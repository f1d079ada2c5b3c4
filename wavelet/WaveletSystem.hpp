#pragma once
// The adaptive grid on its own, as a runnable system: a prescribed profile (a planar front, or a
// smoothed disc/sphere u = (1 - tanh((r - R) / w)) / 2) translating at constant velocity across
// the domain, sampled on the wavelet-adaptive grid and adapted every step with the AWCM cycle of
// 002 §2.2.2 (refine the significant blocks and their adjacent zone -> move -> coarsen the
// insignificant ones). It exercises and measures what the fluid solver will rely on: error
// control (reconstruction to the finest uniform grid against the exact profile), compression,
// ghosts and derivatives (du/dx on every active point against the exact derivative), MPI
// distribution, output and restart. Built from the scene's [wavelet] section.
#include <memory>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"

namespace grainwave::wavelet {

class WaveletSystem {
 public:
  /// Declares the [wavelet] section.
  static void declare(SceneSchema& schema);
  /// Builds the system of the scene's dimension.
  static std::unique_ptr<io::System> create(const Scene& scene);
};

}  // namespace grainwave::wavelet
