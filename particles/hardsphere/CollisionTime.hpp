#pragma once
// Time of first contact of two particles in free flight (002 §2.3.3, Eq. 2.26 with Eq. 2.11).
//
// With relative position d, velocity u and (constant) acceleration a at t = 0,
//   f(t) = |d + u t + a t^2 / 2|^2 - sigma^2
//        = (a.a/4) t^4 + (u.a) t^3 + (u.u + d.a) t^2 + 2 (d.u) t + (d.d - sigma^2),
// a quartic; contact is the first t in [0, T] where f reaches zero while decreasing. Its real roots
// are isolated without sampling: the critical points of f (roots of the cubic f', found the same
// way from f'') split [0, T] into pieces on which f is monotone, so each piece holds at most one
// root, bracketed exactly; a safeguarded Newton–Raphson/bisection iteration (Press et al.,
// "rtsafe", the method 002 cites) converges on it. When the accelerations are equal (a = 0) f is a
// quadratic and the root is taken in closed form (the event-driven case, 002 §2.3.3).
//
// The returned time lies on the non-overlapping side of the root (f >= 0) within a few ulps, so a
// pair rewound to it never starts its collision overlapped by more than round-off. A pair that
// already overlaps and is approaching gets t = 0; one that overlaps but separates gets no contact
// unless it turns round and approaches again inside [0, T].
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

