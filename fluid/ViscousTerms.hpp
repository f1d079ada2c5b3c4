#pragma once
// Viscous and heat-conduction terms of 002 Eqs 2.2-2.3 (non-dimensional, IdealGas.hpp scaling):
//     d(rho u_i)/dt += 1/Re_a  d tau_ij / dx_j,
//     dE/dt         += 1/Re_a  d(u_i tau_ij)/dx_j + 1/((gamma-1) Re_a Pr) d(mu dT/dx_j)/dx_j,
//     tau_ij = mu (du_i/dx_j + du_j/dx_i - 2/3 div u delta_ij),  mu = Sutherland(T) (Eq 2.7),
// split by the structure of each term:
//   - the "Laplacian" parts, d_j(mu d_j u_i) in the momentum, d_j(mu d_j |u|^2/2) (the work of
//     those stresses) and the heat conduction d_j(mu d_j T), by the narrow 5-point 4th-order
//     operator of narrow_diffusion below; so also the part of the rest along its own axis,
//     d_j(mu/3 d_j u_j) in the momentum j and d_j(mu/3 d_j u_j^2/2) in the energy (in tau_jj,
//     mu (d_j u_j - 2/3 div u) = mu/3 d_j u_j - 2/3 mu sum_{k != j} d_k u_k);
//   - the rest, d_j(mu (d_i u_j - 2/3 delta_ij sum_{k != j} d_k u_k)) for i != j or k != j, and
//     its work, as the 4th-order central first derivative (SplitConvection.hpp) of fluxes built
//     from 4th-order central gradients across the flux's axis.
// Why the split: nested first derivatives are blind to the grid's odd-even (2h) mode, so a purely
// nested discretisation leaves that mode undamped. A Brinkman-penalized wall (Penalization.hpp)
// forces it, and the velocity profile next to the wall then zig-zags point to point. The narrow
// operator damps the 2h mode at the physical rate. Both parts are in conservative form: on a
// periodic uniform grid momentum and energy stay conserved to round-off (narrow_diffusion sums
// to zero because its matrix is symmetric). With every derivative along an axis taken once
// along that axis (nested derivatives only across axes), the terms reach 2 points from each
// interior point along an axis and 2 x 2 into the corners: kViscousReach ghost layers, fewer than
// the convection's, so viscosity costs no wider ghost fill (nesting the diagonal rest reached 4).
// Only built when a scene sets a Reynolds number: inviscid scenes never call these.
#include <array>
#include <cstddef>

#include "fluid/SplitConvection.hpp"

