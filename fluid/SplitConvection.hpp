#pragma once
// Inviscid terms of the compressible Euler/Navier-Stokes equations (002 Eqs 2.1-2.3 without the
// viscous parts) on one block, in conservative form with face fluxes,
//     dq_i/dt = -[ F_{i+1/2} - F_{i-1/2} ] / h   (summed over the axes).
//
// Central part: the kinetic-energy-preserving split form of Kennedy & Gruber (J. Comput. Phys.
// 227, 2008) with alpha = beta = kappa = 1/4 for the triple products rho u_a phi (phi = u_k or
// the specific total energy e = E / rho), the continuity flux as 1/2 [D(rho u) + u D(rho) + rho
// D(u)], the pressure work as 1/2 [D(p u) + u D(p) + p D(u)] and the pressure gradient as D(p),
// with the 4th-order central difference D f_i = [2/3 (f_{i+1} - f_{i-1}) - 1/12 (f_{i+2} -
// f_{i-2})] / h. Pirozzoli (J. Comput. Phys. 229, 2010) shows these split derivatives are exactly
// the divergence of the face flux
//     F_{i+1/2} = 2 sum_{m=1,2} a_m sum_{k=0}^{m-1} f(i-k, i-k+m),   a_1 = 2/3, a_2 = -1/12,
// with the two-point flux f(j, l) the Euler flux built from arithmetic means of the two points,
//     f = ( <rho><u_a>,  <rho><u_a><u_k> + <p> delta_ak,  <rho><u_a><e> + <p><u_a> ).
// So the split keeps its kinetic-energy preservation (long smooth runs stay stable without
// dissipation), and the flux form adds: mass, momentum and energy are conserved to round-off on
// any uniform grid (every face flux is shared by its two points), it costs three cheap two-point
// fluxes per face instead of seven products per point, and a face flux can be limited.
//
// Shock capturing: a localised second-difference dissipation in the same flux form (after the
// artificial viscosity of Regele & Vasilyev, Int. J. Comput. Fluid Dyn. 23, 2009, localised here
// by a pressure/density sensor in the spirit of Jameson, Schmidt & Turkel):
//     F_{i+1/2} -= k lambda_{i+1/2} s_{i+1/2} (q_{i+1} - q_i),
//     s_{i+1/2} = max(0, max_{j=i-1..i+2} psi_j - psi_0),
//     psi_j = max over (p, rho) of |f_{j+1} - 2 f_j + f_{j-1}| / (f_{j+1} + 2 f_j + f_{j-1}),
// lambda the largest |u_a| + c of the two points, k s capped at 1/2 (Rusanov). psi is O(h^2) in
// smooth flow, so below the threshold psi_0 smooth regions get no second-difference dissipation
// and keep 4th order.
// With shock capturing goes a weak background dissipation of sixth differences everywhere (the
// high-order background term of Jameson, Schmidt & Turkel, AIAA 81-1259, one order higher),
//     F_{i+1/2} -= kappa_6 lambda_{i+1/2} (q_{i+3} - 5 q_{i+2} + 10 q_{i+1} - 10 q_i + 5 q_{i-1} - q_{i-2}).
// Why: the central scheme has no dissipation, and its grid-scale waves run backwards at up to
// 5/3 of the wave speed (group velocity of the 4th-order difference at k h = pi). Shocks and
// contacts shed them, and they never die: in Sod's tube at 16384 points a noise of 3e-4 of the
// density filled the whole disturbed region and beyond, so a wavelet threshold below it kept
// 77% of the points. The sixth difference damps the mode k h = pi at the rate 64 kappa_6
// lambda / h (kappa_6 = 1/256: a quarter of lambda / h) and a smooth field by O(h^5), so smooth
// regions keep 4th order. It is added to the face flux, so it conserves like the rest.
//
// Positivity: where a forward-Euler step would make a density or pressure non-positive, the
// block's face fluxes are limited towards the local Lax-Friedrichs flux (Hu, Adams & Shu 2013;
// limit_face_flux below). Smooth flow never triggers it, and costs one check per point.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

#include "fluid/IdealGas.hpp"
#include "wavelet/ArrayShape.hpp"

