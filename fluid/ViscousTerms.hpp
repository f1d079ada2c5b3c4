#pragma once
// Viscous and heat-conduction terms of 002 Eqs 2.2-2.3 (non-dimensional, IdealGas.hpp scaling):
//     d(rho u_i)/dt += 1/Re_a  d tau_ij / dx_j,
//     dE/dt         += 1/Re_a  d(u_i tau_ij)/dx_j + 1/((gamma-1) Re_a Pr) d(mu dT/dx_j)/dx_j,
//     tau_ij = mu (du_i/dx_j + du_j/dx_i - 2/3 div u delta_ij),  mu = Sutherland(T) (Eq 2.7),
// split by the structure of each term:
//   - the "Laplacian" parts, d_j(mu d_j u_i) in the momentum, d_j(mu d_j |u|^2/2) (the work of
//     those stresses) and the heat conduction d_j(mu d_j T), by the narrow 5-point 4th-order
//     operator of narrow_diffusion below;
//   - the rest, d_j(mu (d_i u_j - 2/3 delta_ij div u)) and its work, as the 4th-order central first
//     derivative (SplitConvection.hpp) of fluxes built from 4th-order central gradients.
// Why the split: nested first derivatives are blind to the grid's odd-even (2h) mode, so a purely
// nested discretisation leaves that mode undamped. A Brinkman-penalized wall (Penalization.hpp)
// forces it, and the velocity profile next to the wall then zig-zags point to point. The narrow
// operator damps the 2h mode at the physical rate. Both parts are in conservative form: on a
// periodic uniform grid momentum and energy stay conserved to round-off (narrow_diffusion sums
// to zero because its matrix is symmetric). The nested derivatives reach 4 points from each
// interior point (kViscousReach ghost layers).
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

/// d/dx (mu df/dx) at array point i along a stride by the narrow operator
///     1/2 [D2(mu f) - f D2(mu) + mu D2(f)] = 1/2 sum_k c_k (mu_k + mu_0)(f_k - f_0),
/// D2 the 5-point 4th-order second derivative with weights c_k (so it is 4th order, reduces to
/// mu D2 f for constant mu, and damps the 2h mode); inv_h2 = 1/h^2.
inline double narrow_diffusion(const double* mu, const double* f, std::ptrdiff_t i, std::ptrdiff_t stride, double inv_h2) {
  const double m0 = mu[i], f0 = f[i];
  auto pair = [&](std::ptrdiff_t k) {
    return (mu[i + k] + m0) * (f[i + k] - f0) + (mu[i - k] + m0) * (f[i - k] - f0);
  };
  return 0.5 * inv_h2 * ((4.0 / 3.0) * pair(stride) - (1.0 / 12.0) * pair(2 * stride));
}

/// The part of tau_ij that narrow_diffusion does not carry: mu (d_i u_j - 2/3 div u delta_ij),
/// from the velocity gradient grad[i][j] = d_j u_i at a point.
template <int Dim>
inline double viscous_stress_rest(const double (&grad)[Dim][Dim], double mu, int i, int j) {
  double divergence = 0;
  for (int k = 0; k < Dim; ++k) divergence += grad[k][k];
  return mu * (grad[j][i] - (i == j ? 2.0 / 3.0 * divergence : 0.0));
}

/// Viscous stress tau_ij (i = row) from the velocity gradient grad[i][j] = d_j u_i at a point.
template <int Dim>
inline double viscous_stress(const double (&grad)[Dim][Dim], double mu, int i, int j) {
  return mu * grad[i][j] + viscous_stress_rest<Dim>(grad, mu, i, j);
}

}  // namespace grainwave::fluid
