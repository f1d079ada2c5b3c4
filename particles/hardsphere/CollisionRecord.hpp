#pragma once
// One processed impulse, as the colliders log it (for tests, statistics and output).
#include <cstdint>

namespace grainwave::particles::hardsphere {

struct CollisionRecord {
  double time;  ///< RetrospectiveCollider: from the start of the step; EventDrivenCollider: absolute
  std::int64_t id_a;
  std::int64_t id_b;  ///< partner's id, or -1 - face (face = 2 axis + side) for a wall
};

}  // namespace grainwave::particles::hardsphere
