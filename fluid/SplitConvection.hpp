#pragma once
// Inviscid terms of the compressible Euler/Navier-Stokes equations (002 Eqs 2.1-2.3 without the
// viscous parts) on one block line, in conservative form with face fluxes,
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
// smooth flow, so below the threshold psi_0 smooth regions get no dissipation at all and keep
// 4th order.
//
// Positivity: the face flux is finally limited towards the local Lax-Friedrichs flux where a
// forward-Euler step would otherwise make a density or pressure negative (Hu, Adams & Shu 2013;
// limit_face_flux below). Smooth flow never triggers it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "fluid/IdealGas.hpp"

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

/// Jameson-type sensor of one field at array point i along a stride.
inline double second_difference_sensor(const double* f, std::ptrdiff_t i, std::ptrdiff_t stride) {
  const double a = f[i - stride], b = f[i], c = f[i + stride];
  return std::abs(a - 2 * b + c) / (std::abs(a) + 2 * std::abs(b) + std::abs(c));
}

/// Dissipation coefficient of the face between array points i and i + stride: k s lambda (k s
/// capped at the Rusanov level 1/2), with s from the sensor over i - 1 .. i + 2; zero in smooth flow.
/// psi: sensor along this axis; wave: |u_a| + c per point.
inline double dissipation_coefficient(const double* psi, const double* wave, std::ptrdiff_t i, std::ptrdiff_t stride,
                                      double coefficient, double threshold) {
  const double psi_face = std::max(std::max(psi[i - stride], psi[i]), std::max(psi[i + stride], psi[i + 2 * stride]));
  const double s = psi_face - threshold;
  if (s <= 0) return 0;
  // Capped at the Rusanov (local Lax-Friedrichs) level lambda / 2: more is no more robust and
  // would leave the explicit RK stability region at the CFL step.
  return std::min(coefficient * s, kMaxDissipation) * std::max(wave[i], wave[i + stride]);
}

/// Pressure of a conserved state.
template <int Dim>
inline double pressure_of(const std::array<double, Dim + 2>& q, double gamma) {
  double momentum2 = 0;
  for (std::size_t k = 1; k <= static_cast<std::size_t>(Dim); ++k) momentum2 += q[k] * q[k];
  return (gamma - 1) * (q[Dim + 1] - 0.5 * momentum2 / q[0]);
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
  auto admissible = [&](const State& s) { return s[0] > floor_rho && pressure_of<Dim>(s, gamma) > floor_p; };
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
    const double p_high = pressure_of<Dim>(*pair, gamma);
    const double p_low = pressure_of<Dim>(pair == &left ? low_left : low_right, gamma);
    if (p_high < floor_p) theta_p = std::min(theta_p, std::max(0.0, (p_low - floor_p) / (p_low - p_high)));
  }
  for (std::size_t k = 0; k < kF; ++k) flux[k] = theta_p * blended[k] + (1 - theta_p) * low[k];
  return true;
}
/// The sensor-localised dissipation of a line (absent: psi == nullptr).
struct FaceDissipation {
  const double* psi = nullptr;   ///< sensor along the line's axis, per array point
  const double* wave = nullptr;  ///< |u_a| + c per array point
  double coefficient = 0, threshold = 0;
};

/// Scratch of add_line_divergence for lines of up to n points: the line's primitives gathered
/// contiguously (points -2 .. n+1) and its fluxes, structure of arrays, so the loops over faces
/// vectorise whatever the line's stride in the block.
template <int Dim>
struct LineScratch {
  static constexpr std::size_t kPrimitives = Dim + 3;  ///< rho, u_0 .. u_{Dim-1}, p, e
  static constexpr std::size_t kF = Dim + 2;
  std::size_t points = 0;
  std::vector<double> primitives;  ///< kPrimitives x (n + 4)
  std::vector<double> wide_pairs;  ///< kF x (n + 2): two-point flux of points (j - 2, j) of the line
  std::vector<double> flux;        ///< kF x (n + 1): face k between points k - 1 and k
  std::vector<double> conserved;   ///< kF x (n + 2): q at points -1 .. n (dissipation, limiter)
  std::vector<double> point_flux;  ///< kF x (n + 2): Euler flux at points -1 .. n (limiter)
  explicit LineScratch(int n = 0)
      : points(static_cast<std::size_t>(n)),
        primitives(kPrimitives * (points + 4)),
        wide_pairs(kF * (points + 2)),
        flux(kF * (points + 1)),
        conserved(kF * (points + 2)),
        point_flux(kF * (points + 2)) {}
};

