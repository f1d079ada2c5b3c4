// Golden tests (one TOML file per case in tests/golden/hardsphere/) and randomized invariant
// tests for the binary collision impulse of CollisionImpulse.hpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>
#include <toml.hpp>
#include <vector>

#include "core/Error.hpp"
#include "particles/hardsphere/CollisionImpulse.hpp"

namespace hs = grainwave::particles::hardsphere;
using hs::Vec3;

namespace {

std::filesystem::path golden_dir() {
  return std::filesystem::path(GRAINWAVE_TEST_DATA) / "golden" / "hardsphere";
}

std::vector<std::string> golden_cases() {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(golden_dir())) {
    if (entry.path().extension() == ".toml") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

Vec3 read_vec3(const toml::value& table, const std::string& key) {
  const auto a = toml::find<std::vector<double>>(table, key);
  if (a.size() != 3) throw std::runtime_error("key '" + key + "' needs three components");
  return Vec3(a[0], a[1], a[2]);
}

hs::Body read_body(const toml::value& table) {
  hs::Body body;
  if (table.contains("wall") && toml::find<bool>(table, "wall")) return body;  // w = k = r = 0
  body.velocity = read_vec3(table, "velocity");
  body.angular_velocity = read_vec3(table, "angular_velocity");
  body.inverse_mass = 1.0 / toml::find<double>(table, "mass");
  body.inverse_inertia = 1.0 / toml::find<double>(table, "inertia");
  body.radius = toml::find<double>(table, "radius");
  return body;
}

hs::CollisionLaw read_law(const toml::value& table) {
  hs::CollisionLaw law;
  law.friction = toml::find<double>(table, "friction");
  const std::string model = toml::find_or<std::string>(table, "model", "constant");
  if (model == "constant") {
    law.restitution = toml::find<double>(table, "restitution");
  } else if (model == "velocity_dependent") {
    law.model = hs::RestitutionModel::kVelocityDependent;
    law.plastic.yield_stress = toml::find<double>(table, "yield_stress");
    law.plastic.effective_modulus = toml::find<double>(table, "effective_modulus");
    law.plastic.pressure_factor = toml::find<double>(table, "pressure_factor");
  } else {
    throw std::runtime_error("unknown restitution model '" + model + "'");
  }
  hs::validate(law);
  return law;
}

Vec3 tangential(const Vec3& v, const Vec3& n) { return v - v.dot(n) * n; }

class GoldenCollision : public ::testing::TestWithParam<std::string> {};

TEST_P(GoldenCollision, MatchesHandDerivedVelocities) {
  const auto file = golden_dir() / (GetParam() + ".toml");
  const toml::value data = toml::parse(file.string());
  const double tol = toml::find<double>(data, "tolerance");
  const Vec3 n = read_vec3(data, "normal");
  const hs::CollisionLaw law = read_law(toml::find(data, "law"));
  hs::Body a = read_body(toml::find(data, "body1"));
  hs::Body b = read_body(toml::find(data, "body2"));
  const bool wall = b.inverse_mass == 0.0;
  const hs::Body a0 = a, b0 = b;

  const hs::CollisionImpulse result = hs::collide(a, b, n, law);
  const toml::value& expected = toml::find(data, "expected");
  SCOPED_TRACE(toml::find<std::string>(data, "description"));
  ASSERT_TRUE(result.approaching);
  EXPECT_EQ(result.sliding, toml::find<bool>(expected, "sliding"));
  if (expected.contains("restitution")) {
    EXPECT_NEAR(result.restitution, toml::find<double>(expected, "restitution"), tol);
  }
  const Vec3 v1 = read_vec3(expected, "velocity1"), w1 = read_vec3(expected, "angular_velocity1");
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.velocity[k], v1[k], tol) << "velocity1[" << k << "]";
    EXPECT_NEAR(a.angular_velocity[k], w1[k], tol) << "angular_velocity1[" << k << "]";
  }
  if (!wall) {
    const Vec3 v2 = read_vec3(expected, "velocity2"), w2 = read_vec3(expected, "angular_velocity2");
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(b.velocity[k], v2[k], tol) << "velocity2[" << k << "]";
      EXPECT_NEAR(b.angular_velocity[k], w2[k], tol) << "angular_velocity2[" << k << "]";
    }
  }
  // Whatever the case, the law's defining relations must hold.
  const double pn = -result.impulse.dot(n);
  const double pt = tangential(result.impulse, n).norm();
  const Vec3 slip_after = tangential(hs::contact_velocity(a, b, n), n);
  if (result.sliding) {
    EXPECT_NEAR(pt / pn, law.friction, 1e-14);
  } else {
    EXPECT_LE(pt, law.friction * pn * (1 + 1e-14));
    EXPECT_NEAR(slip_after.norm(), 0.0, 1e-14);
  }
  const double gn_before = n.dot(a0.velocity - b0.velocity);
  const double gn_after = n.dot(a.velocity - b.velocity);
  EXPECT_NEAR(gn_after, -result.restitution * gn_before, tol);
}

