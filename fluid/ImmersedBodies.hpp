#pragma once
// Bodies immersed in the flow by volume penalization (002 §2.4.1; Brown-Dymkoski, Kasimov &
// Vasilyev, J. Comput. Phys. 262 (2014)): their shapes as signed distances, the smoothed mask
// chi, the inward normal n and the rigid-body velocity field u0 = v + omega x (x - centre).
//
// The mask is a smoothed step S of the signed distance d (positive inside the body),
//     S(d; w) = 0 for d <= -w,  1 for d >= w,  (1 + d/w + sin(pi d / w) / pi) / 2 between,
// continuous with its first derivative, so the penalized solution and its derivatives stay
// smooth for the central stencils; w is the smoothing half-width, set per scene in units of the
// finest grid spacing. The penalization mask is chi = S(d - delta; w): its mid-point lies a depth
// delta inside the surface. Where the no-slip wall ends up is set by the Brinkman term, which
// holds the velocity at rest wherever chi / eta_b exceeds the viscous rate nu / h^2: with the
// default eta_b = 0.01 h that happens already at chi ~ 1e-3, i.e. near the onset of the step,
// not at its mid-point. A step starting at the surface (delta = w) therefore shrank bodies by
// about 0.9 h (on the Re 40 cylinder at D/16: Cd 1.47 and Lr/D 1.68 instead of 1.53 and 2.2).
// The default delta = 0.91 w - 0.445 h was calibrated on the Rayleigh problem (impulsively
// started flow over a penalized half-space, exact u = U erf(y / 2 sqrt(nu t))): the wall position
// fitted to the computed profile, averaged over 8 sub-grid alignments of the surface, is within
// 0.04 h of the nominal surface for w = 1.5 h, Re_a = 100-500 and two grid levels, and within
// 0.06 h for w = 1 and 3 h (the formula is only calibrated for 1 <= w/h <= 3). Single alignments
// scatter by +-0.3 h (the staircase of the grid); curved bodies average over them. On curved
// walls (circular Couette flow, cases/couette_penalized.toml) the wall sits about 0.1 h into the
// gas on both the convex and the concave side. tests/cases/test_penalization.py re-checks both.
//
// Prescribed motion: constant translational velocity v and angular velocity omega; the centre
// moves as centre(t) = centre(0) + v t. Particles moved by the fluid enter through the same
// description (coupling/), with v and omega updated every step.
#include <array>
#include <string>
#include <vector>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"

namespace grainwave::fluid {

enum class BodyShape { kSphere, kCylinder, kHalfSpace, kBox };
enum class WallThermal { kAdiabatic, kIsothermal };

struct Body {
  BodyShape shape = BodyShape::kCylinder;
  std::array<double, 3> centre{};            ///< at t = 0; a point of the plane for a half-space
  double radius = 0.5;                        ///< sphere, cylinder (a cylinder's axis is z)
  std::array<double, 3> half_size{};          ///< box
  std::array<double, 3> normal{1, 0, 0};      ///< half-space: outward normal of the solid (unit)
  std::array<double, 3> velocity{};           ///< v
  std::array<double, 3> angular_velocity{};  ///< omega
  WallThermal thermal = WallThermal::kAdiabatic;
  double wall_temperature = 1;  ///< T_w of an isothermal wall (T = c^2, 1 in the far field)
  double control_half_width = 0;  ///< control volume: a box of this half-width around the centre
  bool solid_outside = false;     ///< a container: the solid is the shape's complement

  std::array<double, 3> centre_at(double t) const {
    return {centre[0] + velocity[0] * t, centre[1] + velocity[1] * t, centre[2] + velocity[2] * t};
  }
  /// Signed distance to the surface (positive in the solid) and its gradient (the unit normal into
  /// the solid).
  double signed_distance(const std::array<double, 3>& x, double t, std::array<double, 3>& inward) const;
  /// Rigid-body velocity at x.
  std::array<double, 3> velocity_at(const std::array<double, 3>& x, double t) const;
  /// Bounds of the signed distance over an axis-aligned box [lo, hi] (lower may be loose).
  std::array<double, 2> distance_bounds(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                                        double t) const;
  /// Frontal length scale: the diameter (sphere, cylinder) or box width.
  double diameter() const { return 2 * radius; }

 private:
  // The same for the shape itself (positive inside it), before solid_outside flips the sign.
  double shape_distance(const std::array<double, 3>& x, double t, std::array<double, 3>& inward) const;
  std::array<double, 2> shape_distance_bounds(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                                              double t) const;
};

/// Smoothed mask of a signed distance with half-width w.
double smoothed_mask(double d, double w);

/// Default depth of the mask's mid-point inside the surface, in finest spacings, for a smoothing
/// half-width w in finest spacings (the calibration above).
constexpr double default_mask_depth(double w) { return 0.91 * w - 0.445; }

/// The scene's immersed bodies and penalization parameters ([penalization] and [[body]]).
struct PenalizationSettings {
  std::vector<Body> bodies;
  double eta_b = 0;       ///< Brinkman permeability (time); 0 in the scene: tied to the finest spacing
  double eta_c = 0;       ///< characteristic term: 1/eta_c is the inward speed; 0: as above
  double nu_n = 0;        ///< numerical viscosity on the velocity inside bodies
  /// The characteristic (Neumann) terms act with weight min(1, gain chi) rather than chi, so they
  /// run at full speed wherever the Brinkman term holds the velocity (Penalization.hpp); 1: chi.
  double characteristic_gain = 1;
  double smoothing = 1.5;  ///< mask half-width in finest spacings
  double mask_depth = -1;  ///< depth of chi = 1/2 inside the surface, finest spacings (< 0: smoothing)
  double average_after = 0;  ///< force averages (Cd_mean, St) over t >= this
  double reference_speed = 0;  ///< U of the coefficients; 0: the free stream or the first body's speed
  double start_ramp = 0;       ///< time over which the no-slip target goes from free stream to body velocity
  bool refine_control_volume = true;  ///< control-volume boxes forced to the finest level
  /// Each body's force measured a second way, by the momentum balance over its box (force_cv).
  bool control_volume_check = true;
  bool empty() const { return bodies.empty(); }
};

void declare_penalization(SceneSchema& schema);
/// Reads the bodies (none when the scene has no [[body]]); dim is the fluid's dimension.
PenalizationSettings read_penalization(const Scene& scene, int dim);

}  // namespace grainwave::fluid
