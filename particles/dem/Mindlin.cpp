#include "particles/dem/Mindlin.hpp"

#include "core/Error.hpp"

namespace grainwave::particles::dem {

Mindlin::Mindlin(const Parameters& p) : friction_(p.friction), damping_factor_(p.damping_factor) {
  const InputLocation where{"contact law 'mindlin'", 0};
  if (!(p.youngs_modulus > 0.0)) throw InputError(where, "youngs_modulus", "must be > 0");
  if (!(p.poisson_ratio > -1.0 && p.poisson_ratio < 0.5))
    throw InputError(where, "poisson_ratio", "must lie in (-1, 0.5)");
  if (!(friction_ >= 0.0)) throw InputError(where, "friction", "must be >= 0");
  if (!(damping_factor_ >= 0.0)) throw InputError(where, "damping_factor", "must be >= 0");
  const double shear_modulus = p.youngs_modulus / (2.0 * (1.0 + p.poisson_ratio));
  effective_shear_modulus_ = shear_modulus / (2.0 * (2.0 - p.poisson_ratio));
}

Mindlin::Mindlin(const LawParameters& parameters)
    : Mindlin(Parameters{parameters.get("youngs_modulus", "mindlin"),
                         parameters.get_or("poisson_ratio", 0.3),
                         parameters.get("friction", "mindlin"),
                         parameters.get_or("damping_factor", 0.0)}) {}

extern const bool kMindlinRegistered = tangential_law_registry().add(
    "mindlin", [](const LawParameters& parameters) -> std::unique_ptr<TangentialLaw> {
      return std::make_unique<Mindlin>(parameters);
    });

}  // namespace grainwave::particles::dem
