// Pointwise checks of the contact laws and their registry against hand-derived values.
#include "particles/dem/CoulombSpring.hpp"
#include "particles/dem/HertzNormal.hpp"
#include "particles/dem/LinearSpringDashpot.hpp"
#include "particles/dem/Mindlin.hpp"
#include "particles/dem/StaticFriction.hpp"

#include "core/Error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace dem = grainwave::particles::dem;
using grainwave::particles::Vec3;

TEST(ContactLawRegistry, BuildsEveryBuiltinLawByName) {
  for (const char* name : {"linear_spring_dashpot", "hertz"})
    EXPECT_TRUE(dem::normal_law_registry().contains(name)) << name;
  for (const char* name : {"static_friction", "coulomb_spring", "mindlin"})
    EXPECT_TRUE(dem::tangential_law_registry().contains(name)) << name;
  const auto model = dem::make_contact_model("linear_spring_dashpot",
                                             {{"stiffness", 10.0}, {"restitution", 0.5}},
                                             "coulomb_spring", {{"stiffness", 3.0}, {"friction", 0.4}});
  EXPECT_NE(dynamic_cast<const dem::LinearSpringDashpot*>(model.normal.get()), nullptr);
  EXPECT_NE(dynamic_cast<const dem::CoulombSpring*>(model.tangential.get()), nullptr);
  EXPECT_TRUE(model.tangential->needs_history());
}

TEST(ContactLawRegistry, RejectsUnknownLawsAndKeys) {
  EXPECT_THROW(dem::normal_law_registry().create("hooke", {{"stiffness", 1.0}}),
               grainwave::InputError);
  EXPECT_THROW(dem::normal_law_registry().create("linear_spring_dashpot",
                                                 {{"stiffness", 1.0}, {"stifness", 2.0}}),
               grainwave::InputError);
  EXPECT_THROW(dem::normal_law_registry().create("linear_spring_dashpot", {{"restitution", 0.5}}),
               grainwave::InputError);
  EXPECT_THROW(dem::LinearSpringDashpot({1.0, 1.5}), grainwave::InputError);
}

TEST(LinearSpringDashpot, DampingMatchesEq310) {
  const double k = 2.0e4, e = 0.6, m = 3.0e-3;
  const dem::LinearSpringDashpot law({k, e});
  const double eta = -2.0 * std::log(e) * std::sqrt(m * k) /
                     std::sqrt(std::numbers::pi * std::numbers::pi + std::log(e) * std::log(e));
  // Approaching at 0.3 m/s with 1 µm overlap: spring plus dashpot both repel.
  EXPECT_NEAR(law.force(1e-6, -0.3, m), k * 1e-6 + eta * 0.3, 1e-12);
  EXPECT_DOUBLE_EQ(law.force(1e-6, 0.0, m), k * 1e-6);
  // e = 1 gives no damping and the undamped half period π sqrt(m/k).
  const dem::LinearSpringDashpot elastic({k, 1.0});
  EXPECT_DOUBLE_EQ(elastic.damping_factor(), 0.0);
  EXPECT_NEAR(elastic.contact_duration(m, 0.0), std::numbers::pi * std::sqrt(m / k), 1e-15);
}

TEST(HertzNormal, ElasticScaledDurationMatchesClosedForm) {
  // s_c = 2 ∫₀¹ dx/sqrt(1 − x^{5/2}) · (5/4)^{2/5} = 2.9432·1.0934 for the elastic collision.
  const auto elastic = dem::HertzNormal::integrate_scaled_collision(0.0);
  EXPECT_NEAR(elastic.restitution, 1.0, 1e-6);
  EXPECT_NEAR(elastic.duration, 2.94320 * std::pow(1.25, 0.4), 2e-4);
  // Damping is bisected to reproduce the requested restitution.
  const dem::HertzNormal law({1e9, 0.25, 0.7, 1.0});
  EXPECT_NEAR(dem::HertzNormal::integrate_scaled_collision(law.damping_factor()).restitution, 0.7,
              1e-6);
  // K = 4/3 E* sqrt(R*), E* = E / (2 (1 − ν²)).
  EXPECT_NEAR(law.stiffness(4e-6), 4.0 / 3.0 * 1e9 / (2.0 * (1.0 - 0.0625)) * 2e-3, 1e-3);
  EXPECT_NEAR(law.force(1e-8, 0.0, 1.0, 4e-6), law.stiffness(4e-6) * 1e-12, 1e-18);
}

TEST(StaticFriction, OpposesSlipWithCoulombMagnitude) {
  const dem::StaticFriction law({0.4, 0.0});
  const Vec3 slip(0.0, 2.0, 0.0);  // j's surface moves +y relative to i: i is dragged along +y
  const Vec3 f = law.force(5.0, slip);
  EXPECT_NEAR(f.y(), 0.4 * 5.0, 1e-14);
  EXPECT_NEAR(f.x(), 0.0, 1e-14);
  EXPECT_EQ(law.force(-1.0, slip), Vec3::Zero());   // no friction without compression
  EXPECT_EQ(law.force(5.0, Vec3::Zero()), Vec3::Zero());
  const dem::StaticFriction regularised({0.4, 4.0});  // below ε: μ f_n v/ε
  EXPECT_NEAR(regularised.force(5.0, slip).y(), 0.4 * 5.0 * 2.0 / 4.0, 1e-14);
}

TEST(CoulombSpring, StickThenSlipShortensDisplacement) {
  Vec3 xi(1e-3, 0.0, 0.0);
  // Stick: |k ξ| = 0.1 < μ f_n = 0.5.
  Vec3 f = dem::coulomb_limited_spring(100.0, 0.0, 0.5, 1.0, Vec3::Zero(), xi);
  EXPECT_NEAR(f.x(), 0.1, 1e-14);
  EXPECT_NEAR(xi.x(), 1e-3, 1e-18);
  // Slip: k ξ = 1.0 > 0.5, force capped and ξ cut to μ f_n / k.
  xi = Vec3(0.0, -1e-2, 0.0);
  f = dem::coulomb_limited_spring(100.0, 0.0, 0.5, 1.0, Vec3::Zero(), xi);
  EXPECT_NEAR(f.y(), -0.5, 1e-14);
  EXPECT_NEAR(xi.y(), -5e-3, 1e-16);
}

TEST(CoulombSpring, RotatesStoredDisplacementIntoNewPlane) {
  const Vec3 xi(1.0, 0.0, 0.0);
  const Vec3 n = Vec3(0.6, 0.8, 0.0);  // tilted contact normal
  const Vec3 rotated = dem::rotate_into_plane(xi, n);
  EXPECT_NEAR(rotated.dot(n), 0.0, 1e-15);
  EXPECT_NEAR(rotated.norm(), 1.0, 1e-15);
  EXPECT_GT(rotated.x(), 0.0);
}

TEST(Mindlin, StiffnessFromShearModulusAndContactRadius) {
  const double e_mod = 7e10, nu = 0.25;
  const dem::Mindlin law({e_mod, nu, 0.5, 0.0});
  const double g = e_mod / (2.0 * (1.0 + nu));
  const double g_star = 1.0 / (2.0 * (2.0 - nu) / g);
  const double r = 1e-3, delta = 1e-6;
  EXPECT_NEAR(law.stiffness(delta, r), 8.0 * g_star * std::sqrt(r * delta), 1e-6);
  EXPECT_DOUBLE_EQ(law.stiffness(0.0, r), 0.0);
}
