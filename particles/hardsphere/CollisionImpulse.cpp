#include "particles/hardsphere/CollisionImpulse.hpp"

#include <fmt/format.h>

#include "core/Error.hpp"

namespace grainwave::particles::hardsphere {

namespace {
void require(bool ok, const std::string& key, const std::string& message, const std::string& hint) {
  if (!ok) throw InputError(InputLocation{"collision law", 0}, key, message, hint);
}
}  // namespace

void validate(const CollisionLaw& law, const std::string& key_prefix) {
  require(law.restitution >= 0.0 && law.restitution <= 1.0, key_prefix + ".restitution",
          fmt::format("restitution {} is outside [0, 1]", law.restitution),
          "1 is elastic, 0 perfectly plastic");
  require(law.friction >= 0.0, key_prefix + ".friction",
          fmt::format("friction coefficient {} is negative", law.friction), "use mu >= 0");
  if (law.model == RestitutionModel::kVelocityDependent) {
    require(law.plastic.yield_stress > 0.0, key_prefix + ".yield_stress",
            "yield stress must be positive", "");
    require(law.plastic.effective_modulus > 0.0, key_prefix + ".effective_modulus",
            "effective modulus must be positive", "");
    require(law.plastic.pressure_factor > 0.0, key_prefix + ".pressure_factor",
            "mean-pressure factor alpha must be positive", "3 for metals, 1 for foams (000 §2.4)");
  }
}

std::string describe(const CollisionLaw& law) {
  if (law.model == RestitutionModel::kConstant) {
    return fmt::format("hard sphere: e = {}, mu = {}", law.restitution, law.friction);
  }
  return fmt::format("hard sphere: e(v_n) plastic (Y = {}, E* = {}, alpha = {}), mu = {}",
                     law.plastic.yield_stress, law.plastic.effective_modulus,
                     law.plastic.pressure_factor, law.friction);
}

}  // namespace grainwave::particles::hardsphere
