#include "fluid/ExactSolutions.hpp"

#include <algorithm>
#include <numbers>
#include <stdexcept>

namespace grainwave::fluid {

ExactRiemannSolver::ExactRiemannSolver(RiemannState left, RiemannState right, double gamma)
    : left_(left), right_(right), gamma_(gamma) {
  c_left_ = std::sqrt(gamma * left.p / left.rho);
  c_right_ = std::sqrt(gamma * right.p / right.rho);
  const double du = right.u - left.u;
  if (2 * (c_left_ + c_right_) / (gamma - 1) <= du)
    throw std::invalid_argument("Riemann problem generates vacuum");
  // Start from the two-rarefaction approximation (Toro 4.46), then Newton (Toro 4.44).
  const double g = (gamma - 1) / (2 * gamma);
  double p = std::pow((c_left_ + c_right_ - 0.5 * (gamma - 1) * du) /
                          (c_left_ / std::pow(left.p, g) + c_right_ / std::pow(right.p, g)),
                      1 / g);
  p = std::max(p, 1e-12);
  for (int it = 0; it < 100; ++it) {
    double dl = 0, dr = 0;
    const double f = pressure_function(p, left_, c_left_, dl) +
                     pressure_function(p, right_, c_right_, dr) + du;
    double next = p - f / (dl + dr);
    if (next < 0) next = 0.5 * p;
    const double change = 2 * std::abs(next - p) / (next + p);
    p = next;
    if (change < 1e-15) break;
  }
  double dl = 0, dr = 0;
  const double fl = pressure_function(p, left_, c_left_, dl);
  const double fr = pressure_function(p, right_, c_right_, dr);
  star_.p = p;
  star_.u = 0.5 * (left.u + right.u) + 0.5 * (fr - fl);
  const double gm = (gamma - 1) / (gamma + 1);
  auto star_density = [&](const RiemannState& s) {
    const double ratio = p / s.p;
    return ratio > 1 ? s.rho * (ratio + gm) / (gm * ratio + 1)       // behind a shock
                     : s.rho * std::pow(ratio, 1 / gamma);           // behind a rarefaction
  };
  star_.rho_left = star_density(left_);
  star_.rho_right = star_density(right_);
  star_.left_is_shock = p > left.p;
  star_.right_is_shock = p > right.p;
  const double q = (gamma + 1) / (2 * gamma), r = (gamma - 1) / (2 * gamma);
  star_.left_speed = star_.left_is_shock ? left.u - c_left_ * std::sqrt(q * p / left.p + r)
                                         : left.u - c_left_;
  star_.right_speed = star_.right_is_shock ? right.u + c_right_ * std::sqrt(q * p / right.p + r)
                                           : right.u + c_right_;
}

double ExactRiemannSolver::pressure_function(double p, const RiemannState& s, double c,
                                             double& derivative) const {
  const double g = gamma_;
  if (p > s.p) {  // shock (Toro 4.6, 4.37)
    const double a = 2 / ((g + 1) * s.rho), b = (g - 1) / (g + 1) * s.p;
    const double root = std::sqrt(a / (p + b));
    derivative = root * (1 - 0.5 * (p - s.p) / (b + p));
    return (p - s.p) * root;
  }
  // rarefaction (Toro 4.7, 4.37)
  const double ratio = p / s.p;
  derivative = 1 / (s.rho * c) * std::pow(ratio, -(g + 1) / (2 * g));
  return 2 * c / (g - 1) * (std::pow(ratio, (g - 1) / (2 * g)) - 1);
}

RiemannState ExactRiemannSolver::sample(double xi) const {
  const double g = gamma_;
  const auto& st = star_;
  if (xi <= st.u) {  // left of the contact
    const auto& s = left_;
    const double c = c_left_;
    if (st.left_is_shock) return xi < st.left_speed ? s : RiemannState{st.rho_left, st.u, st.p};
    const double c_star = c * std::pow(st.p / s.p, (g - 1) / (2 * g));
    if (xi <= s.u - c) return s;
    if (xi >= st.u - c_star) return {st.rho_left, st.u, st.p};
    // inside the left rarefaction fan (Toro 4.56)
    const double factor = 2 / (g + 1) + (g - 1) / ((g + 1) * c) * (s.u - xi);
    return {s.rho * std::pow(factor, 2 / (g - 1)), 2 / (g + 1) * (c + 0.5 * (g - 1) * s.u + xi),
            s.p * std::pow(factor, 2 * g / (g - 1))};
  }
  const auto& s = right_;
  const double c = c_right_;
  if (st.right_is_shock) return xi > st.right_speed ? s : RiemannState{st.rho_right, st.u, st.p};
  const double c_star = c * std::pow(st.p / s.p, (g - 1) / (2 * g));
  if (xi >= s.u + c) return s;
  if (xi <= st.u + c_star) return {st.rho_right, st.u, st.p};
  const double factor = 2 / (g + 1) - (g - 1) / ((g + 1) * c) * (s.u - xi);
  return {s.rho * std::pow(factor, 2 / (g - 1)), 2 / (g + 1) * (-c + 0.5 * (g - 1) * s.u + xi),
          s.p * std::pow(factor, 2 * g / (g - 1))};
}

ShockJump normal_shock(double Ms, double gamma) {
  if (!(Ms > 1)) throw std::invalid_argument("shock Mach number must exceed 1");
  const double m2 = Ms * Ms;
  return {1 + 2 * gamma / (gamma + 1) * (m2 - 1), (gamma + 1) * m2 / ((gamma - 1) * m2 + 2),
          2 / (gamma + 1) * (Ms - 1 / Ms)};
}

double reflected_shock_mach(double Ms, double gamma) {
  // The reflected shock brings the post-incident-shock gas (state 2) back to rest:
  //   Mr/(Mr^2 - 1) = Ms/(Ms^2 - 1) sqrt(1 + 2(gamma-1)/(gamma+1)^2 (Ms^2 - 1)(gamma + 1/Ms^2)),
  // with Mr measured relative to state 2 (Anderson, "Modern Compressible Flow", §7.7).
  const double m2 = Ms * Ms;
  const double rhs = Ms / (m2 - 1) *
                     std::sqrt(1 + 2 * (gamma - 1) / ((gamma + 1) * (gamma + 1)) * (m2 - 1) *
                                       (gamma + 1 / m2));
  // Mr/(Mr^2-1) = rhs  ->  rhs Mr^2 - Mr - rhs = 0, the root above 1.
  return (1 + std::sqrt(1 + 4 * rhs * rhs)) / (2 * rhs);
}

double reflected_pressure_ratio(double Ms, double gamma) {
  const double mr = reflected_shock_mach(Ms, gamma);
  return normal_shock(Ms, gamma).pressure_ratio * (1 + 2 * gamma / (gamma + 1) * (mr * mr - 1));
}

std::array<double, 4> isentropic_vortex(double dx, double dy, double beta, double u_inf,
                                        double v_inf, double gamma) {
  // Background: rho = 1, p = 1/gamma, so T = gamma p / rho = 1 and c = 1 (002's scaling).
  const double r2 = dx * dx + dy * dy;
  const double bump = std::exp(0.5 * (1 - r2));
  const double du = beta / (2 * std::numbers::pi) * bump;
  // Radial equilibrium dp/dr = rho u_theta^2 / r with p = rho T / gamma and p / rho^gamma fixed
  // gives dT/dr = (gamma - 1) u_theta^2 / r: no 1/gamma here, unlike the p = rho T scaling.
  const double T = 1 - (gamma - 1) * beta * beta / (8 * std::numbers::pi * std::numbers::pi) * bump * bump;
  const double rho = std::pow(T, 1 / (gamma - 1));
  return {rho, u_inf - du * dy, v_inf + du * dx, rho * T / gamma};
}

}  // namespace grainwave::fluid