namespace grainwave::fluid {

/// Weights of the 4th-order central first derivative at offsets +1 and +2 (antisymmetric).
inline constexpr double kCentral1 = 2.0 / 3.0;
inline constexpr double kCentral2 = -1.0 / 12.0;
/// Largest dissipation coefficient, in units of lambda (the Rusanov flux).
inline constexpr double kMaxDissipation = 0.5;
/// Ghost layers the split convection and the dissipation read on each side.
inline constexpr int kStencilReach = 3;
/// Ghost layers the split convection reads without the dissipation (shock capturing off), the
/// positivity limiter's Rusanov faces included; none into corners either way (every difference
/// is along one axis). Checked by BlockKernels.ReadNoGhostBeyondTheirReach.
inline constexpr int kCentralReach = 2;

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
  // Local copies of the pointers: the stores must not seem to change them (the loop was left
  // scalar when each iteration reloaded q[f] and u[a] through the references), and ivdep: no
  // output array overlaps an input.
  const std::array<const double*, Dim + 2> in = q;
  const std::array<double*, Dim> velocity = u;
#pragma GCC ivdep
  for (std::size_t at = 0; at < volume; ++at) {
    const double r = in[0][at], inv_r = 1 / r;
    double kinetic = 0;
    for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
      const double ua = in[a + 1][at] * inv_r;
      velocity[a][at] = ua;
      kinetic += ua * ua;
    }
    const double E = in[Dim + 1][at];
    rho[at] = r;
    e[at] = E * inv_r;
    p[at] = gm1 * (E - 0.5 * r * kinetic);
  }
}

/// Jameson-type sensor of one field at array point i along a stride.
inline double second_difference_sensor(const double* f, std::ptrdiff_t i, std::ptrdiff_t stride) {
  const double a = f[i - stride], b = f[i], c = f[i + stride];
  return std::abs(a - 2 * b + c) / (std::abs(a) + 2 * std::abs(b) + std::abs(c));
}