namespace grainwave::fluid {

/// Ghost layers the viscous terms read.
inline constexpr int kViscousReach = 2;

/// 4th-order central first derivative of f at array point i along a stride, times inv_h.
inline double central_derivative(const double* f, std::ptrdiff_t i, std::ptrdiff_t stride, double inv_h) {
  return inv_h * (kCentral1 * (f[i + stride] - f[i - stride]) + kCentral2 * (f[i + 2 * stride] - f[i - 2 * stride]));
}

/// d/dx (mu df/dx) at array point i along a stride by the narrow operator
///     1/2 [D2(mu f) - f D2(mu) + mu D2(f)] = 1/2 sum_k c_k (mu_k + mu_0)(f_k - f_0),
/// D2 the 5-point 4th-order second derivative with weights c_k (so it is 4th order, reduces to
/// mu D2 f for constant mu, and damps the 2h mode); inv_h2 = 1/h^2.
/// The sums mu_k + mu_0 depend only on mu: NarrowStencil holds them, so that the several fields
/// diffused with one viscosity share them.
struct NarrowStencil {
  double plus1, minus1, plus2, minus2;  ///< mu_{i+-s} + mu_i and mu_{i+-2s} + mu_i
};

inline NarrowStencil narrow_stencil(const double* mu, std::ptrdiff_t i, std::ptrdiff_t stride) {
  const double m0 = mu[i];
  return {mu[i + stride] + m0, mu[i - stride] + m0, mu[i + 2 * stride] + m0, mu[i - 2 * stride] + m0};
}

/// The narrow operator with the viscosity sums m; f_of(k) gives f at array point k (a field
/// computed on the fly).
template <class F>
inline double narrow_diffusion_with(const NarrowStencil& m, F&& f_of, std::ptrdiff_t i, std::ptrdiff_t stride,
                                    double inv_h2) {
  const double f0 = f_of(i);
  const double near = m.plus1 * (f_of(i + stride) - f0) + m.minus1 * (f_of(i - stride) - f0);
  const double far = m.plus2 * (f_of(i + 2 * stride) - f0) + m.minus2 * (f_of(i - 2 * stride) - f0);
  return 0.5 * inv_h2 * ((4.0 / 3.0) * near - (1.0 / 12.0) * far);
}

template <class F>
inline double narrow_diffusion_of(const double* mu, F&& f_of, std::ptrdiff_t i, std::ptrdiff_t stride, double inv_h2) {
  return narrow_diffusion_with(narrow_stencil(mu, i, stride), f_of, i, stride, inv_h2);
}

inline double narrow_diffusion(const double* mu, const double* f, std::ptrdiff_t i, std::ptrdiff_t stride, double inv_h2) {
  return narrow_diffusion_of(mu, [f](std::ptrdiff_t k) { return f[k]; }, i, stride, inv_h2);
}

/// Viscous stress tau_ij = mu (d_j u_i + d_i u_j - 2/3 div u delta_ij) (i = row) from the velocity
/// gradient grad[i][j] = d_j u_i at a point (the control-volume forces; add_block_viscous splits
/// the same stress between the narrow operator and nested derivatives).
template <int Dim>
inline double viscous_stress(const double (&grad)[Dim][Dim], double mu, int i, int j) {
  double divergence = 0;
  for (int k = 0; k < Dim; ++k) divergence += grad[k][k];
  return mu * (grad[i][j] + grad[j][i] - (i == j ? 2.0 / 3.0 * divergence : 0.0));
}

/// The fields add_block_viscous reads and its scratch, arrays of one block with ghosts.
template <int Dim>
struct ViscousBlock {
  std::array<const double*, Dim> u{};
  const double* rho = nullptr;
  const double* p = nullptr;
  std::array<std::array<double*, Dim>, Dim> gradient{};  ///< out: gradient[i][a] = d_a u_i
  double* temperature = nullptr;                          ///< out: T = gamma p / rho
  double* mu = nullptr;                                   ///< out: Sutherland viscosity
  double* kinetic = nullptr;                              ///< scratch: |u|^2 / 2
  std::array<double*, Dim + 1> flux{};                    ///< scratch: stress rest and its work
};

struct ViscousSettings {
  double gamma = 1.4, reynolds = 1, prandtl = 0.72, sutherland_s1 = 110.4 / 300.0;
};

/// Adds the viscous and heat-conduction terms of one block (its n^Dim interior points from array
/// coordinate g on, g >= kViscousReach) to out (out[f * n^Dim + p], p the interior point number,
/// x fastest; the density row is not touched). Also leaves the velocity gradients, T and mu at
/// the interior points in `block` (the force integrals read them). Loops over x-contiguous
/// rows (for_each_row) with every stencil at constant offsets: they vectorise whatever the
/// derivative's axis.
template <int Dim>
inline void add_block_viscous(const wavelet::ArrayShape<Dim>& shape, int g, int n, const std::array<double, Dim>& h,
                              const ViscousSettings& settings, const ViscousBlock<Dim>& block, double* out) {
  std::size_t per_block = 1;
  for (int a = 0; a < Dim; ++a) per_block *= static_cast<std::size_t>(n);
  const double inv_re = 1 / settings.reynolds;
  const double conduction = 1 / ((settings.gamma - 1) * settings.reynolds * settings.prandtl);
  const double gamma = settings.gamma, s1 = settings.sutherland_s1;
  // Local copies of the pointers: the vectoriser must see them invariant.
  const auto u = block.u;
  const auto grad_of = block.gradient;
  const auto flux = block.flux;
  const double* rho = block.rho;
  const double* p = block.p;
  double* temperature = block.temperature;
  double* mu = block.mu;
  double* kinetic = block.kinetic;
  std::array<int, Dim> lo{}, hi{}, interior_lo{}, interior_hi{};
  lo.fill(g - 2);
  hi.fill(g + n + 2);
  interior_lo.fill(g);
  interior_hi.fill(g + n);
  // T, mu and |u|^2 / 2 at the interior points +- 2 (what the narrow operator and the fluxes read).
  // The |u|^2 / 2 carries the work of the Laplacian stresses, d_j(mu d_j |u|^2/2).
  for_each_row<Dim>(shape, lo, hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
    for (int x = 0; x < length; ++x) {
      const std::ptrdiff_t at = start + x;
      const double T = gamma * p[at] / rho[at];
      temperature[at] = T;
      mu[at] = sutherland_viscosity(T, s1);
      double k = 0;
      for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) k += u[i][at] * u[i][at];
      kinetic[at] = 0.5 * k;
    }
  });
  // Gradients d_a u_i at the interior points, and +- 2 across axis a (the fluxes along the other
  // axes read them there; along a itself no derivative is nested, so u is read 2 points out).
  for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
    const double inv_h = 1 / h[a];
    const std::ptrdiff_t stride = shape.stride(static_cast<int>(a));
    auto across_lo = lo, across_hi = hi;
    across_lo[a] = g;
    across_hi[a] = g + n;
    for_each_row<Dim>(shape, across_lo, across_hi, [&](std::ptrdiff_t start, int length, const auto&) {
      for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
        const double* ui = u[i];
        double* gi = grad_of[i][a];
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) gi[start + x] = central_derivative(ui, start + x, stride, inv_h);
      }
    });
  }
  for (int j = 0; j < Dim; ++j) {
    const auto ju = static_cast<std::size_t>(j);
    const double inv_h = 1 / h[ju], inv_h2 = inv_h * inv_h;
    const std::ptrdiff_t stride = shape.stride(j);
    // The rest of tau_ij and its work u_i tau_ij at the interior points +- 2 along j, from the
    // gradients across j only: mu d_i u_j (i != j) and -2/3 mu sum_{k != j} d_k u_k (i = j).
    auto flux_lo = interior_lo, flux_hi = interior_hi;
    flux_lo[ju] = g - 2;
    flux_hi[ju] = g + n + 2;
    std::array<const double*, Dim> d_uj{}, diagonal{};
    for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
      d_uj[i] = grad_of[ju][i];
      diagonal[i] = grad_of[i][i];
    }
    // (In 1D there is no rest: tau = 4/3 mu du/dx, all of it narrow.)
    if constexpr (Dim > 1) {
      for_each_row<Dim>(shape, flux_lo, flux_hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) {
          const std::ptrdiff_t at = start + x;
          double across = 0;  // sum_{k != j} d_k u_k
          for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k)
            if (k != ju) across += diagonal[k][at];
          const double scale = inv_re * mu[at];
          double work = 0;
          for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
            const double rest = scale * (i == ju ? -2.0 / 3.0 * across : d_uj[i][at]);
            flux[i][at] = rest;
            work += u[i][at] * rest;
          }
          flux[Dim][at] = work;
        }
      });
    }
    // One pass over the interior adds, per point and in this order, the derivative of the rest
    // along j and the narrow terms, so the viscosity sums are formed once for the Dim + 2 fields
    // they diffuse.
    const double* uj = u[ju];
    std::array<double, Dim> weight{};  // d_j(mu d_j u_i), and for i = j the 1/3 of tau_jj's own-axis part
    for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) weight[i] = i == ju ? inv_re * (4.0 / 3.0) : inv_re;
    for_each_row<Dim>(shape, interior_lo, interior_hi, [&](std::ptrdiff_t start, int length, const auto& first) {
      const std::size_t point = interior_point_number<Dim>(first, g, n);
      std::array<double*, Dim + 2> o{};
      for (std::size_t f = 1; f < static_cast<std::size_t>(Dim + 2); ++f) o[f] = out + f * per_block + point;
      // Energy: d_j(mu d_j (|u|^2/2 + u_j^2/6)), the work of those stresses, and the conduction.
      auto work_potential = [kinetic, uj](std::ptrdiff_t k) { return kinetic[k] + (1.0 / 6.0) * uj[k] * uj[k]; };
      auto temperature_at = [temperature](std::ptrdiff_t k) { return temperature[k]; };
#pragma GCC ivdep
      for (int x = 0; x < length; ++x) {
        const std::ptrdiff_t at = start + x;
        const NarrowStencil m = narrow_stencil(mu, at, stride);
        for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
          double v = o[i + 1][x];
          if constexpr (Dim > 1) v += central_derivative(flux[i], at, stride, inv_h);
          const double* ui = u[i];
          o[i + 1][x] = v + weight[i] * narrow_diffusion_with(m, [ui](std::ptrdiff_t k) { return ui[k]; }, at, stride, inv_h2);
        }
        double energy = o[Dim + 1][x];
        if constexpr (Dim > 1) energy += central_derivative(flux[Dim], at, stride, inv_h);
        o[Dim + 1][x] = energy + (inv_re * narrow_diffusion_with(m, work_potential, at, stride, inv_h2) +
                                  conduction * narrow_diffusion_with(m, temperature_at, at, stride, inv_h2));
      }
    });
  }
}

}  // namespace grainwave::fluid
