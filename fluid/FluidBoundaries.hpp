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

}  // namespace grainwave::fluid
