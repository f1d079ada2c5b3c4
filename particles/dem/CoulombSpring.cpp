#include "particles/dem/CoulombSpring.hpp"

#include "core/Error.hpp"

namespace grainwave::particles::dem {

CoulombSpring::CoulombSpring(const Parameters& parameters)
    : stiffness_(parameters.stiffness),
      friction_(parameters.friction),
      damping_factor_(parameters.damping_factor) {
  const InputLocation where{"contact law 'coulomb_spring'", 0};
  if (!(stiffness_ > 0.0)) throw InputError(where, "stiffness", "must be > 0");
  if (!(friction_ >= 0.0)) throw InputError(where, "friction", "must be >= 0");
  if (!(damping_factor_ >= 0.0)) throw InputError(where, "damping_factor", "must be >= 0");
}

CoulombSpring::CoulombSpring(const LawParameters& parameters)
    : CoulombSpring(Parameters{parameters.get("stiffness", "coulomb_spring"),
                               parameters.get("friction", "coulomb_spring"),
                               parameters.get_or("damping_factor", 0.0)}) {}

extern const bool kCoulombSpringRegistered = tangential_law_registry().add(
    "coulomb_spring", [](const LawParameters& parameters) -> std::unique_ptr<TangentialLaw> {
      return std::make_unique<CoulombSpring>(parameters);
    });

}  // namespace grainwave::particles::dem
