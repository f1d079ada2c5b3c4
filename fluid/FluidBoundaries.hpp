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
//     exact there; for subsonic inflow it over-specifies and reflects outgoing sound (use
//     characteristic_inflow).
//   - outflow: zero-gradient extrapolation of the conserved variables (transmissive; it
//     reflects part of an acoustic wave).
//   - characteristic_outflow: non-reflecting, after the locally one-dimensional characteristic
//     analysis of Thompson (JCP 68, 1987) and Poinsot & Lele (JCP 101, 1992) with the pressure
//     relaxation of Rudy & Strikwerda (JCP 36, 1980), imposed through the ghosts. Linearised
//     about the edge point b (rho, u_n, c), the characteristic variables along the outward
//     normal are w+ = p + rho c u_n (speed u_n + c), w- = p - rho c u_n (u_n - c), the entropy
//     rho - p/c^2 and the tangential velocities (u_n). Outgoing ones keep their gradient: the
//     ghosts extrapolate them linearly from b and its inner neighbour. The incoming acoustic one
//     gets the gradient that makes its amplitude L- = (u_n - c) dw-/dn = K (p_b - p_far),
//     K = sigma (1 - M^2) c / L_domain: a slow pull of the edge pressure towards the far field
//     that keeps the mean state from drifting while passing waves leave (sigma -> 0: perfectly
//     non-reflecting but ill-posed; sigma ~ 0.25 is the usual compromise). At supersonic outflow
//     everything is extrapolated; where gas enters (u_n < 0) entropy and tangential velocity are
//     held at their edge values.
//   - characteristic_inflow: the same analysis on an edge where gas enters: the incoming
//     characteristics (entropy, tangential velocity, the inward acoustic wave) take the face's
//     far-field state, the outgoing acoustic wave leaves (the plain inflow fixes all of them and
//     reflects it). At supersonic inflow this is the plain inflow.
//   - no-slip walls (the wall on the edge point, as for the slip wall): the ghosts mirror the
//     density and reverse every velocity component, so u is odd about the wall. Adiabatic: the
//     temperature is even (no heat flux through the wall; with rho even and |u|^2 even the total
//     energy simply mirrors). Isothermal at T_w: the pressure is even (dp/dn = 0, the boundary-
//     layer approximation) and T_ghost = 2 T_w - T_mirror, so the central heat flux at the wall
//     sees the wall temperature; rho_ghost = gamma p / T_ghost. The wall point itself is held at
//     u = 0 (and T = T_w) by constrain_wall_point, applied to the state and to its time derivative.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <span>

#include "fluid/IdealGas.hpp"
#include "wavelet/ArrayShape.hpp"

