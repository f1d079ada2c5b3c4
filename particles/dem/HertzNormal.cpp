#include "particles/dem/HertzNormal.hpp"

#include "core/Error.hpp"

#include <algorithm>
#include <array>

namespace grainwave::particles::dem {

HertzNormal::ScaledCollision HertzNormal::integrate_scaled_collision(double damping_factor) {
  // Classical RK4 on (x, x'); the contact ends at the first x < 0, found by linear interpolation.
  const double ds = 2.0e-4;
  auto rhs = [damping_factor](double x, double u) {
    const double xp = std::max(x, 0.0);
    const double q = std::sqrt(std::sqrt(xp));
    return -xp * q * q - damping_factor * q * u;
  };
  double x = 0.0, u = 1.0, s = 0.0;
  for (int step = 0; step < 10'000'000; ++step) {
    const double k1x = u, k1u = rhs(x, u);
    const double k2x = u + 0.5 * ds * k1u, k2u = rhs(x + 0.5 * ds * k1x, u + 0.5 * ds * k1u);
    const double k3x = u + 0.5 * ds * k2u, k3u = rhs(x + 0.5 * ds * k2x, u + 0.5 * ds * k2u);
    const double k4x = u + ds * k3u, k4u = rhs(x + ds * k3x, u + ds * k3u);
    const double x_new = x + ds / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
    const double u_new = u + ds / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u);
    if (x_new < 0.0 && step > 0) {
      const double w = x / (x - x_new);
      return {-(u + w * (u_new - u)), s + w * ds};
    }
    x = x_new;
    u = u_new;
    s += ds;
  }
  throw NumericalFailure("Hertz scaled collision did not end", "HertzNormal", 0.0, 0);
}

HertzNormal::HertzNormal(const Parameters& p)
    : effective_modulus_(p.youngs_modulus / (2.0 * (1.0 - p.poisson_ratio * p.poisson_ratio))),
      restitution_(p.restitution),
      reference_velocity_(p.reference_velocity) {
  const InputLocation where{"contact law 'hertz'", 0};
  if (!(p.youngs_modulus > 0.0)) throw InputError(where, "youngs_modulus", "must be > 0");
  if (!(p.poisson_ratio > -1.0 && p.poisson_ratio < 0.5))
    throw InputError(where, "poisson_ratio", "must lie in (-1, 0.5)");
  if (!(restitution_ > 0.0 && restitution_ <= 1.0))
    throw InputError(where, "restitution", "must lie in (0, 1]");
  if (!(reference_velocity_ > 0.0)) throw InputError(where, "reference_velocity", "must be > 0");
  if (restitution_ < 1.0) {
    // e(c) falls monotonically from 1 at c = 0; bracket, then bisect.
    double lo = 0.0, hi = 0.5;
    while (integrate_scaled_collision(hi).restitution > restitution_) hi *= 2.0;
    for (int iteration = 0; iteration < 40; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      (integrate_scaled_collision(mid).restitution > restitution_ ? lo : hi) = mid;
    }
    damping_factor_ = 0.5 * (lo + hi);
  }
  scaled_duration_ = integrate_scaled_collision(damping_factor_).duration;
}

HertzNormal::HertzNormal(const LawParameters& parameters)
    : HertzNormal(Parameters{parameters.get("youngs_modulus", "hertz"),
                             parameters.get_or("poisson_ratio", 0.3),
                             parameters.get_or("restitution", 1.0),
                             parameters.get_or("reference_velocity", 1.0)}) {}

double HertzNormal::contact_duration(double effective_mass, double effective_radius) const {
  const double k = stiffness(effective_radius);
  return scaled_duration_ *
         std::pow(effective_mass * effective_mass / (k * k * reference_velocity_), 0.2);
}

extern const bool kHertzNormalRegistered = normal_law_registry().add(
    "hertz", [](const LawParameters& parameters) -> std::unique_ptr<NormalLaw> {
      return std::make_unique<HertzNormal>(parameters);
    });

}  // namespace grainwave::particles::dem
