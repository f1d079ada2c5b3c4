#pragma once
// The box a particle system lives in, as scene parameters: dimension, box_lo/box_hi, the kind of
// each face (boundary_x/y/z) and the gravitational acceleration. Declared and read once here
// for every particle system ([particles], [dem]); errors point at the offending key.
#include <string>
#include <vector>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "particles/Domain.hpp"

namespace grainwave::particles {

struct BoxDefaults {
  std::string length_unit;             ///< appended to the docs, e.g. " [m]"; empty: scaled units
  std::vector<double> gravity{0, 0, 0};
};

void declare_box(SectionDecl& section, const BoxDefaults& defaults);

/// Reads the box into a Domain and the gravity vector (2D: z components must be zero).
Domain read_box(const SceneSection& section, Eigen::Vector3d& gravity);

}  // namespace grainwave::particles
