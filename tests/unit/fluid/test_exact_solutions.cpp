// The reference solutions against published values (shared/reference/README.md).
#include <gtest/gtest.h>

#include <cmath>

#include "fluid/ExactSolutions.hpp"
#include "fluid/IdealGas.hpp"

namespace gf = grainwave::fluid;

TEST(ExactRiemann, SodStarStateMatchesToro) {
  gf::ExactRiemannSolver sod({1.0, 0.0, 1.0}, {0.125, 0.0, 0.1}, 1.4);
  const auto& s = sod.star();
  EXPECT_NEAR(s.p, 0.30313, 5e-6);
  EXPECT_NEAR(s.u, 0.92745, 5e-6);
  EXPECT_NEAR(s.rho_left, 0.42632, 5e-6);
  EXPECT_NEAR(s.rho_right, 0.26557, 5e-6);
  EXPECT_NEAR(s.right_speed, 1.75216, 5e-6);
  EXPECT_TRUE(s.right_is_shock);
  EXPECT_FALSE(s.left_is_shock);
}

TEST(ExactRiemann, SamplingIsConsistent) {
  gf::ExactRiemannSolver sod({1.0, 0.0, 1.0}, {0.125, 0.0, 0.1}, 1.4);
  EXPECT_DOUBLE_EQ(sod.sample(-2).rho, 1.0);
  EXPECT_DOUBLE_EQ(sod.sample(2).rho, 0.125);
  EXPECT_NEAR(sod.sample(0.5).rho, 0.42632, 5e-6);   // between fan tail and contact
  EXPECT_NEAR(sod.sample(1.2).rho, 0.26557, 5e-6);   // between contact and shock
  // The fan is continuous at its head and tail, and isentropic inside.
  const double c = std::sqrt(1.4);
  EXPECT_NEAR(sod.sample(-c + 1e-12).rho, 1.0, 1e-9);
  const auto mid = sod.sample(-0.5);
  EXPECT_NEAR(mid.p / std::pow(mid.rho, 1.4), 1.0, 1e-12);
}

TEST(ExactRiemann, SymmetricCollisionHasZeroStarVelocity) {
  gf::ExactRiemannSolver r({1.0, 1.0, 1.0}, {1.0, -1.0, 1.0}, 1.4);
  EXPECT_NEAR(r.star().u, 0.0, 1e-14);
  EXPECT_TRUE(r.star().left_is_shock && r.star().right_is_shock);
}

TEST(ShockRelations, MatchTheReferenceTable) {
  struct Row { double ms, p21, rho21, u2c1, p51; };
  // shared/reference/README.md (gamma = 1.4), values given to 3-4 digits.
  for (const Row& r : {Row{1.66, 3.048, 2.132, 0.881, 7.88}, Row{1.92, 4.134, 2.546, 1.166, 13.08},
                       Row{2.02, 4.594, 2.696, 1.271, 15.50}}) {
    const auto j = gf::normal_shock(r.ms, 1.4);
    EXPECT_NEAR(j.pressure_ratio, r.p21, 6e-4) << r.ms;
    EXPECT_NEAR(j.density_ratio, r.rho21, 6e-4) << r.ms;
    EXPECT_NEAR(j.velocity_over_c1, r.u2c1, 6e-4) << r.ms;
    EXPECT_NEAR(gf::reflected_pressure_ratio(r.ms, 1.4), r.p51, 6e-3) << r.ms;
  }
  const auto j = gf::normal_shock(2.81, 1.4);
  EXPECT_NEAR(j.pressure_ratio, 9.046, 6e-4);
  EXPECT_NEAR(j.density_ratio, 3.674, 6e-4);
  EXPECT_NEAR(j.velocity_over_c1, 2.045, 6e-4);
}

TEST(ShockRelations, ReflectedShockBringsGasToRest) {
  // Check the reflected Mach number independently: in the frame of the wall, the reflected
  // shock moving into state 2 (velocity u2 towards the wall) must leave gas at rest.
  const double g = 1.4, ms = 1.92;
  const auto j = gf::normal_shock(ms, g);
  const double c2 = std::sqrt(j.pressure_ratio / j.density_ratio);  // c2/c1 = sqrt(T2/T1)
  const double mr = gf::reflected_shock_mach(ms, g);
  const auto k = gf::normal_shock(mr, g);
  // Gas velocity jump across the reflected shock equals u2 (both over c1).
  EXPECT_NEAR(k.velocity_over_c1 * c2, j.velocity_over_c1, 1e-12);
}

TEST(IdealGas, ConversionsRoundTripAndEquationOfState) {
  gf::Primitive<3> w{1.3, {0.1, -0.2, 0.3}, 0.7};
  const auto q = gf::to_conserved(w, 1.4);
  const auto back = gf::to_primitive<3>(q, 1.4);
  EXPECT_NEAR(back.rho, w.rho, 1e-15);
  EXPECT_NEAR(back.p, w.p, 1e-15);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(back.u[k], w.u[k], 1e-15);
  // 002 Eq. 2.4: p = rho T / gamma, so c^2 = T.
  const double T = gf::temperature(w.rho, w.p, 1.4);
  EXPECT_NEAR(gf::sound_speed(w.rho, w.p, 1.4), std::sqrt(T), 1e-15);
  EXPECT_DOUBLE_EQ(gf::sutherland_viscosity(1.0, 0.368), 1.0);  // mu(T0) = mu0
  const auto f = gf::euler_flux(w, 1, 1.4);
  EXPECT_NEAR(f[0], w.rho * w.u[1], 1e-15);
  EXPECT_NEAR(f[2], w.rho * w.u[1] * w.u[1] + w.p, 1e-15);
}

TEST(IsentropicVortex, FarFieldIsTheUniformFlowAndEntropyIsConstant) {
  const auto far = gf::isentropic_vortex(30, 30, 5, 1, 1, 1.4);
  EXPECT_NEAR(far[0], 1.0, 1e-12);
  EXPECT_NEAR(far[3], 1 / 1.4, 1e-12);
  for (double r : {0.0, 0.5, 1.0, 2.0}) {
    const auto w = gf::isentropic_vortex(r, 0.3 * r, 5, 0, 0, 1.4);
    EXPECT_NEAR(w[3] / std::pow(w[0], 1.4), 1 / 1.4, 1e-13);
  }
}

TEST(IsentropicVortex, PressureGradientBalancesTheCentripetalAcceleration) {
  // A steady solution of the Euler equations: dp/dr = rho u_theta^2 / r along a ray.
  const double gamma = 1.4, beta = 5, dr = 1e-5;
  for (double r : {0.3, 0.8, 1.5, 2.5}) {
    const auto w = gf::isentropic_vortex(r, 0, beta, 0, 0, gamma);
    const double dpdr = (gf::isentropic_vortex(r + dr, 0, beta, 0, 0, gamma)[3] -
                         gf::isentropic_vortex(r - dr, 0, beta, 0, 0, gamma)[3]) / (2 * dr);
    const double u_theta = w[2];  // on the +x axis the swirl is the y velocity
    EXPECT_NEAR(dpdr, w[0] * u_theta * u_theta / r, 1e-8) << "r = " << r;
  }
}