INSTANTIATE_TEST_SUITE_P(Files, GoldenCollision, ::testing::ValuesIn(golden_cases()),
                         [](const auto& test_info) { return test_info.param; });

TEST(GoldenCollision, DirectoryHoldsTheRequiredCases) {
  const auto names = golden_cases();
  for (const char* required : {"head_on_spheres", "oblique_sliding", "oblique_sticking",
                               "sphere_wall_rolling", "disk_wall_rolling"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), required), names.end()) << required;
  }
}

// ---- randomized invariants ------------------------------------------------------------------

struct Pair {
  hs::Body a, b;
  double m1 = 1, m2 = 1, i1 = 1, i2 = 1;
  Vec3 n = Vec3::UnitX();
};

Vec3 random_unit(std::mt19937_64& rng, int dimension) {
  std::normal_distribution<double> g(0.0, 1.0);
  Vec3 v(g(rng), g(rng), dimension == 3 ? g(rng) : 0.0);
  return v.normalized();
}

Pair random_pair(std::mt19937_64& rng, int dimension, bool wall) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Pair p;
  auto make = [&](hs::Body& body, double& m, double& inertia) {
    m = 0.1 + 10.0 * u(rng);
    body.radius = 0.1 + 2.0 * u(rng);
    inertia = (0.05 + 0.6 * u(rng)) * m * body.radius * body.radius;  // general, not just 2/5
    body.inverse_mass = 1.0 / m;
    body.inverse_inertia = 1.0 / inertia;
    body.velocity = Vec3(g(rng), g(rng), dimension == 3 ? g(rng) : 0.0);
    body.angular_velocity = dimension == 3 ? Vec3(g(rng), g(rng), g(rng)) : Vec3(0, 0, g(rng));
  };
  make(p.a, p.m1, p.i1);
  if (!wall) {
    make(p.b, p.m2, p.i2);
  } else {
    p.m2 = p.i2 = 0;  // wall: zero inverse mass and radius, at rest
  }
  p.n = random_unit(rng, dimension);
  if (p.n.dot(p.a.velocity - p.b.velocity) < 0) p.n = -p.n;  // make it a collision
  return p;
}

double kinetic_energy(const Pair& p) {
  double e = 0.5 * p.m1 * p.a.velocity.squaredNorm() + 0.5 * p.i1 * p.a.angular_velocity.squaredNorm();
  e += 0.5 * p.m2 * p.b.velocity.squaredNorm() + 0.5 * p.i2 * p.b.angular_velocity.squaredNorm();
  return e;
}

Vec3 linear_momentum(const Pair& p) { return p.m1 * p.a.velocity + p.m2 * p.b.velocity; }

/// Angular momentum of both bodies about the contact point (centre 1 at the origin).
Vec3 angular_momentum_about_contact(const Pair& p) {
  const Vec3 x1 = Vec3::Zero(), x2 = (p.a.radius + p.b.radius) * p.n, c = p.a.radius * p.n;
  return p.i1 * p.a.angular_velocity + (x1 - c).cross(p.m1 * p.a.velocity) +
         p.i2 * p.b.angular_velocity + (x2 - c).cross(p.m2 * p.b.velocity);
}

void check_invariants(int dimension, bool wall, bool elastic_frictionless) {
  std::mt19937_64 rng(1234u + static_cast<unsigned>(dimension) * 7u + (wall ? 1u : 0u));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int slides = 0, sticks = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Pair p = random_pair(rng, dimension, wall);
    hs::CollisionLaw law;
    law.restitution = elastic_frictionless ? 1.0 : u(rng);
    law.friction = elastic_frictionless ? 0.0 : 1.5 * u(rng);
    const Pair before = p;
    const hs::CollisionImpulse r = hs::collide(p.a, p.b, p.n, law);
    ASSERT_TRUE(r.approaching);
    (r.sliding ? slides : sticks) += 1;
    const double e0 = kinetic_energy(before), e1 = kinetic_energy(p);
    if (elastic_frictionless) {
      ASSERT_NEAR(e1, e0, 1e-14 * e0) << "trial " << trial;
    } else {
      ASSERT_LE(e1, e0 * (1 + 1e-14)) << "trial " << trial;
    }
    const double scale_p = before.m1 * before.a.velocity.norm() + before.m2 * before.b.velocity.norm();
    if (!wall) {
      ASSERT_LE((linear_momentum(p) - linear_momentum(before)).norm(), 1e-14 * scale_p);
    }
    const Vec3 l0 = angular_momentum_about_contact(before), l1 = angular_momentum_about_contact(p);
    const double scale_l = l0.norm() + 10.0 * scale_p;
    ASSERT_LE((l1 - l0).norm(), 2e-14 * scale_l) << "trial " << trial;
    if (dimension == 2) {  // disks stay in plane and spin only about z
      ASSERT_EQ(p.a.velocity.z(), 0.0);
      ASSERT_EQ(p.a.angular_velocity.x(), 0.0);
      ASSERT_EQ(p.a.angular_velocity.y(), 0.0);
    }
    // Coulomb: sliding keeps the slip direction (never reverses it), sticking stops it.
    const Vec3 slip0 = tangential(hs::contact_velocity(before.a, before.b, p.n), p.n);
    const Vec3 slip1 = tangential(hs::contact_velocity(p.a, p.b, p.n), p.n);
    if (r.sliding) {
      ASSERT_GE(slip1.dot(slip0), -1e-14 * slip0.squaredNorm());
    } else {
      ASSERT_LE(slip1.norm(), 1e-12 * (1.0 + slip0.norm()));
    }
  }
  if (!elastic_frictionless) {  // both branches were exercised
    EXPECT_GT(slides, 1000);
    EXPECT_GT(sticks, 1000);
  }
}