/// Positivity-preserving limiter of one face flux (after Hu, Adams & Shu, J. Comput. Phys. 242,
/// 2013, in flux-deviation form). A forward-Euler step of length dt updates point i by
/// -dt/h (F_{i+1/2} - F_{i-1/2}) summed over the Dim axes; as the point's own Euler flux f_i
/// cancels in each axis' difference, that is the mean of the 2 Dim states
///     q_i - sigma (F_{i+1/2} - f_i)   and   q_i + sigma (F_{i-1/2} - f_i),   sigma = 2 Dim dt / h,
/// one per face of the point. The high-order flux F is kept where both states of this face,
///     q_L - sigma (F - f_L)   and   q_R + sigma (F - f_R),
/// have positive density and pressure; elsewhere it is blended towards the local Lax-Friedrichs
/// flux F_LF, F = theta F + (1 - theta) F_LF, with the largest theta that keeps them positive
/// (linear in theta for the density; for the pressure, which is concave in q, the secant bound
/// is safe). With F_LF the states are convex combinations of q and q -+ f / alpha (admissible for
/// alpha >= |u_a| + c) when sigma alpha <= 1, i.e. for CFL numbers up to 1/2; SSP-RK3 stages are
/// forward-Euler steps, so then the whole step stays positive. In smooth flow F - f_i = O(h), so
/// the states stay near q_i at any CFL number and the limiter does not act.
/// Returns whether the flux was changed. qL, qR: conserved states; wL, wR: their primitives.
template <int Dim>
inline bool limit_face_flux(const std::array<double, Dim + 2>& qL, const std::array<double, Dim + 2>& qR,
                            const Primitive<Dim>& wL, const Primitive<Dim>& wR, int axis, double sigma, double gamma,
                            std::array<double, Dim + 2>& flux) {
  constexpr std::size_t kF = Dim + 2;
  using State = std::array<double, kF>;
  const double floor_rho = 1e-12 * std::min(qL[0], qR[0]), floor_p = 1e-12 * std::min(wL.p, wR.p);
  const auto fL = euler_flux<Dim>(wL, axis, gamma), fR = euler_flux<Dim>(wR, axis, gamma);
  auto states = [&](const State& f, State& left, State& right) {
    for (std::size_t k = 0; k < kF; ++k) {
      left[k] = qL[k] - sigma * (f[k] - fL[k]);
      right[k] = qR[k] + sigma * (f[k] - fR[k]);
    }
  };
  auto admissible = [&](const State& s) { return s[0] > floor_rho && to_primitive<Dim>(s, gamma).p > floor_p; };
  State left{}, right{};
  states(flux, left, right);
  if (admissible(left) && admissible(right)) return false;
  // Local Lax-Friedrichs flux of the two states.
  const double alpha = std::max(max_wave_speed_along<Dim>(wL, axis, gamma), max_wave_speed_along<Dim>(wR, axis, gamma));
  State low{};
  for (std::size_t k = 0; k < kF; ++k) low[k] = 0.5 * (fL[k] + fR[k]) - 0.5 * alpha * (qR[k] - qL[k]);
  State low_left{}, low_right{};
  states(low, low_left, low_right);
  // Density: linear in theta.
  double theta = 1;
  for (const auto* pair : {&left, &right}) {
    const State& high_state = *pair;
    const State& low_state = pair == &left ? low_left : low_right;
    if (high_state[0] < floor_rho)
      theta = std::min(theta, std::max(0.0, (low_state[0] - floor_rho) / (low_state[0] - high_state[0])));
  }
  State blended{};
  for (std::size_t k = 0; k < kF; ++k) blended[k] = theta * flux[k] + (1 - theta) * low[k];
  states(blended, left, right);
  // Pressure: concave in q, so along the segment from the low to the blended flux it lies above
  // the secant; the secant's root is a safe theta.
  double theta_p = 1;
  for (const auto* pair : {&left, &right}) {
    const double p_high = to_primitive<Dim>(*pair, gamma).p;
    const double p_low = to_primitive<Dim>(pair == &left ? low_left : low_right, gamma).p;
    if (p_high < floor_p) theta_p = std::min(theta_p, std::max(0.0, (p_low - floor_p) / (p_low - p_high)));
  }
  for (std::size_t k = 0; k < kF; ++k) flux[k] = theta_p * blended[k] + (1 - theta_p) * low[k];
  return true;
}

/// What bounds the explicit time step at a point (block_max_rate).
struct StableRateSettings {
  double gamma = 1.4;
  bool viscous = false;  ///< add the explicit viscous and heat-conduction limit
  double reynolds = 1, prandtl = 0.72, sutherland_s1 = 110.4 / 300.0;
};

/// Calls row(start, length, first) for each row along x (contiguous in memory) of the box
/// lo <= i < hi of array coordinates: start is the array index of the row's first point, first
/// its coordinates. Kernels loop over a row's points with constant offsets to every stencil
/// neighbour, so the compiler vectorises them whatever the derivative's axis.
template <int Dim, class Row>
inline void for_each_row(const wavelet::ArrayShape<Dim>& shape, const std::array<int, Dim>& lo,
                         const std::array<int, Dim>& hi, Row&& row) {
  const int length = hi[0] - lo[0];
  if constexpr (Dim == 1) {
    row(shape.index(lo), length, lo);
  } else if constexpr (Dim == 2) {
    for (int y = lo[1]; y < hi[1]; ++y) row(shape.index({lo[0], y}), length, std::array<int, 2>{lo[0], y});
  } else {
    for (int z = lo[2]; z < hi[2]; ++z)
      for (int y = lo[1]; y < hi[1]; ++y) row(shape.index({lo[0], y, z}), length, std::array<int, 3>{lo[0], y, z});
  }
}

/// Interior point number (x fastest) of the array point with coordinates `first`, for a block of
/// n^Dim interior points from array coordinate g on.
template <int Dim>
inline std::size_t interior_point_number(const std::array<int, Dim>& first, int g, int n) {
  std::size_t point = 0;
  for (int b = Dim - 1; b >= 0; --b)
    point = point * static_cast<std::size_t>(n) + static_cast<std::size_t>(first[static_cast<std::size_t>(b)] - g);
  return point;
}