/// Two-point fluxes of the split form, weight 1, for pairs (left[j], right[j]) of gathered
/// primitives (rows of `stride` values), j = 0 .. count - 1, into out rows f * out_stride.
template <int Dim>
inline void pair_fluxes(const double* prim, std::size_t stride, std::size_t left, std::size_t right, std::size_t count,
                        int axis, double* out, std::size_t out_stride) {
  const double* rho = prim;
  const double* ua = prim + (1 + static_cast<std::size_t>(axis)) * stride;
  const double* p = prim + (Dim + 1) * stride;
  const double* e = prim + (Dim + 2) * stride;
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t l = left + j, r = right + j;
    const double rho_mean = 0.5 * (rho[l] + rho[r]), ua_mean = 0.5 * (ua[l] + ua[r]), p_mean = 0.5 * (p[l] + p[r]);
    const double mass = rho_mean * ua_mean;
    out[j] = mass;
    for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) {
      const double* uk = prim + (1 + k) * stride;
      out[(k + 1) * out_stride + j] = mass * 0.5 * (uk[l] + uk[r]);
    }
    out[(static_cast<std::size_t>(axis) + 1) * out_stride + j] += p_mean;
    out[(Dim + 1) * out_stride + j] = mass * 0.5 * (e[l] + e[r]) + p_mean * ua_mean;
  }
}

