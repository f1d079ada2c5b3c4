#pragma once
// Boundary conditions of the fluid on non-periodic domain edges, imposed through the ghost
// layers the grid leaves outside the domain (GhostKind::kOutsideDomain), so the interior scheme
// is the same central one everywhere:
//   - slip wall: mirror image about the edge point (the point on the wall), normal momentum
//     reversed. The mirrored flux rho u_n u_n + p is even and the mass flux odd about the wall,
//     so the wall point keeps u_n = 0 and no mass or energy crosses it. On a low edge the wall
//     point is x = lo; on a high edge it is the last point of the block, x = hi - h.
//   - inflow: the ghosts hold a fixed state (the initial state at the face centre, e.g. the gas
//     behind an incoming shock). All characteristics enter through a supersonic inflow, so this is
//     exact there; for subsonic inflow it over-specifies (no characteristic treatment yet).
//   - outflow: zero-gradient extrapolation of the conserved variables (transmissive; it
//     reflects weakly, a characteristic treatment is not implemented yet).
#include <array>
#include <cstddef>
#include <span>

#include "fluid/IdealGas.hpp"
#include "wavelet/ArrayShape.hpp"

namespace grainwave::fluid {

enum class BoundaryKind { kPeriodic, kSlipWall, kOutflow, kInflow };

/// Fills the ghosts of one block beyond one edge (axis, high side or not) for the Dim + 2
/// conserved fields. bs: interior points per axis, g: ghost layers; inflow: the conserved state
/// of an inflow edge.
template <int Dim>
void fill_edge_ghosts(std::span<double* const> fields, const wavelet::ArrayShape<Dim>& shape, int bs, int g, int axis,
                      bool high, BoundaryKind kind, std::span<const double> inflow) {
  const std::ptrdiff_t stride = shape.stride(axis);
  const int edge = high ? g + bs - 1 : g;  // array coordinate of the edge point
  const int direction = high ? 1 : -1;
  for (std::size_t at = 0; at < shape.size(); ++at) {
    const auto i = shape.coords(static_cast<std::ptrdiff_t>(at));
    const int k = (i[static_cast<std::size_t>(axis)] - edge) * direction;  // layers beyond the edge
    if (k <= 0) continue;
    if (kind == BoundaryKind::kInflow) {
      for (std::size_t f = 0; f < fields.size(); ++f) fields[f][at] = inflow[f];
      continue;
    }
    const int source = kind == BoundaryKind::kSlipWall ? edge - direction * k : edge;
    const auto from = static_cast<std::ptrdiff_t>(at) + (source - i[static_cast<std::size_t>(axis)]) * stride;
    for (std::size_t f = 0; f < fields.size(); ++f) {
      const double v = fields[f][from];
      fields[f][at] = (kind == BoundaryKind::kSlipWall && f == static_cast<std::size_t>(axis) + 1) ? -v : v;
    }
  }
}

/// Relaxation source of a sponge layer at one point, added to `source`: q relaxes at the rate
/// sigma to the face state. Whole state: dq/dt = -sigma (q - q_face). Thermodynamic (outflow
/// edges): density and pressure relax at fixed velocity,
///   d rho/dt = -sigma (rho - rho_face),  d(rho u)/dt = u d rho/dt,
///   d(rho E)/dt = -sigma (p - p_face)/(gamma - 1) + |u|^2/2 d rho/dt,
/// so du/dt = 0 and, at fixed density, dp/dt = -sigma (p - p_face). An acoustic wave carries p' and
/// is damped (at about sigma/2); a wake's velocity deficit passes unforced. The internal energy
/// is the same function of p for both states, so gamma is not needed.
template <int Dim>
void add_sponge_source(const Conserved<Dim>& q, const Conserved<Dim>& face, double sigma, bool thermodynamic,
                       Conserved<Dim>& source) {
  if (!thermodynamic) {
    for (std::size_t f = 0; f < q.size(); ++f) source[f] -= sigma * (q[f] - face[f]);
    return;
  }
  constexpr auto energy = static_cast<std::size_t>(Dim + 1);
  double momentum2 = 0, face_momentum2 = 0;
  for (std::size_t i = 1; i <= static_cast<std::size_t>(Dim); ++i) {
    momentum2 += q[i] * q[i];
    face_momentum2 += face[i] * face[i];
  }
  const double rho = q[0];
  // (p - p_face)/(gamma - 1): the difference of the internal energies per volume.
  const double internal_excess = (q[energy] - 0.5 * momentum2 / rho) - (face[energy] - 0.5 * face_momentum2 / face[0]);
  const double drho = -sigma * (rho - face[0]);
  source[0] += drho;
  for (std::size_t i = 1; i <= static_cast<std::size_t>(Dim); ++i) source[i] += drho * q[i] / rho;
  source[energy] += -sigma * internal_excess + 0.5 * momentum2 / (rho * rho) * drho;
}

}  // namespace grainwave::fluid
