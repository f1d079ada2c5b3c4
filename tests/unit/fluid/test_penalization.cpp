// Immersed-body geometry and the pointwise penalization terms: signed distances and inward
// normals of each shape, the distance bounds used for forced refinement (checked against
// sampled points), the smoothed mask, the rigid-body velocity, the exact Brinkman relaxation
// and the chain rule from primitive to conserved penalty rates.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "fluid/IdealGas.hpp"
#include "fluid/ImmersedBodies.hpp"
#include "fluid/Penalization.hpp"

namespace gf = grainwave::fluid;

namespace {

gf::Body make(gf::BodyShape shape) {
  gf::Body b;
  b.shape = shape;
  b.centre = {0.3, -0.2, 0.1};
  b.radius = 0.5;
  b.half_size = {0.4, 0.3, 0.2};
  b.normal = {0.6, 0.8, 0};
  return b;
}

}  // namespace

TEST(Penalization, SignedDistanceAndInwardNormal) {
  std::array<double, 3> n{};
  const auto sphere = make(gf::BodyShape::kSphere);
  EXPECT_NEAR(sphere.signed_distance({0.3, -0.2, 0.1}, 0, n), 0.5,
              1e-15);  // centre: depth = radius
  EXPECT_NEAR(sphere.signed_distance({1.3, -0.2, 0.1}, 0, n), -0.5, 1e-15);
  EXPECT_NEAR(n[0], -1, 1e-15);  // inward: back towards the centre
  const auto cylinder = make(gf::BodyShape::kCylinder);
  EXPECT_NEAR(cylinder.signed_distance({0.3, 0.5, 7.0}, 0, n), -0.2, 1e-15);  // z plays no part
  EXPECT_NEAR(n[1], -1, 1e-15);
  const auto plane = make(gf::BodyShape::kHalfSpace);  // solid where (x - c) . n_out < 0
  EXPECT_NEAR(plane.signed_distance({0.3 - 0.6, -0.2 - 0.8, 0}, 0, n), 1.0, 1e-15);
  EXPECT_NEAR(n[0], -0.6, 1e-15);
  const auto box = make(gf::BodyShape::kBox);
  EXPECT_NEAR(box.signed_distance({0.3, -0.2, 0.1}, 0, n), 0.2, 1e-15);  // nearest face: z
  EXPECT_NEAR(box.signed_distance({0.3 + 0.7, -0.2 + 0.7, 0.1}, 0, n), -0.5,
              1e-15);                               // corner (0.3, 0.4)
  auto container = make(gf::BodyShape::kCylinder);  // solid beyond the radius
  container.solid_outside = true;
  EXPECT_NEAR(container.signed_distance({0.3, 0.5, 7.0}, 0, n), 0.2, 1e-15);
  EXPECT_NEAR(n[1], 1, 1e-15);  // into the solid: away from the axis
}

TEST(Penalization, DistanceBoundsEncloseSampledDistances) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.5, 1.5), w(0.01, 0.6);
  for (auto shape : {gf::BodyShape::kSphere, gf::BodyShape::kCylinder, gf::BodyShape::kHalfSpace,
                     gf::BodyShape::kBox})
    for (bool container : {false, true}) {
      auto body = make(shape);
      body.solid_outside = container;
      for (int trial = 0; trial < 200; ++trial) {
        std::array<double, 3> lo{}, hi{};
        for (std::size_t a = 0; a < 3; ++a) {
          lo[a] = u(rng);
          hi[a] = lo[a] + w(rng);
        }
        const auto bounds = body.distance_bounds(lo, hi, 0);
        for (int s = 0; s < 27; ++s) {
          std::array<double, 3> x{}, n{};
          int rest = s;
          for (std::size_t a = 0; a < 3; ++a, rest /= 3)
            x[a] = lo[a] + 0.5 * (rest % 3) * (hi[a] - lo[a]);
          const double d = body.signed_distance(x, 0, n);
          ASSERT_GE(d, bounds[0] - 1e-12) << "shape " << static_cast<int>(shape);
          ASSERT_LE(d, bounds[1] + 1e-12) << "shape " << static_cast<int>(shape);
        }
      }
    }
}

TEST(Penalization, SmoothedMaskIsAC1Step) {
  const double w = 0.3;
  EXPECT_EQ(gf::smoothed_mask(-w, w), 0.0);
  EXPECT_EQ(gf::smoothed_mask(w, w), 1.0);
  EXPECT_NEAR(gf::smoothed_mask(0, w), 0.5, 1e-15);
  const double e = 1e-6;  // slope vanishes at both ends, is 1/w in the middle
  EXPECT_NEAR((gf::smoothed_mask(-w + e, w) - gf::smoothed_mask(-w, w)) / e, 0.0, 1e-6);
  EXPECT_NEAR((gf::smoothed_mask(e, w) - gf::smoothed_mask(-e, w)) / (2 * e), 1 / w, 1e-6);
  for (double d = -w; d < w; d += 0.01)
    EXPECT_LE(gf::smoothed_mask(d, w), gf::smoothed_mask(d + 0.01, w));
}

