#include "particles/dem/LinearSpringDashpot.hpp"

#include "core/Error.hpp"

#include <numbers>

namespace grainwave::particles::dem {

LinearSpringDashpot::LinearSpringDashpot(const Parameters& parameters)
    : stiffness_(parameters.stiffness), restitution_(parameters.restitution) {
  if (!(stiffness_ > 0.0))
    throw InputError({"contact law 'linear_spring_dashpot'", 0}, "stiffness", "must be > 0");
  if (!(restitution_ > 0.0 && restitution_ <= 1.0))
    throw InputError({"contact law 'linear_spring_dashpot'", 0}, "restitution",
                     "must lie in (0, 1]");
  const double log_e = std::log(restitution_);
  damping_factor_ = -2.0 * log_e / std::sqrt(std::numbers::pi * std::numbers::pi + log_e * log_e);
}

LinearSpringDashpot::LinearSpringDashpot(const LawParameters& parameters)
    : LinearSpringDashpot(Parameters{parameters.get("stiffness", "linear_spring_dashpot"),
                                     parameters.get_or("restitution", 1.0)}) {}

double LinearSpringDashpot::contact_duration(double effective_mass, double) const {
  const double log_e = std::log(restitution_);
  return std::sqrt((std::numbers::pi * std::numbers::pi + log_e * log_e) * effective_mass /
                   stiffness_);
}

extern const bool kLinearSpringDashpotRegistered = normal_law_registry().add(
    "linear_spring_dashpot", [](const LawParameters& parameters) -> std::unique_ptr<NormalLaw> {
      return std::make_unique<LinearSpringDashpot>(parameters);
    });

}  // namespace grainwave::particles::dem