namespace grainwave::particles::hardsphere {

namespace polynomial {

/// Coefficients c[0] + c[1] t + ... + c[D] t^D.
template <int D>
using Coefficients = std::array<double, D + 1>;

template <int D>
inline double evaluate(const Coefficients<D>& c, double t) {
  double p = c[D];
  for (int k = D - 1; k >= 0; --k) p = p * t + c[static_cast<std::size_t>(k)];
  return p;
}

template <int D>
inline Coefficients<D - 1> derivative(const Coefficients<D>& c) {
  Coefficients<D - 1> d{};
  for (int k = 1; k <= D; ++k) d[static_cast<std::size_t>(k - 1)] = k * c[static_cast<std::size_t>(k)];
  return d;
}

/// The single root of p in [lo, hi] given p(lo) > 0 >= p(hi) or p(lo) < 0 <= p(hi) and p monotone
/// there. Returns a point on the side of p(lo)'s sign, within a few ulps of the root.
template <int D>
inline double monotone_root(const Coefficients<D>& p, double lo, double hi) {
  const Coefficients<D - 1> dp = derivative<D>(p);
  const double sign_lo = evaluate<D>(p, lo) > 0.0 ? 1.0 : -1.0;
  const double tol = 8.0 * std::numeric_limits<double>::epsilon() *
                     std::max({std::abs(lo), std::abs(hi), std::numeric_limits<double>::min()});
  double t = 0.5 * (lo + hi);
  double previous_step = hi - lo;
  for (int iteration = 0; iteration < 200; ++iteration) {
    const double value = evaluate<D>(p, t);
    const bool before_root = value * sign_lo > 0.0;
    if (before_root) lo = t; else hi = t;
    if (hi - lo <= 2.0 * tol) break;
    const double slope = evaluate<D - 1>(dp, t);
    double next = slope != 0.0 ? t - value / slope : 0.5 * (lo + hi);
    // A converged Newton step is pushed just past the root so the bracket closes on both sides.
    if (std::abs(next - t) <= tol) next = t + (before_root ? tol : -tol);
    // Newton only while it stays inside the bracket and at least halves the step (rtsafe rule);
    // bisection otherwise, so flat (grazing) roots still converge in ~60 iterations.
    if (!(next > lo && next < hi) || std::abs(next - t) > 0.5 * previous_step) next = 0.5 * (lo + hi);
    previous_step = std::abs(next - t);
    t = next;
  }
  return lo;  // the side where p has p(lo)'s sign (f > 0: not yet touching)
}

/// Sorted real roots of p strictly inside (lo, hi), written to out; returns their count (<= D).
template <int D>
inline int roots_inside(const Coefficients<D>& p, double lo, double hi, double* out) {
  if constexpr (D == 1) {
    if (p[1] == 0.0) return 0;
    const double t = -p[0] / p[1];
    if (t > lo && t < hi) { out[0] = t; return 1; }
    return 0;
  } else {
    double breaks[D + 1];
    breaks[0] = lo;
    const int critical = roots_inside<D - 1>(derivative<D>(p), lo, hi, breaks + 1);
    breaks[critical + 1] = hi;
    int count = 0;
    for (int k = 0; k <= critical; ++k) {
      const double a = breaks[k], b = breaks[k + 1];
      const double fa = evaluate<D>(p, a), fb = evaluate<D>(p, b);
      if ((fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0)) {
        out[count++] = monotone_root<D>(p, a, b);
      } else if (fb == 0.0 && k < critical) {
        out[count++] = b;
      }
    }
    return count;
  }
}

}  // namespace polynomial

/// First t in [0, T] at which f (a quartic, see above) reaches 0 while decreasing.
inline std::optional<double> first_descending_zero(const polynomial::Coefficients<4>& f, double T) {
  double breaks[5];
  breaks[0] = 0.0;
  const int critical = polynomial::roots_inside<3>(polynomial::derivative<4>(f), 0.0, T, breaks + 1);
  breaks[critical + 1] = T;
  for (int k = 0; k <= critical; ++k) {
    const double a = breaks[k], b = breaks[k + 1];
    const double fa = polynomial::evaluate<4>(f, a), fb = polynomial::evaluate<4>(f, b);
    if (!(fb < fa) || fb > 0.0) continue;  // rising, or still apart at the end of this piece
    if (fa <= 0.0) return a;               // overlapping and (now) approaching
    return polynomial::monotone_root<4>(f, a, b);
  }
  // f'(0) < 0 with f(0) <= 0 but no decrease resolved numerically (T tiny): still approaching.
  if (polynomial::evaluate<4>(f, 0.0) <= 0.0 && f[1] < 0.0) return 0.0;
  return std::nullopt;
}

/// First contact time in [0, T] of two spheres whose centres are d apart (from 1 to 2), with
/// relative velocity u = v2 - v1 and relative acceleration a = a2 - a1, contact distance sigma.
inline std::optional<double> first_contact_time(const Eigen::Vector3d& d, const Eigen::Vector3d& u,
                                                const Eigen::Vector3d& a, double sigma, double T) {
  const polynomial::Coefficients<4> f{d.squaredNorm() - sigma * sigma, 2.0 * d.dot(u),
                                      u.squaredNorm() + d.dot(a), u.dot(a), 0.25 * a.squaredNorm()};
  return first_descending_zero(f, T);
}

/// Closed-form contact time for equal accelerations (relative motion is uniform): the smaller
/// root of |d + u t|^2 = sigma^2, in the cancellation-free form c / (-b + sqrt(b^2 - u.u c)).
/// No limit on t (event-driven use); returns nullopt when the pair never touches.
inline std::optional<double> ballistic_contact_time(const Eigen::Vector3d& d,
                                                    const Eigen::Vector3d& u, double sigma) {
  const double b = d.dot(u);
  if (!(b < 0.0)) return std::nullopt;  // not approaching
  const double c = d.squaredNorm() - sigma * sigma;
  if (c <= 0.0) return 0.0;  // overlapping and approaching
  const double discriminant = b * b - u.squaredNorm() * c;
  if (discriminant < 0.0) return std::nullopt;  // passes by
  return c / (-b + std::sqrt(discriminant));
}

/// The same root as ballistic_contact_time, +infinity when there is none, computed without
/// data-dependent branches (about half the candidates of a pair scan recede, and mispredicted
/// branches cost more than the always-taken square root). EventDrivenCollider::contact_times
/// spells this formula out on plain doubles so that the compiler vectorises it.
inline double ballistic_contact_time_or_never(const Eigen::Vector3d& d, const Eigen::Vector3d& u,
                                              double sigma) {
  const double b = d.dot(u);
  const double c = d.squaredNorm() - sigma * sigma;
  const double discriminant = b * b - u.squaredNorm() * c;
  const double t = std::max(0.0, c / (std::sqrt(std::max(discriminant, 0.0)) - b));
  return (b < 0.0 && discriminant >= 0.0) ? t : std::numeric_limits<double>::infinity();
}

/// First time in [0, T] at which a centre moving as h(t) = h0 + w t + g t^2 / 2 along a wall's
/// inward normal reaches distance `radius` from it while approaching (h = signed distance).
inline std::optional<double> wall_contact_time(double h0, double w, double g, double radius,
                                               double T) {
  const double gap = h0 - radius;
  // Reuse the quartic machinery with a degree-2 polynomial (zero t^3, t^4 terms).
  return first_descending_zero(polynomial::Coefficients<4>{gap, w, 0.5 * g, 0.0, 0.0}, T);
}

}  // namespace grainwave::particles::hardsphere
