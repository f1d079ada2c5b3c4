#pragma once
// Inviscid terms of the compressible Euler/Navier-Stokes equations (002 Eqs 2.1-2.3 without the
// viscous parts), discretised pointwise on one block line by 4th-order central differences,
//     D f_i = [ 2/3 (f_{i+1} - f_{i-1}) - 1/12 (f_{i+2} - f_{i-2}) ] / h,
// in the kinetic-energy-preserving split form of Kennedy & Gruber (J. Comput. Phys. 227, 2008)
// with alpha = beta = kappa = 1/4 for the triple products rho u_a phi (phi = u_k or the specific
// total energy e = E / rho):
//     d(rho u_a phi)/dx_a ~ 1/4 [ D(rho u phi) + u D(rho phi) + rho D(u phi) + phi D(rho u)
//                                 + rho u D(phi) + rho phi D(u) + u phi D(rho) ],
// the continuity flux as 1/2 [ D(rho u) + u D(rho) + rho D(u) ], the pressure work as
// 1/2 [ D(p u) + u D(p) + p D(u) ] (Pirozzoli, Annu. Rev. Fluid Mech. 43, 2011) and the pressure
// gradient as D(p). On a periodic uniform grid D is antisymmetric, so every pair a D(b) + b D(a)
// sums to zero over the grid: mass, momentum and energy are conserved to round-off, and the split
// keeps long smooth runs stable without dissipation.
//
// Shock capturing: a localised second-difference dissipation in conservative flux form along
// each axis (after the artificial viscosity of Regele & Vasilyev, Int. J. Comput. Fluid Dyn. 23,
// 2009, localised here by a pressure/density sensor in the spirit of Jameson, Schmidt & Turkel):
//     dq_i/dt += [ F_{i+1/2} - F_{i-1/2} ] / h,   F_{i+1/2} = k lambda_{i+1/2} s_{i+1/2} (q_{i+1} - q_i),
//     s_{i+1/2} = max(0, max_{j=i-1..i+2} psi_j - psi_0),
//     psi_j = max over (p, rho) of |f_{j+1} - 2 f_j + f_{j-1}| / (f_{j+1} + 2 f_j + f_{j-1}),
// lambda the largest |u_a| + c of the two points, k s capped at 1/2 (Rusanov). psi is O(h^2) in smooth flow, so below the
// threshold psi_0 smooth regions get no dissipation at all and keep 4th order.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace grainwave::fluid {

/// Weights of the 4th-order central first derivative at offsets +1 and +2 (antisymmetric).
inline constexpr double kCentral1 = 2.0 / 3.0;
inline constexpr double kCentral2 = -1.0 / 12.0;
/// Largest dissipation coefficient, in units of lambda (the Rusanov flux).
inline constexpr double kMaxDissipation = 0.5;
/// Ghost layers the split convection and the dissipation read on each side.
inline constexpr int kStencilReach = 3;

/// Primitive fields of one block, including ghosts (ArrayShape order): rho, u_k, p and the
/// specific total energy e = E / rho.
template <int Dim>
struct BlockPrimitives {
  const double* rho;
  std::array<const double*, Dim> u;
  const double* p;
  const double* e;
};

/// Primitives at every point of a block (ghosts included) from its conserved fields q = (rho,
/// rho u, E): rho, u, e = E / rho and p = (gamma - 1) (E - rho |u|^2 / 2).
template <int Dim>
inline void block_primitives(const std::array<const double*, Dim + 2>& q, std::size_t volume, double gamma,
                             double* rho, const std::array<double*, Dim>& u, double* e, double* p) {
  const double gm1 = gamma - 1;
  for (std::size_t at = 0; at < volume; ++at) {
    const double r = q[0][at], inv_r = 1 / r;
    double kinetic = 0;
    for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
      const double ua = q[a + 1][at] * inv_r;
      u[a][at] = ua;
      kinetic += ua * ua;
    }
    const double E = q[Dim + 1][at];
    rho[at] = r;
    e[at] = E * inv_r;
    p[at] = gm1 * (E - 0.5 * r * kinetic);
  }
}

