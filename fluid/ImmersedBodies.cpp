#include "fluid/ImmersedBodies.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace grainwave::fluid {

namespace {

std::array<double, 3> three(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

}  // namespace

double smoothed_mask(double d, double w) {
  if (d <= -w) return 0;
  if (d >= w) return 1;
  const double s = d / w;
  return 0.5 * (1 + s + std::sin(std::numbers::pi * s) / std::numbers::pi);
}

double Body::signed_distance(const std::array<double, 3>& x, double t, std::array<double, 3>& inward) const {
  const double d = shape_distance(x, t, inward);
  if (!solid_outside) return d;
  for (double& n : inward) n = -n;
  return -d;
}

std::array<double, 2> Body::distance_bounds(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                                            double t) const {
  const auto bounds = shape_distance_bounds(lo, hi, t);
  return solid_outside ? std::array<double, 2>{-bounds[1], -bounds[0]} : bounds;
}

double Body::shape_distance(const std::array<double, 3>& x, double t, std::array<double, 3>& inward) const {
  const auto c = centre_at(t);
  std::array<double, 3> r{x[0] - c[0], x[1] - c[1], x[2] - c[2]};
  switch (shape) {
    case BodyShape::kSphere:
    case BodyShape::kCylinder: {
      if (shape == BodyShape::kCylinder) r[2] = 0;
      const double len = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      // At the centre any direction will do: chi = 1 there and no term uses n deep inside.
      for (std::size_t a = 0; a < 3; ++a) inward[a] = len > 0 ? -r[a] / len : (a == 0 ? -1.0 : 0.0);
      return radius - len;
    }
    case BodyShape::kHalfSpace: {
      // The solid lies on the side the normal points away from: d = -(x - c).n_out.
      double d = 0;
      for (std::size_t a = 0; a < 3; ++a) {
        d -= r[a] * normal[a];
        inward[a] = -normal[a];
      }
      return d;
    }
    case BodyShape::kBox: {
      // Inside: the distance to the nearest face; outside: the distance to the box.
      std::array<double, 3> q{};
      std::size_t nearest = 0;
      double outside2 = 0;
      for (std::size_t a = 0; a < 3; ++a) {
        q[a] = std::abs(r[a]) - half_size[a];
        if (q[a] > q[nearest]) nearest = a;
        outside2 += std::max(q[a], 0.0) * std::max(q[a], 0.0);
      }
      inward = {0, 0, 0};
      if (q[nearest] <= 0) {
        inward[nearest] = r[nearest] > 0 ? -1.0 : 1.0;
        return -q[nearest];
      }
      const double out = std::sqrt(outside2);
      for (std::size_t a = 0; a < 3; ++a) inward[a] = q[a] > 0 ? -std::copysign(q[a], r[a]) / out : 0.0;
      return -out;
    }
  }
  return 0;
}

std::array<double, 3> Body::velocity_at(const std::array<double, 3>& x, double t) const {
  const auto c = centre_at(t);
  const std::array<double, 3> r{x[0] - c[0], x[1] - c[1], x[2] - c[2]};
  const auto& w = angular_velocity;
  return {velocity[0] + w[1] * r[2] - w[2] * r[1], velocity[1] + w[2] * r[0] - w[0] * r[2],
          velocity[2] + w[0] * r[1] - w[1] * r[0]};
}

std::array<double, 2> Body::shape_distance_bounds(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                                                  double t) const {
  const auto c = centre_at(t);
  switch (shape) {
    case BodyShape::kSphere:
    case BodyShape::kCylinder: {
      const int axes = shape == BodyShape::kCylinder ? 2 : 3;
      double near2 = 0, far2 = 0;
      for (std::size_t a = 0; a < static_cast<std::size_t>(axes); ++a) {
        const double below = lo[a] - c[a], above = hi[a] - c[a];
        const double nearest = below > 0 ? below : above < 0 ? above : 0.0;
        near2 += nearest * nearest;
        far2 += std::max(below * below, above * above);
      }
      return {radius - std::sqrt(far2), radius - std::sqrt(near2)};
    }
    case BodyShape::kHalfSpace: {
      double dmin = 0, dmax = 0;
      for (std::size_t a = 0; a < 3; ++a) {
        const double e1 = -(lo[a] - c[a]) * normal[a], e2 = -(hi[a] - c[a]) * normal[a];
        dmin += std::min(e1, e2);
        dmax += std::max(e1, e2);
      }
      return {dmin, dmax};
    }
    case BodyShape::kBox: {
      // Outside the box grown by |d|: a loose but safe interval from the box-to-box gap and overlap.
      double gap2 = 0, depth = std::numeric_limits<double>::infinity();
      for (std::size_t a = 0; a < 3; ++a) {
        const double below = lo[a] - c[a], above = hi[a] - c[a];
        const double nearest = below > 0 ? below : above < 0 ? above : 0.0;
        const double excess = std::max(std::abs(nearest) - half_size[a], 0.0);
        gap2 += excess * excess;
        depth = std::min(depth, half_size[a] - std::abs(nearest));
      }
      const double dmax = gap2 > 0 ? -std::sqrt(gap2) : depth;
      double far2 = 0;
      for (std::size_t a = 0; a < 3; ++a) {
        const double far = std::max(std::abs(lo[a] - c[a]), std::abs(hi[a] - c[a]));
        far2 += far * far;
      }
      return {-std::sqrt(far2), dmax};
    }
  }
  return {0, 0};
}

void declare_penalization(SceneSchema& schema) {
  auto& s = schema.section(
      "penalization",
      "Parameters of the characteristic-based Brinkman volume penalization of the [[body]] entries "
      "(002 Eqs 2.27-2.30; Brown-Dymkoski, Kasimov & Vasilyev 2014).");
  s.real("eta_b", 0.0, "Brinkman permeability eta_b (no-slip; integrated exactly, so it does not limit the step); 0: 0.01 h, h the finest spacing").at_least(0);
  s.real("eta_c", 0.0,
         "characteristic penalization eta_c (Neumann conditions on rho and T; 1/eta_c is the speed at which "
         "the wall values are carried into the body); 0: 1 (the reference sound speed)")
      .at_least(0);
  s.real("nu_n", 0.0, "numerical viscosity on the velocity inside bodies (0: none)").at_least(0);
  s.real("characteristic_gain", 1.0,
         "the characteristic terms (Neumann conditions on rho and T) act with weight min(1, gain chi); 1: weight chi, "
         "as in Brown-Dymkoski et al. A gain of 30 lets them run at full speed where the Brinkman term already "
         "holds the velocity: waves reflect from walls 3x more accurately at eta_c = 1, but the Re 40 cylinder's "
         "drag drops by 3.8% (see fluid/Penalization.hpp)")
      .at_least(1);
  s.real("smoothing", 1.5, "half-width of the mask's smoothed step, in finest grid spacings").above(0);
  s.real("mask_depth", -1.0,
         "depth of the mask's mid-point (chi = 1/2) inside the body surface, in finest grid spacings; negative: "
         "0.91 smoothing - 0.445, which puts the effective no-slip wall at the surface (calibrated on the Rayleigh "
         "problem for smoothing 1-3, see ImmersedBodies.hpp)");
  s.real("average_after", 0.0, "time-averaged force metrics (Cd_mean, Cl_amplitude, St) use t >= this")
      .at_least(0);
  s.real("reference_speed", 0.0,
         "U of the force coefficients; 0: the uniform free-stream speed, or the first body's speed in still gas")
      .at_least(0);
  s.flag("refine_control_volume", true,
         "keep each body's control-volume box (and its weight's ramp) at the finest level, so the momentum-balance "
         "cross-check does not carry the adaptive grid's threshold error (false: only the interface band is)");
  s.flag("control_volume_check", true,
         "measure each body's force a second time, by the momentum balance over a box around it (Cd_control_volume, "
         "forces.csv's Fx_cv..): an independent check of the volume integral, which needs the stresses over the "
         "box's ramp, about half the force measurement's time around moving bodies; false leaves it out (those "
         "columns then read nan) and the boxes unrefined");
  s.real("start_ramp", 0.0,
         "soft start: the no-slip target velocity goes smoothly from the free stream to the body velocity over "
         "this time (0: impulsive start)")
      .at_least(0);

  auto& b = schema.section("body", "One immersed body, imposed by penalization (needs [fluid]).", true);
  b.text("shape", "cylinder", "cylinder (2D disc; axis z in 3D), sphere, half_space or box")
      .one_of({"cylinder", "sphere", "half_space", "box"});
  b.reals("centre", std::vector<double>{0, 0, 0}, "centre at t = 0 (half_space: a point of its plane)").of_length(3);
  b.real("radius", 0.5, "radius (cylinder, sphere)").above(0);
  b.reals("half_size", std::vector<double>{0.5, 0.5, 0.5}, "box: half widths").of_length(3);
  b.reals("normal", std::vector<double>{-1, 0, 0}, "half_space: outward normal of the solid (towards the gas)")
      .of_length(3);
  b.reals("velocity", std::vector<double>{0, 0, 0}, "translational velocity (prescribed, constant)").of_length(3);
  b.reals("angular_velocity", std::vector<double>{0, 0, 0}, "angular velocity (prescribed, constant)").of_length(3);
  b.text("solid", "inside",
         "inside: the body is the shape; outside: the shape is a hollow in the solid (a container, e.g. the outer "
         "wall of a Couette cell; its forces are those on the container, without a control-volume cross-check)")
      .one_of({"inside", "outside"});
  b.text("wall", "adiabatic", "thermal condition: adiabatic (dT/dn = 0) or isothermal (T = wall_temperature)")
      .one_of({"adiabatic", "isothermal"});
  b.real("wall_temperature", 1.0, "isothermal wall temperature (T = c^2; 1 in the reference gas)").above(0);
  b.real("control_volume", 0.0,
         "half-width of the control-volume box around the body for the momentum-balance force (0: 1 diameter)")
      .at_least(0);
}

PenalizationSettings read_penalization(const Scene& scene, int dim) {
  PenalizationSettings out;
  const auto& entries = scene.entries("body");
  if (scene.has("penalization")) {
    const auto& s = scene.section("penalization");
    out.eta_b = s.real("eta_b");
    out.eta_c = s.real("eta_c");
    out.nu_n = s.real("nu_n");
    out.characteristic_gain = s.real("characteristic_gain");
    out.smoothing = s.real("smoothing");
    out.mask_depth = s.real("mask_depth");
    out.average_after = s.real("average_after");
    out.reference_speed = s.real("reference_speed");
    out.start_ramp = s.real("start_ramp");
    out.control_volume_check = s.flag("control_volume_check");
    out.refine_control_volume = out.control_volume_check && s.flag("refine_control_volume");
    if (entries.empty()) s.fail("eta_b", "[penalization] without any [[body]] entry");
  }
  for (const auto& e : entries) {
    Body body;
    const auto& shape = e.text("shape");
    body.shape = shape == "sphere"       ? BodyShape::kSphere
                 : shape == "half_space" ? BodyShape::kHalfSpace
                 : shape == "box"        ? BodyShape::kBox
                                         : BodyShape::kCylinder;
    if (body.shape == BodyShape::kSphere && dim < 3)
      e.fail("shape", "a sphere needs a 3D fluid", "use shape = \"cylinder\" in 2D");
    if (body.shape == BodyShape::kCylinder && dim < 2)
      e.fail("shape", "a cylinder needs a 2D or 3D fluid", "use shape = \"half_space\" in 1D");
    body.centre = three(e.reals("centre"));
    body.radius = e.real("radius");
    body.half_size = three(e.reals("half_size"));
    body.velocity = three(e.reals("velocity"));
    body.angular_velocity = three(e.reals("angular_velocity"));
    auto n = three(e.reals("normal"));
    double norm = 0;
    for (int a = 0; a < dim; ++a) norm += n[static_cast<std::size_t>(a)] * n[static_cast<std::size_t>(a)];
    for (int a = dim; a < 3; ++a) n[static_cast<std::size_t>(a)] = 0;
    if (body.shape == BodyShape::kHalfSpace && !(norm > 0))
      e.fail("normal", "the normal needs a non-zero component within the scene's dimension");
    for (auto& c : n) c = norm > 0 ? c / std::sqrt(norm) : 0.0;
    body.normal = n;
    for (int a = dim; a < 3; ++a) {
      const auto au = static_cast<std::size_t>(a);
      if (body.velocity[au] != 0 || body.centre[au] != 0)
        e.fail("velocity", fmt::format("a {}D body moves and sits in the first {} coordinates only", dim, dim));
    }
    if (dim == 2 && (body.angular_velocity[0] != 0 || body.angular_velocity[1] != 0))
      e.fail("angular_velocity", "a 2D body rotates about z only");
    body.solid_outside = e.text("solid") == "outside";
    body.thermal = e.text("wall") == "isothermal" ? WallThermal::kIsothermal : WallThermal::kAdiabatic;
    body.wall_temperature = e.real("wall_temperature");
    const double cv = e.real("control_volume");
    body.control_half_width = cv > 0 ? cv : body.diameter();
    out.bodies.push_back(body);
  }
  return out;
}

}  // namespace grainwave::fluid