/// The largest rate over a block's interior points that an explicit RK step of 4th-order central
/// differences must resolve, dt <= cfl / rate:
///     rate = sum_a (|u_a| + c) / h_a  [+ 16/3 max(4/3, gamma / Pr) nu sum_a 1 / h_a^2],
/// the diffusion part (spectral radius of the narrow 4th-order second derivative times the
/// largest diffusivity, momentum 4/3 nu or heat gamma nu / Pr, nu = mu / (rho Re_a)) for
/// explicit viscous terms. Non-finite rates are skipped (the state check reports them).
/// row: scratch of at least n values.
template <int Dim>
inline double block_max_rate(const wavelet::ArrayShape<Dim>& shape, int g, int n,
                             const std::array<const double*, Dim + 2>& q_fields, const std::array<double, Dim>& h,
                             const StableRateSettings& settings, double* row) {
  const std::array<const double*, Dim + 2> q = q_fields;
  std::array<int, Dim> lo{}, hi{};
  lo.fill(g);
  hi.fill(g + n);
  double inv_h_sum = 0, inv_h2_sum = 0;
  std::array<double, Dim> inv_h{};
  for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
    inv_h[a] = 1 / h[a];
    inv_h_sum += inv_h[a];
    inv_h2_sum += inv_h[a] * inv_h[a];
  }
  const double gamma = settings.gamma, gm1 = gamma - 1;
  const double diffusion = settings.viscous ? (16.0 / 3.0) * std::max(4.0 / 3.0, gamma / settings.prandtl) /
                                                  settings.reynolds * inv_h2_sum
                                            : 0.0;
  double rate = 0;
  for_each_row<Dim>(shape, lo, hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
    for (int x = 0; x < length; ++x) {
      const std::ptrdiff_t at = start + x;
      const double rho = q[0][at], inv_rho = 1 / rho;
      double kinetic = 0, speeds = 0;
      for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
        const double u = q[a + 1][at] * inv_rho;
        kinetic += u * u;
        speeds += std::abs(u) * inv_h[a];
      }
      const double T = std::abs(gamma * gm1 * (q[Dim + 1][at] * inv_rho - 0.5 * kinetic));  // c^2 = gamma p / rho
      const double c = std::sqrt(T);
      double r = speeds + c * inv_h_sum;
      if (settings.viscous) r += diffusion * sutherland_viscosity(T, settings.sutherland_s1) * inv_rho;
      row[x] = r;
    }
    for (int x = 0; x < length; ++x)
      if (std::isfinite(row[x])) rate = std::max(rate, row[x]);
  });
  return rate;
}

/// Scratch of add_block_inviscid: per-field arrays of the block's volume (with ghosts).
template <int Dim>
struct BlockScratch {
  std::array<std::vector<double>, Dim + 2> wide;  ///< two-point flux of (i, i + 2 s) at i
  std::array<std::vector<double>, Dim + 2> face;  ///< face flux of (i, i + s) at i
  std::vector<double> psi, sound;
  explicit BlockScratch(std::size_t volume = 0) {
    for (auto* set : {&wide, &face})
      for (auto& v : *set) v.assign(volume, 0.0);
    psi.assign(volume, 0.0);
    sound.assign(volume, 0.0);
  }
};

/// What add_block_inviscid adds besides the central split flux.
struct InviscidSettings {
  double gamma = 1.4;
  bool capturing = false;           ///< the sensor-localised dissipation (and the background one)
  double coefficient = 0, threshold = 0;
  double background = 0;            ///< kappa_6 of the sixth-difference background dissipation
  double limiter_dt = 0;            ///< forward-Euler step the positivity limiter guards (0: none)
};