/// Adds -(inviscid flux divergence along `axis`) at array point i to out[0..Dim+1]
/// (rho, rho u_k, E). stride: array stride of the axis; inv_h: 1 / spacing.
template <int Dim>
inline void add_split_convection(const BlockPrimitives<Dim>& w, std::ptrdiff_t i, std::ptrdiff_t stride,
                                 int axis, double inv_h, double* out) {
  constexpr int kPhi = Dim + 1;  // transported quantities: u_0..u_{Dim-1}, e
  const double* ua_field = w.u[static_cast<std::size_t>(axis)];
  double s_rho = 0, s_u = 0, s_p = 0, s_rhou = 0, s_pu = 0;
  std::array<double, kPhi> s_phi{}, s_rhophi{}, s_uphi{}, s_rhouphi{};
  for (int m = 1; m <= 2; ++m) {
    const double c = m == 1 ? kCentral1 : kCentral2;
    for (int sign = -1; sign <= 1; sign += 2) {
      const std::ptrdiff_t j = i + sign * m * stride;
      const double cs = sign * c;
      const double rho = w.rho[j], ua = ua_field[j], p = w.p[j];
      s_rho += cs * rho;
      s_u += cs * ua;
      s_p += cs * p;
      s_rhou += cs * rho * ua;
      s_pu += cs * p * ua;
      for (int k = 0; k < kPhi; ++k) {
        const double phi = k < Dim ? w.u[static_cast<std::size_t>(k)][j] : w.e[j];
        const auto ku = static_cast<std::size_t>(k);
        s_phi[ku] += cs * phi;
        s_rhophi[ku] += cs * rho * phi;
        s_uphi[ku] += cs * ua * phi;
        s_rhouphi[ku] += cs * rho * ua * phi;
      }
    }
  }
  const double rho = w.rho[i], ua = ua_field[i], p = w.p[i];
  out[0] -= inv_h * 0.5 * (s_rhou + ua * s_rho + rho * s_u);
  for (int k = 0; k < kPhi; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double phi = k < Dim ? w.u[ku][i] : w.e[i];
    double d = 0.25 * (s_rhouphi[ku] + ua * s_rhophi[ku] + rho * s_uphi[ku] + phi * s_rhou + rho * ua * s_phi[ku] +
                       rho * phi * s_u + ua * phi * s_rho);
    if (k == axis) d += s_p;
    if (k == Dim) d += 0.5 * (s_pu + ua * s_p + p * s_u);
    out[k + 1] -= inv_h * d;
  }
}

/// Jameson-type sensor of one field at array point i along a stride.
inline double second_difference_sensor(const double* f, std::ptrdiff_t i, std::ptrdiff_t stride) {
  const double a = f[i - stride], b = f[i], c = f[i + stride];
  return std::abs(a - 2 * b + c) / (std::abs(a) + 2 * std::abs(b) + std::abs(c));
}

/// Adds the localised dissipation along one axis at array point i to out[0..Dim+1].
/// q: conserved fields (with ghosts); psi: sensor along this axis; wave: |u_a| + c per point.
template <int Dim>
inline void add_shock_dissipation(const std::array<const double*, Dim + 2>& q, const double* psi, const double* wave,
                                  std::ptrdiff_t i, std::ptrdiff_t stride, double coefficient, double threshold,
                                  double inv_h, double* out) {
  const double psi_mid = std::max(psi[i - stride], std::max(psi[i], psi[i + stride]));
  const double s_left = std::max(0.0, std::max(psi_mid, psi[i - 2 * stride]) - threshold);
  const double s_right = std::max(0.0, std::max(psi_mid, psi[i + 2 * stride]) - threshold);
  if (s_left == 0 && s_right == 0) return;
  // Capped at the Rusanov (local Lax-Friedrichs) level lambda / 2: more is no more robust and
  // would leave the explicit RK stability region at the CFL step.
  const double e_left = std::min(coefficient * s_left, kMaxDissipation) * std::max(wave[i - stride], wave[i]);
  const double e_right = std::min(coefficient * s_right, kMaxDissipation) * std::max(wave[i], wave[i + stride]);
  for (int f = 0; f < Dim + 2; ++f) {
    const double* qf = q[static_cast<std::size_t>(f)];
    out[f] += inv_h * (e_right * (qf[i + stride] - qf[i]) - e_left * (qf[i] - qf[i - stride]));
  }
}

}  // namespace grainwave::fluid
