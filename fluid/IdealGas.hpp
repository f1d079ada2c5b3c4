#pragma once
// Pointwise physics of the non-dimensional compressible Navier-Stokes equations of 002
// (Goetsch 2015) Eqs 2.1-2.7, after Brown-Dymkoski et al. (2014):
//   velocity scaled by the reference sound speed c0, time by L/c0, density by rho0, pressure by
//   rho0 c0^2, temperature by T0, viscosity by mu0;
//   equation of state (2.4)      p = rho T / gamma        (so the sound speed is c^2 = T)
//   total energy per volume      rho e = p/(gamma-1) + rho |u|^2 / 2
//   Sutherland's law (2.7)       mu = (1 + S1)/(T + S1) T^(3/2)
//   viscous stress (2.5)         tau_ij = mu (du_i/dx_j + du_j/dx_i - 2/3 div u delta_ij)
// with 1/Re_a in front of the viscous terms and 1/((gamma-1) Re_a Pr) in front of heat
// conduction (Eqs 2.2-2.3). Everything here is an inline function of point values; block drivers
// own the loops.
#include <array>
#include <cmath>

namespace grainwave::fluid {

template <int Dim>
struct Primitive {
  double rho = 1;
  std::array<double, Dim> u{};
  double p = 1;
};

/// Conserved variables (rho, rho u_1..rho u_Dim, rho e).
template <int Dim>
using Conserved = std::array<double, Dim + 2>;

struct GasProperties {
  double gamma = 1.4;
  double sutherland_s1 = 110.4 / 300.0;  ///< S1 = 110.4 K over T0 = 300 K (air)
};

inline double temperature(double rho, double p, double gamma) { return gamma * p / rho; }
inline double sound_speed(double rho, double p, double gamma) { return std::sqrt(gamma * p / rho); }
inline double sutherland_viscosity(double T, double s1) {
  return (1 + s1) / (T + s1) * T * std::sqrt(T);
}

template <int Dim>
Conserved<Dim> to_conserved(const Primitive<Dim>& w, double gamma) {
  Conserved<Dim> q{};
  q[0] = w.rho;
  double kinetic = 0;
  for (int k = 0; k < Dim; ++k) {
    q[static_cast<std::size_t>(k + 1)] = w.rho * w.u[static_cast<std::size_t>(k)];
    kinetic += w.u[static_cast<std::size_t>(k)] * w.u[static_cast<std::size_t>(k)];
  }
  q[Dim + 1] = w.p / (gamma - 1) + 0.5 * w.rho * kinetic;
  return q;
}

template <int Dim>
Primitive<Dim> to_primitive(const Conserved<Dim>& q, double gamma) {
  Primitive<Dim> w;
  w.rho = q[0];
  double kinetic = 0;
  for (int k = 0; k < Dim; ++k) {
    w.u[static_cast<std::size_t>(k)] = q[static_cast<std::size_t>(k + 1)] / q[0];
    kinetic += w.u[static_cast<std::size_t>(k)] * q[static_cast<std::size_t>(k + 1)];
  }
  w.p = (gamma - 1) * (q[Dim + 1] - 0.5 * kinetic);
  return w;
}

/// Inviscid flux along axis `a`: (rho u_a, rho u u_a + p e_a, (rho e + p) u_a).
template <int Dim>
Conserved<Dim> euler_flux(const Primitive<Dim>& w, int a, double gamma) {
  const double ua = w.u[static_cast<std::size_t>(a)];
  Conserved<Dim> q = to_conserved(w, gamma);
  Conserved<Dim> f{};
  f[0] = w.rho * ua;
  for (int k = 0; k < Dim; ++k) f[static_cast<std::size_t>(k + 1)] = q[static_cast<std::size_t>(k + 1)] * ua;
  f[static_cast<std::size_t>(a + 1)] += w.p;
  f[Dim + 1] = (q[Dim + 1] + w.p) * ua;
  return f;
}

/// Largest characteristic speed |u_a| + c over the axes (for the CFL condition).
template <int Dim>
double max_wave_speed(const Primitive<Dim>& w, double gamma) {
  const double c = sound_speed(w.rho, w.p, gamma);
  double s = 0;
  for (int k = 0; k < Dim; ++k) s = std::max(s, std::abs(w.u[static_cast<std::size_t>(k)]) + c);
  return s;
}

/// Characteristic speed |u_a| + c along one axis.
template <int Dim>
double max_wave_speed_along(const Primitive<Dim>& w, int a, double gamma) {
  return std::abs(w.u[static_cast<std::size_t>(a)]) + sound_speed(w.rho, w.p, gamma);
}

}  // namespace grainwave::fluid