/// Sets out to the inviscid right-hand side -sum_a [F_a(i) - F_a(i - s_a)] / h_a of one block
/// (out[f * n^Dim + p], p the interior point number, x fastest). The block's interior is the
/// n^Dim points from array coordinate g on in every axis (g >= kStencilReach ghost layers).
/// Along each axis the face fluxes F(i), through the face between i and i + s, are computed
/// once each for the faces of the interior points,
///     F = 2 a_1 f(i, i+s) + 2 a_2 (f(i-s, i+s) + f(i, i+2s)),
/// each wide pair f(j, j + 2s) once for the two faces that share it; then the dissipation acts
/// on them if the sensor exceeds the threshold anywhere in the block along this axis, and the
/// background term on every face when settings.background > 0. With
/// limiter_dt > 0, if a forward-Euler step of 2 limiter_dt would make some point's density or
/// pressure non-positive, the block is computed again with every face flux limited
/// (limit_face_flux). Returns the number of faces the limiter changed.
template <int Dim>
inline long add_block_inviscid(const wavelet::ArrayShape<Dim>& shape, int g, int n, const BlockPrimitives<Dim>& w,
                               const std::array<const double*, Dim + 2>& q_fields, const std::array<double, Dim>& h,
                               const InviscidSettings& settings, BlockScratch<Dim>& scratch, double* out) {
  constexpr std::size_t kF = Dim + 2;
  // Local copies of the field pointers: stores through the scratch pointers cannot change them,
  // which the vectoriser must know.
  const std::array<const double*, kF> q = q_fields;
  std::array<const double*, Dim> u{};
  for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) u[k] = w.u[k];
  std::size_t per_block = 1;
  for (int a = 0; a < Dim; ++a) per_block *= static_cast<std::size_t>(n);
  std::array<int, Dim> interior_lo{}, interior_hi{};
  interior_lo.fill(g);
  interior_hi.fill(g + n);
  const double* rho = w.rho;
  const double* p = w.p;
  const double* e = w.e;
  long limited = 0;
  bool sound_ready = false;
  // One pass over the axes: out = -sum_a [F_a(i) - F_a(i - s_a)] / h_a, the face fluxes limited
  // for positivity when `limit` (then returns the faces changed).
  auto pass = [&](bool limit) {
  // The axis is a template parameter: with it known at compile time the two-point flux's
  // pressure term f[axis + 1] has a fixed slot, so f lives in registers and the pair loops
  // vectorise (with a run-time axis they stayed scalar).
  auto along_axis = [&]<int axis>() {
    constexpr auto au = static_cast<std::size_t>(axis);
    const std::ptrdiff_t s = shape.stride(axis);
    const double* ua = u[au];
    auto along = [&](int from, int to) {  // the interior box, rows from..to-1 along this axis
      auto lo = interior_lo, hi = interior_hi;
      lo[au] = from;
      hi[au] = to;
      return std::pair{lo, hi};
    };
    // The two-point flux of (j, l) from arithmetic means (the header comment's f).
    auto pair_flux = [&](std::ptrdiff_t j, std::ptrdiff_t l, std::array<double, kF>& f) {
      const double rho_mean = 0.5 * (rho[j] + rho[l]), ua_mean = 0.5 * (ua[j] + ua[l]), p_mean = 0.5 * (p[j] + p[l]);
      const double mass = rho_mean * ua_mean;
      f[0] = mass;
      for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) f[k + 1] = mass * 0.5 * (u[k][j] + u[k][l]);
      f[au + 1] += p_mean;
      f[Dim + 1] = mass * 0.5 * (e[j] + e[l]) + p_mean * ua_mean;
    };
    std::array<double*, kF> wide{}, face{};
    for (std::size_t f = 0; f < kF; ++f) wide[f] = scratch.wide[f].data(), face[f] = scratch.face[f].data();
    {
      const auto [lo, hi] = along(g - 2, g + n);
      for_each_row<Dim>(shape, lo, hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) {
          const std::ptrdiff_t j = start + x;
          std::array<double, kF> f;
          pair_flux(j, j + 2 * s, f);
          for (std::size_t k = 0; k < kF; ++k) wide[k][j] = f[k];
        }
      });
    }
    const auto [face_lo, face_hi] = along(g - 1, g + n);
    const double background = settings.capturing ? settings.background : 0.0;
    double* sound = scratch.sound.data();
    // Sound speeds where the faces' wave speeds read them (the interior and one layer around it),
    // once per block: c^2 = gamma p / rho = gamma (gamma - 1) (e - |u|^2 / 2), without a division.
    auto sound_speeds = [&] {
      if (sound_ready) return;
      std::array<int, Dim> reached_lo{}, reached_hi{};
      reached_lo.fill(g - 1);
      reached_hi.fill(g + n + 1);
      const double gg1 = settings.gamma * (settings.gamma - 1);
      for_each_row<Dim>(shape, reached_lo, reached_hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) {
          const std::ptrdiff_t at = start + x;
          double kinetic = 0;
          for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) kinetic += u[k][at] * u[k][at];
          sound[at] = std::sqrt(std::abs(gg1 * (e[at] - 0.5 * kinetic)));
        }
      });
      sound_ready = true;
    };
    for_each_row<Dim>(shape, face_lo, face_hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
      for (int x = 0; x < length; ++x) {
        const std::ptrdiff_t i = start + x;
        std::array<double, kF> f;
        pair_flux(i, i + s, f);
        for (std::size_t k = 0; k < kF; ++k) face[k][i] = 2 * kCentral1 * f[k] + 2 * kCentral2 * (wide[k][i - s] + wide[k][i]);
      }
    });
    if (background > 0) {  // a pass of its own: fused into the one above, neither vectorised as well
      sound_speeds();
      for_each_row<Dim>(shape, face_lo, face_hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) {
          const std::ptrdiff_t i = start + x;
          const double sixth = background * std::max(std::abs(ua[i]) + sound[i], std::abs(ua[i + s]) + sound[i + s]);
          for (std::size_t k = 0; k < kF; ++k) {
            const double* qk = q[k];
            // The fifth difference of q across the face (i, i + s).
            face[k][i] -= sixth * ((qk[i + 3 * s] - qk[i - 2 * s]) - 5 * (qk[i + 2 * s] - qk[i - s]) + 10 * (qk[i + s] - qk[i]));
          }
        }
      });
    }
    if (settings.capturing) {
      double* psi = scratch.psi.data();
      int above = 0;
      const auto [lo, hi] = along(g - 2, g + n + 2);
      // Whether the sensor exceeds the threshold anywhere, without its divisions (most blocks are
      // smooth): psi > psi_0 is tested as |second difference| > psi_0 (1 - 1e-12) * sum. The
      // margin exceeds the division's rounding, so a block this calls smooth has psi <= psi_0
      // everywhere, and gets no dissipation, exactly as with psi computed.
      const double margin = settings.threshold * (1 - 1e-12);
      for_each_row<Dim>(shape, lo, hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
        for (int x = 0; x < length; ++x) {
          const std::ptrdiff_t i = start + x;
          for (const double* f : {p, rho}) {
            const double a = f[i - s], b = f[i], c = f[i + s];
            above |= static_cast<int>(std::abs(a - 2 * b + c) > margin * (std::abs(a) + 2 * std::abs(b) + std::abs(c)));
          }
        }
      });
      // Below the threshold everywhere in the block the dissipation is exactly zero: skip it.
      if (above) {
        for_each_row<Dim>(shape, lo, hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
          for (int x = 0; x < length; ++x) {
            const std::ptrdiff_t i = start + x;
            psi[i] = std::max(second_difference_sensor(p, i, s), second_difference_sensor(rho, i, s));
          }
        });
        sound_speeds();
        for_each_row<Dim>(shape, face_lo, face_hi, [&](std::ptrdiff_t start, int length, const auto&) {
#pragma GCC ivdep
          for (int x = 0; x < length; ++x) {
            const std::ptrdiff_t i = start + x;
            const double psi_face = std::max(std::max(psi[i - s], psi[i]), std::max(psi[i + s], psi[i + 2 * s]));
            const double excess = std::max(0.0, psi_face - settings.threshold);
            // Capped at the Rusanov (local Lax-Friedrichs) level lambda / 2: more is no more
            // robust and would leave the explicit RK stability region at the CFL step.
            const double coefficient = std::min(settings.coefficient * excess, kMaxDissipation) *
                                       std::max(std::abs(ua[i]) + sound[i], std::abs(ua[i + s]) + sound[i + s]);
            for (std::size_t k = 0; k < kF; ++k) face[k][i] -= coefficient * (q[k][i + s] - q[k][i]);
          }
        });
      }
    }
    if (limit) {
      const double sigma = 2 * Dim * settings.limiter_dt / h[au];
      auto state_at = [&](std::ptrdiff_t j, std::array<double, kF>& qj, Primitive<Dim>& wj) {
        for (std::size_t k = 0; k < kF; ++k) qj[k] = q[k][j];
        wj.rho = rho[j];
        for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) wj.u[k] = u[k][j];
        wj.p = p[j];
      };
      for_each_row<Dim>(shape, face_lo, face_hi, [&](std::ptrdiff_t start, int length, const auto&) {
        std::array<double, kF> qL{}, qR{}, f{};
        Primitive<Dim> wL, wR;
        for (std::ptrdiff_t i = start; i < start + length; ++i) {
          state_at(i, qL, wL);
          state_at(i + s, qR, wR);
          for (std::size_t k = 0; k < kF; ++k) f[k] = face[k][i];
          if (!limit_face_flux<Dim>(qL, qR, wL, wR, axis, sigma, settings.gamma, f)) continue;
          ++limited;
          for (std::size_t k = 0; k < kF; ++k) face[k][i] = f[k];
        }
      });
    }
    // The divergence at the interior points.
    const double inv_h = 1 / h[au];
    for_each_row<Dim>(shape, interior_lo, interior_hi, [&](std::ptrdiff_t start, int length, const auto& first) {
      const std::size_t point = interior_point_number<Dim>(first, g, n);
      for (std::size_t k = 0; k < kF; ++k) {
        double* o = out + k * per_block + point;
        const double* fk = face[k] + start;
        if (axis == 0) {
#pragma GCC ivdep
          for (int x = 0; x < length; ++x) o[x] = -inv_h * (fk[x] - fk[x - s]);
        } else {
#pragma GCC ivdep
          for (int x = 0; x < length; ++x) o[x] -= inv_h * (fk[x] - fk[x - s]);
        }
      }
    });
  };
  [&]<int... kAxes>(std::integer_sequence<int, kAxes...>) {
    (along_axis.template operator()<kAxes>(), ...);  // axes in order 0, 1, ...
  }(std::make_integer_sequence<int, Dim>{});
  };
  pass(false);
  if (settings.limiter_dt <= 0) return 0;
  // Positivity: would a forward-Euler step of twice limiter_dt with this right-hand side keep
  // every interior point's density and pressure positive (above 1e-12 of its own)? Mostly it
  // would, and the fluxes stand. Otherwise the block is redone with every face flux limited
  // (limit_face_flux), which keeps each point's update positive. The factor 2 is a margin for
  // stages that are not forward-Euler steps (RK4's): with 1, the Woodward-Colella blast fails
  // under RK4 at CFL 0.8; with 2 it completes (SSP-RK3 at CFL 0.5 needs no margin).
  const double dt = 2 * settings.limiter_dt, gm1 = settings.gamma - 1;
  int violations = 0;
  for_each_row<Dim>(shape, interior_lo, interior_hi, [&](std::ptrdiff_t start, int length, const auto& first) {
    const std::size_t point = interior_point_number<Dim>(first, g, n);
    int row = 0;
    for (int x = 0; x < length; ++x) {
      const std::ptrdiff_t i = start + x;
      const std::size_t o = point + static_cast<std::size_t>(x);
      const double rho_next = q[0][i] + dt * out[o];
      double momentum2 = 0;
      for (std::size_t k = 1; k <= static_cast<std::size_t>(Dim); ++k) {
        const double m = q[k][i] + dt * out[k * per_block + o];
        momentum2 += m * m;
      }
      const double energy = q[Dim + 1][i] + dt * out[(Dim + 1) * per_block + o];
      row |= static_cast<int>(rho_next <= 1e-12 * q[0][i]) |
             static_cast<int>(gm1 * (rho_next * energy - 0.5 * momentum2) <= 1e-12 * p[i] * rho_next);
    }
    violations |= row;
  });
  if (!violations) return 0;
  pass(true);
  return limited;
}

}  // namespace grainwave::fluid