/// Adds -[F_{k+1/2} - F_{k-1/2}] * inv_h along one line of n interior points to out: point k of
/// the line is array point first + k stride and output out[f * field_stride + k * out_step].
/// Faces k = 0..n (face k between points k - 1 and k) are computed once each: the split flux
///     F = 2 a_1 f(k-1, k) + 2 a_2 (f(k-2, k) + f(k-1, k+1)),
/// each wide pair f(j - 2, j) computed once for the two faces that share it; then the dissipation
/// (if any) and, for sigma > 0, the positivity limiter act on the faces. scratch: for n points.
/// Returns the number of faces the limiter changed.
template <int Dim>
inline int add_line_divergence(const BlockPrimitives<Dim>& w, const std::array<const double*, Dim + 2>& q,
                               std::ptrdiff_t first, std::ptrdiff_t stride, int n, int axis, double inv_h,
                               const FaceDissipation& dissipation, double sigma, double gamma, LineScratch<Dim>& scratch,
                               double* out, std::size_t field_stride, std::size_t out_step) {
  constexpr std::size_t kF = Dim + 2;
  const auto points = static_cast<std::size_t>(n);
  const std::size_t row = points + 4, faces = points + 1, wide = points + 2;
  double* prim = scratch.primitives.data();
  // Gather points -2 .. n+1 (row index j + 2).
  for (std::size_t j = 0; j < row; ++j) {
    const std::ptrdiff_t at = first + (static_cast<std::ptrdiff_t>(j) - 2) * stride;
    prim[j] = w.rho[at];
    for (std::size_t k = 0; k < static_cast<std::size_t>(Dim); ++k) prim[(1 + k) * row + j] = w.u[k][at];
    prim[(Dim + 1) * row + j] = w.p[at];
    prim[(Dim + 2) * row + j] = w.e[at];
  }
  // Wide pairs (j - 2, j) for line points j = 0 .. n+1: rows j and j + 2.
  double* wide_pairs = scratch.wide_pairs.data();
  pair_fluxes<Dim>(prim, row, 0, 2, wide, axis, wide_pairs, wide);
  // Narrow pairs (k - 1, k) for faces k = 0 .. n: rows k + 1 and k + 2; then the face flux.
  double* flux = scratch.flux.data();
  pair_fluxes<Dim>(prim, row, 1, 2, faces, axis, flux, faces);
  for (std::size_t f = 0; f < kF; ++f) {
    double* face = flux + f * faces;
    const double* pairs = wide_pairs + f * wide;
    for (std::size_t k = 0; k < faces; ++k) face[k] = 2 * kCentral1 * face[k] + 2 * kCentral2 * (pairs[k] + pairs[k + 1]);
  }
  const bool limiting = sigma > 0;
  double* qline = scratch.conserved.data();  // points -1 .. n, row index k + 1
  if (dissipation.psi || limiting)
    for (std::size_t f = 0; f < kF; ++f)
      for (std::size_t j = 0; j < wide; ++j) qline[f * wide + j] = q[f][first + (static_cast<std::ptrdiff_t>(j) - 1) * stride];
  if (dissipation.psi) {
    for (std::size_t k = 0; k < faces; ++k) {
      const std::ptrdiff_t i = first + (static_cast<std::ptrdiff_t>(k) - 1) * stride;
      const double e = dissipation_coefficient(dissipation.psi, dissipation.wave, i, stride, dissipation.coefficient,
                                               dissipation.threshold);
      if (e == 0) continue;
      for (std::size_t f = 0; f < kF; ++f) flux[f * faces + k] -= e * (qline[f * wide + k + 1] - qline[f * wide + k]);
    }
  }
  int limited = 0, any_bad = 0;
  if (limiting) {
    // First a branch-free pass over the faces (it vectorises): is any state q_L - sigma (F - f_L)
    // or q_R + sigma (F - f_R) of this line not positive? Mostly none is, and the line is done.
    // The Euler fluxes f of points -1 .. n (rows of qline) first.
    double* point_flux = scratch.point_flux.data();
    for (std::size_t j = 0; j < wide; ++j) {
      const double ua = prim[(1 + static_cast<std::size_t>(axis)) * row + j + 1], p = prim[(Dim + 1) * row + j + 1];
      for (std::size_t f = 0; f <= static_cast<std::size_t>(Dim); ++f) point_flux[f * wide + j] = qline[f * wide + j] * ua;
      point_flux[(static_cast<std::size_t>(axis) + 1) * wide + j] += p;
      point_flux[(Dim + 1) * wide + j] = (qline[(Dim + 1) * wide + j] + p) * ua;
    }
    const double gm1 = gamma - 1;
    for (std::size_t k = 0; k < faces; ++k) {
      for (int side = 0; side < 2; ++side) {
        const std::size_t j = k + static_cast<std::size_t>(side);
        const double sign = side == 0 ? -sigma : sigma;
        const double rho = qline[j] + sign * (flux[k] - point_flux[j]);
        double momentum2 = 0;
        for (std::size_t a = 1; a <= static_cast<std::size_t>(Dim); ++a) {
          const double m = qline[a * wide + j] + sign * (flux[a * faces + k] - point_flux[a * wide + j]);
          momentum2 += m * m;
        }
        const double energy =
            qline[(Dim + 1) * wide + j] + sign * (flux[(Dim + 1) * faces + k] - point_flux[(Dim + 1) * wide + j]);
        // Floors as in limit_face_flux, against 2x the density and pressure of this point alone:
        // the pass only has to be conservative, the limiter decides.
        const double floor_rho = 2e-12 * qline[j], floor_p = 2e-12 * prim[(Dim + 1) * row + j + 1];
        any_bad |= static_cast<int>(rho <= floor_rho) | static_cast<int>(gm1 * (rho * energy - 0.5 * momentum2) <= floor_p * rho);
      }
    }
  }
  if (limiting && any_bad) {
    std::array<double, kF> qL{}, qR{}, face{};
    Primitive<Dim> wL, wR;
    auto state_at = [&](std::size_t j, std::array<double, kF>& qi, Primitive<Dim>& wi) {  // j: row of qline
      for (std::size_t f = 0; f < kF; ++f) qi[f] = qline[f * wide + j];
      wi.rho = prim[j + 1];
      for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) wi.u[a] = prim[(1 + a) * row + j + 1];
      wi.p = prim[(Dim + 1) * row + j + 1];
    };
    for (std::size_t k = 0; k < faces; ++k) {
      state_at(k, qL, wL);
      state_at(k + 1, qR, wR);
      for (std::size_t f = 0; f < kF; ++f) face[f] = flux[f * faces + k];
      if (!limit_face_flux<Dim>(qL, qR, wL, wR, axis, sigma, gamma, face)) continue;
      ++limited;
      for (std::size_t f = 0; f < kF; ++f) flux[f * faces + k] = face[f];
    }
  }
  for (std::size_t f = 0; f < kF; ++f) {
    double* o = out + f * field_stride;
    const double* face = flux + f * faces;
    for (std::size_t k = 0; k < points; ++k) o[k * out_step] -= inv_h * (face[k + 1] - face[k]);
  }
  return limited;
}

}  // namespace grainwave::fluid
