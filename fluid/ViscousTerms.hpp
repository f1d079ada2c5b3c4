#pragma once
// Viscous and heat-conduction terms of 002 Eqs 2.2-2.3 (non-dimensional, IdealGas.hpp scaling):
//     d(rho u_i)/dt += 1/Re_a  d tau_ij / dx_j,
//     dE/dt         += 1/Re_a  d(u_i tau_ij)/dx_j + 1/((gamma-1) Re_a Pr) d(mu dT/dx_j)/dx_j,
//     tau_ij = mu (du_i/dx_j + du_j/dx_i - 2/3 div u delta_ij),  mu = Sutherland(T) (Eq 2.7),
// discretised as the 4th-order central first derivative (SplitConvection.hpp) of fluxes built
// from 4th-order central gradients: the divergence of a flux in conservative form, so on a
// periodic uniform grid momentum and energy stay conserved to round-off. The nested first
// derivatives reach 4 points from each interior point (kViscousReach ghost layers).
// Only built when a scene sets a Reynolds number: inviscid scenes never call these.
#include <cstddef>

#include "fluid/SplitConvection.hpp"

namespace grainwave::fluid {

/// Ghost layers the viscous terms read.
inline constexpr int kViscousReach = 4;

/// 4th-order central first derivative of f at array point i along a stride, times inv_h.
inline double central_derivative(const double* f, std::ptrdiff_t i, std::ptrdiff_t stride, double inv_h) {
  return inv_h * (kCentral1 * (f[i + stride] - f[i - stride]) + kCentral2 * (f[i + 2 * stride] - f[i - 2 * stride]));
}

/// Viscous momentum flux tau_ij / Re_a (i = row) from the velocity gradient grad[i][j] at a point.
template <int Dim>
inline double viscous_stress(const double (&grad)[Dim][Dim], double mu, int i, int j) {
  double divergence = 0;
  for (int k = 0; k < Dim; ++k) divergence += grad[k][k];
  return mu * (grad[i][j] + grad[j][i] - (i == j ? 2.0 / 3.0 * divergence : 0.0));
}

}  // namespace grainwave::fluid