TEST(CollisionInvariants, SpheresRandom) { check_invariants(3, false, false); }
TEST(CollisionInvariants, SpheresOnWallRandom) { check_invariants(3, true, false); }
TEST(CollisionInvariants, DisksRandom) { check_invariants(2, false, false); }
TEST(CollisionInvariants, ElasticFrictionlessConservesEnergy3D) { check_invariants(3, false, true); }
TEST(CollisionInvariants, ElasticFrictionlessConservesEnergy2D) { check_invariants(2, false, true); }
TEST(CollisionInvariants, ElasticFrictionlessConservesEnergyWall) { check_invariants(3, true, true); }

// Crowe's sliding criterion for solid spheres: slide iff n.G / |Gc_t| < 2 / (7 mu (1 + e)).
TEST(SlidingCriterion, SolidSpheresSwitchAtCroweThreshold) {
  const double e = 0.6, mu = 0.2;
  const double threshold = 2.0 / (7.0 * mu * (1.0 + e));
  for (double factor : {0.999, 1.001}) {
    hs::Body a, b;
    for (hs::Body* body : {&a, &b}) {
      body->inverse_mass = 1.0 / 2.0;
      body->radius = 0.7;
      body->inverse_inertia = 1.0 / (0.4 * 2.0 * 0.49);
    }
    const double normal_speed = 1.3;
    a.velocity = Vec3(normal_speed, normal_speed / (threshold * factor), 0.0);  // |Gc_t| set by v_y
    const hs::CollisionImpulse r = hs::collision_impulse(a, b, Vec3::UnitX(), hs::CollisionLaw{e, mu});
    EXPECT_EQ(r.sliding, factor < 1.0) << "factor " << factor;
  }
}

// Disks (I = m r^2 / 2) have W_n / W_t = 1/3, so their threshold is 1 / (3 mu (1 + e)), not 2/7.
TEST(SlidingCriterion, DisksSwitchAtOneThird) {
  const double e = 1.0, mu = 0.1;
  const double threshold = 1.0 / (3.0 * mu * (1.0 + e));
  for (double factor : {0.999, 1.001}) {
    hs::Body a, b;
    for (hs::Body* body : {&a, &b}) {
      body->inverse_mass = 1.0;
      body->radius = 1.0;
      body->inverse_inertia = 2.0;
    }
    a.velocity = Vec3(1.0, 1.0 / (threshold * factor), 0.0);
    const auto r = hs::collision_impulse(a, b, Vec3::UnitX(), hs::CollisionLaw{e, mu});
    EXPECT_EQ(r.sliding, factor < 1.0) << "factor " << factor;
  }
}

TEST(CollisionImpulse, SeparatingBodiesGetNoImpulse) {
  hs::Body a, b;
  a.inverse_mass = b.inverse_mass = 1.0;
  a.velocity = Vec3(-1.0, 0.5, 0.0);
  const auto r = hs::collide(a, b, Vec3::UnitX(), hs::CollisionLaw{0.9, 0.3});
  EXPECT_FALSE(r.approaching);
  EXPECT_EQ(a.velocity, Vec3(-1.0, 0.5, 0.0));
}

TEST(CollisionImpulse, PlasticRestitutionFallsWithImpactSpeedAsPowerMinusQuarter) {
  hs::PlasticImpact p{1.0, 1000.0, 3.0};
  const double e1 = hs::plastic_restitution(p, 1.0, 1.0, 10.0);
  const double e2 = hs::plastic_restitution(p, 1.0, 1.0, 160.0);
  EXPECT_LT(e1, 1.0);
  EXPECT_NEAR(e2 / e1, std::pow(16.0, -0.25), 1e-14);  // e ~ (v^2)^(-1/8)
  EXPECT_EQ(hs::plastic_restitution(p, 1.0, 1.0, 1e-12), 1.0);  // clamped: slow impacts elastic
}

TEST(CollisionLaw, ValidationRejectsOutOfRange) {
  EXPECT_THROW(hs::validate(hs::CollisionLaw{1.2, 0.0}), grainwave::InputError);
  EXPECT_THROW(hs::validate(hs::CollisionLaw{0.5, -0.1}), grainwave::InputError);
  EXPECT_NO_THROW(hs::validate(hs::CollisionLaw{0.5, 0.1}));
}

}  // namespace
