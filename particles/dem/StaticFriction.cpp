#include "particles/dem/StaticFriction.hpp"

#include "core/Error.hpp"

namespace grainwave::particles::dem {

StaticFriction::StaticFriction(const Parameters& parameters)
    : friction_(parameters.friction), regularization_speed_(parameters.regularization_speed) {
  const InputLocation where{"contact law 'static_friction'", 0};
  if (!(friction_ >= 0.0)) throw InputError(where, "friction", "must be >= 0");
  if (!(regularization_speed_ >= 0.0))
    throw InputError(where, "regularization_speed", "must be >= 0");
}

StaticFriction::StaticFriction(const LawParameters& parameters)
    : StaticFriction(Parameters{parameters.get("friction", "static_friction"),
                                parameters.get_or("regularization_speed", 0.0)}) {}

extern const bool kStaticFrictionRegistered = tangential_law_registry().add(
    "static_friction", [](const LawParameters& parameters) -> std::unique_ptr<TangentialLaw> {
      return std::make_unique<StaticFriction>(parameters);
    });

}  // namespace grainwave::particles::dem