namespace grainwave::fluid {

enum class BoundaryKind { kPeriodic, kSlipWall, kOutflow, kInflow, kNoSlipAdiabatic, kNoSlipIsothermal, kCharacteristic,
                          kCharacteristicInflow };

inline bool is_no_slip(BoundaryKind kind) {
  return kind == BoundaryKind::kNoSlipAdiabatic || kind == BoundaryKind::kNoSlipIsothermal;
}

/// What the ghosts of walls and characteristic outflows need beyond the state.
struct EdgeGas {
  double gamma = 1.4;
  double temperature = 1;  ///< T_w of an isothermal wall (T = gamma p / rho, the squared sound speed)
  double outflow_sigma = 0.25;  ///< characteristic outflow: pressure relaxation sigma
  double length = 1;            ///< characteristic outflow: domain length along the edge's normal
  double spacing = 0;           ///< the block's spacing along the normal
};

/// Ghost values beyond a characteristic edge (see the header): `edge` and `inner` are the
/// primitives at the edge point and its inner neighbour, `far` the face's far-field state, `axis`
/// the normal, `outward` +1 on a high edge and -1 on a low one, k the ghost layer. Outgoing
/// characteristics keep their gradient. Incoming ones: on an inflow edge they take the far
/// field's values (the outgoing acoustic wave leaves freely); on an outflow edge the acoustic one
/// gets the amplitude K (p_b - p_far) and entropy and tangential velocity stay at the edge's.
template <int Dim>
Primitive<Dim> characteristic_ghost(const Primitive<Dim>& edge, const Primitive<Dim>& inner, const Primitive<Dim>& far,
                                    int axis, int outward, int k, bool inflow_edge, const EdgeGas& gas) {
  const auto n = static_cast<std::size_t>(axis);
  const double c = std::sqrt(gas.gamma * edge.p / edge.rho), impedance = edge.rho * c, layers = k;
  struct Characteristics { double out, in, entropy; };  // p + Z u_n, p - Z u_n, rho - p/c^2
  const auto of = [&](const Primitive<Dim>& w) {
    const double un = outward * w.u[n];
    return Characteristics{w.p + impedance * un, w.p - impedance * un, w.rho - w.p / (c * c)};
  };
  const auto at_edge = of(edge), at_inner = of(inner), at_far = of(far);
  const auto extrapolated = [&](double value, double inner_value) { return value + layers * (value - inner_value); };
  const double un = outward * edge.u[n];
  const double w_out = un + c > 0 ? extrapolated(at_edge.out, at_inner.out) : at_far.out;
  double w_in = 0;
  if (un - c > 0) {
    w_in = extrapolated(at_edge.in, at_inner.in);
  } else if (inflow_edge) {
    w_in = at_far.in;
  } else {
    const double mach = un / c;
    const double relaxation = gas.outflow_sigma * (1 - mach * mach) * c / gas.length;
    w_in = at_edge.in + layers * gas.spacing * relaxation * (edge.p - far.p) / (un - c);
  }
  const bool leaving = un > 0;
  Primitive<Dim> ghost;
  ghost.p = 0.5 * (w_out + w_in);
  const double entropy = leaving ? extrapolated(at_edge.entropy, at_inner.entropy) : inflow_edge ? at_far.entropy : at_edge.entropy;
  ghost.rho = entropy + ghost.p / (c * c);
  for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a)
    ghost.u[a] = leaving ? extrapolated(edge.u[a], inner.u[a]) : inflow_edge ? far.u[a] : edge.u[a];
  ghost.u[n] = outward * (w_out - w_in) / (2 * impedance);
  return ghost;
}