TEST(Penalization, RigidBodyVelocityAndMotion) {
  auto body = make(gf::BodyShape::kCylinder);
  body.velocity = {0.1, 0.2, 0};
  body.angular_velocity = {0, 0, 2};
  const auto c = body.centre_at(3.0);
  EXPECT_NEAR(c[0], 0.6, 1e-15);
  EXPECT_NEAR(c[1], 0.4, 1e-15);
  const auto v = body.velocity_at({c[0] + 0.5, c[1], 0}, 3.0);  // omega x r = (0, 1, 0)
  EXPECT_NEAR(v[0], 0.1, 1e-15);
  EXPECT_NEAR(v[1], 1.2, 1e-15);
}

TEST(Penalization, BrinkmanRelaxationIsExactAndKeepsInternalEnergy) {
  const double gamma = 1.4, eta = 1e-3, tau = 2e-3, chi = 0.7;
  gf::Primitive<2> w{1.3, {0.4, -0.2}, 0.9};
  auto q = gf::to_conserved(w, gamma);
  const std::array<double, 2> u0{0.1, 0.05};
  gf::brinkman_relaxation<2>({&q[0], &q[1], &q[2], &q[3]}, chi, u0, tau, eta, false, 1.0, gamma);
  const auto after = gf::to_primitive<2>(q, gamma);
  const double decay = std::exp(-chi * tau / eta);
  EXPECT_NEAR(after.u[0], u0[0] + (w.u[0] - u0[0]) * decay, 1e-14);
  EXPECT_NEAR(after.u[1], u0[1] + (w.u[1] - u0[1]) * decay, 1e-14);
  EXPECT_EQ(after.rho, w.rho);
  EXPECT_NEAR(after.p, w.p, 1e-14);  // internal energy untouched on an adiabatic wall
  // Two half steps equal one full step (the exact solution of a linear relaxation).
  auto a = gf::to_conserved(w, gamma), b = a;
  gf::brinkman_relaxation<2>({&a[0], &a[1], &a[2], &a[3]}, chi, u0, tau, eta, true, 1.1, gamma);
  gf::brinkman_relaxation<2>({&b[0], &b[1], &b[2], &b[3]}, chi, u0, tau / 2, eta, true, 1.1, gamma);
  gf::brinkman_relaxation<2>({&b[0], &b[1], &b[2], &b[3]}, chi, u0, tau / 2, eta, true, 1.1, gamma);
  for (std::size_t f = 0; f < 4; ++f) EXPECT_NEAR(a[f], b[f], 1e-13);
  const auto iso = gf::to_primitive<2>(a, gamma);  // T relaxes to 1.1 at the same rate
  EXPECT_NEAR(gf::temperature(iso.rho, iso.p, gamma),
              1.1 + (gf::temperature(w.rho, w.p, gamma) - 1.1) * decay, 1e-13);
}

TEST(Penalization, ConservedRatesFollowTheChainRule) {
  // Compare with the time derivative of the conserved state along a primitive path.
  const double gamma = 1.4, cv = 1 / (gamma * (gamma - 1));
  const double rho = 1.2, T = 0.9, rate_rho = 0.3, rate_T = -0.2;
  const std::array<double, 2> u{0.3, -0.1}, rate_u{0.05, 0.4};
  const auto rates = gf::conserved_penalty<2>(rho, u, T, rate_rho, rate_u, rate_T, cv);
  auto state = [&](double dt) {
    gf::Primitive<2> w;
    w.rho = rho + rate_rho * dt;
    w.u = {u[0] + rate_u[0] * dt, u[1] + rate_u[1] * dt};
    w.p = w.rho * (T + rate_T * dt) / gamma;
    return gf::to_conserved(w, gamma);
  };
  const double dt = 1e-6;
  const auto plus = state(dt), minus = state(-dt);
  for (std::size_t f = 0; f < 4; ++f)
    EXPECT_NEAR(rates[f], (plus[f] - minus[f]) / (2 * dt), 1e-8) << "field " << f;
}

TEST(Penalization, UpwindDerivativesAreExactForLowOrderPolynomials) {
  std::array<double, 9> f{};
  const double h = 0.1;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const double x = static_cast<double>(i) * h;
    f[i] = 1 + 2 * x - 3 * x * x + 0.5 * x * x * x;
  }
  const double x4 = 0.4, exact = 2 - 6 * x4 + 1.5 * x4 * x4;
  for (bool positive : {true, false})
    EXPECT_NEAR(gf::upwind_derivative(f.data(), 4, 1, positive, 1 / h), exact, 1e-12);
  EXPECT_NEAR(gf::central_second_derivative(f.data(), 4, 1, 1 / (h * h)), -6 + 3 * x4, 1e-10);
}
