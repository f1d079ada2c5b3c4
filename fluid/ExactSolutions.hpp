#pragma once
// Exact solutions the fluid cases are measured against.
//
// - The Riemann problem of the 1D Euler equations for an ideal gas (Toro, "Riemann Solvers and
//   Numerical Methods for Fluid Dynamics", ch. 4): star pressure from Newton's method on the
//   pressure function, then the self-similar solution sampled at x/t.
// - Normal-shock relations for a shock of Mach number Ms moving into quiescent gas, and the
//   shock reflected from a rigid wall (the gas behind it is at rest again): p2/p1, rho2/rho1,
//   u2/c1, reflected Mach number Mr and p5/p1.
// - The isentropic vortex (Shu 1998; Yee et al. 1999) advected by a uniform flow.
// All in the non-dimensional variables of IdealGas.hpp (p = rho T / gamma).
#include <array>
#include <cmath>

namespace grainwave::fluid {

struct RiemannState {
  double rho, u, p;
};

struct RiemannStar {
  double p, u;           ///< pressure and velocity between the two non-linear waves
  double rho_left;       ///< density left of the contact
  double rho_right;      ///< density right of the contact
  double left_speed;     ///< shock speed, or head speed of the rarefaction (left wave)
  double right_speed;    ///< shock speed, or head speed of the rarefaction (right wave)
  bool left_is_shock, right_is_shock;
};

class ExactRiemannSolver {
 public:
  ExactRiemannSolver(RiemannState left, RiemannState right, double gamma);
  const RiemannStar& star() const { return star_; }
  /// The solution at similarity coordinate xi = (x - x0) / t.
  RiemannState sample(double xi) const;

 private:
  double pressure_function(double p, const RiemannState& s, double c, double& derivative) const;
  RiemannState left_, right_;
  double gamma_, c_left_, c_right_;
  RiemannStar star_{};
};

struct ShockJump {
  double pressure_ratio;    ///< p2/p1
  double density_ratio;     ///< rho2/rho1
  double velocity_over_c1;  ///< u2/c1, the gas velocity behind the shock
};

/// A normal shock of Mach number Ms (> 1) entering gas at rest.
ShockJump normal_shock(double Ms, double gamma);
/// Mach number, relative to the gas ahead of it, of the shock reflected from a rigid wall.
double reflected_shock_mach(double Ms, double gamma);
/// p5/p1 behind the reflected shock.
double reflected_pressure_ratio(double Ms, double gamma);

/// Primitive (rho, u, v, p) of the isentropic vortex of strength beta centred at (x0, y0) on a
/// uniform flow (rho, p) = (1, 1/gamma), velocity (u_inf, v_inf), at distance (dx, dy) from its
/// centre: the temperature dip T = 1 - (gamma-1) beta^2/(8 pi^2) exp(1 - r^2) with entropy
/// p/rho^gamma constant.
std::array<double, 4> isentropic_vortex(double dx, double dy, double beta, double u_inf,
                                        double v_inf, double gamma);

}  // namespace grainwave::fluid