/// Fills the ghosts of one block beyond one edge (axis, high side or not) for the Dim + 2
/// conserved fields. bs: interior points per axis, g: ghost layers; inflow: the conserved state
/// of an inflow edge (the far field of a characteristic one); gas: what walls and characteristic
/// edges need beyond the state.
template <int Dim>
void fill_edge_ghosts(std::span<double* const> fields, const wavelet::ArrayShape<Dim>& shape, int bs, int g, int axis,
                      bool high, BoundaryKind kind, std::span<const double> inflow, const EdgeGas& gas = {}) {
  const std::ptrdiff_t stride = shape.stride(axis);
  const int edge = high ? g + bs - 1 : g;  // array coordinate of the edge point
  const int direction = high ? 1 : -1;
  Primitive<Dim> far{};  // the face's state, for characteristic edges
  if (kind == BoundaryKind::kCharacteristic || kind == BoundaryKind::kCharacteristicInflow) {
    Conserved<Dim> far_state{};
    for (std::size_t f = 0; f < far_state.size(); ++f) far_state[f] = inflow[f];
    far = to_primitive<Dim>(far_state, gas.gamma);
  }
  // The layers beyond the edge, k = 1, 2, ...: the points with i[axis] = edge + direction k are
  // runs of `stride` consecutive indices, one every stride * extent. Every value below is read
  // from the edge side, so the order of the points does not matter.
  const int extent = shape.extent[static_cast<std::size_t>(axis)];
  const auto period = static_cast<std::size_t>(stride) * static_cast<std::size_t>(extent);
  for (int k = 1; edge + direction * k >= 0 && edge + direction * k < extent; ++k) {
    const int layer = edge + direction * k;  // array coordinate along `axis`
    for (std::size_t run = static_cast<std::size_t>(layer) * static_cast<std::size_t>(stride); run < shape.size();
         run += period) {
      for (std::size_t at = run; at < run + static_cast<std::size_t>(stride); ++at) {
        if (kind == BoundaryKind::kInflow) {
          for (std::size_t f = 0; f < fields.size(); ++f) fields[f][at] = inflow[f];
          continue;
        }
        if (kind == BoundaryKind::kCharacteristic || kind == BoundaryKind::kCharacteristicInflow) {
          const auto primitive_at = [&](std::ptrdiff_t index) {
            Conserved<Dim> q{};
            for (std::size_t f = 0; f < q.size(); ++f) q[f] = fields[f][index];
            return to_primitive<Dim>(q, gas.gamma);
          };
          const auto edge_at = static_cast<std::ptrdiff_t>(at) + (edge - layer) * stride;
          const auto ghost = to_conserved<Dim>(
              characteristic_ghost<Dim>(primitive_at(edge_at), primitive_at(edge_at - direction * stride),
                                        far, axis, direction, k,
                                        kind == BoundaryKind::kCharacteristicInflow, gas),
              gas.gamma);
          for (std::size_t f = 0; f < ghost.size(); ++f) fields[f][at] = ghost[f];
          continue;
        }
        const bool mirror = kind == BoundaryKind::kSlipWall || is_no_slip(kind);
        const int source = mirror ? edge - direction * k : edge;
        const auto from = static_cast<std::ptrdiff_t>(at) + (source - layer) * stride;
        if (kind == BoundaryKind::kNoSlipAdiabatic) {
          fields[0][at] = fields[0][from];
          for (std::size_t f = 1; f <= static_cast<std::size_t>(Dim); ++f) fields[f][at] = -fields[f][from];
          fields[Dim + 1][at] = fields[Dim + 1][from];
          continue;
        }
        if (kind == BoundaryKind::kNoSlipIsothermal) {
          Conserved<Dim> q{};
          for (std::size_t f = 0; f < q.size(); ++f) q[f] = fields[f][from];
          auto w = to_primitive<Dim>(q, gas.gamma);
          // Kept positive when the gas next to the wall is much hotter than twice the wall.
          const double t_ghost = std::max(2 * gas.temperature - temperature(w.rho, w.p, gas.gamma), 0.1 * gas.temperature);
          w.rho = gas.gamma * w.p / t_ghost;
          for (auto& u : w.u) u = -u;
          q = to_conserved<Dim>(w, gas.gamma);
          for (std::size_t f = 0; f < q.size(); ++f) fields[f][at] = q[f];
          continue;
        }
        for (std::size_t f = 0; f < fields.size(); ++f) {
          const double v = fields[f][from];
          fields[f][at] = (kind == BoundaryKind::kSlipWall && f == static_cast<std::size_t>(axis) + 1) ? -v : v;
        }
      }
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

/// Holds a no-slip wall point at rest (and an isothermal one at T_w). Applied alike to the state
/// q (zero momentum; isothermal: E = rho T_w / (gamma (gamma - 1))) and to its time derivative
/// (zero momentum rate; isothermal: dE/dt = T_w / (gamma (gamma - 1)) d rho/dt): both relations
/// are linear in (rho, E) once the momentum is zero. The density evolves by the mass flux.
template <int Dim>
void constrain_wall_point(std::span<double> q, BoundaryKind kind, const EdgeGas& wall) {
  for (std::size_t f = 1; f <= static_cast<std::size_t>(Dim); ++f) q[f] = 0;
  if (kind == BoundaryKind::kNoSlipIsothermal) q[Dim + 1] = q[0] * wall.temperature / (wall.gamma * (wall.gamma - 1));
}

}  // namespace grainwave::fluid
