// Contact times from CollisionTime.hpp against closed-form roots, grazing and degenerate cases,
// and randomized trajectories built backwards from a chosen contact time.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "particles/hardsphere/CollisionTime.hpp"

namespace hs = grainwave::particles::hardsphere;
using Eigen::Vector3d;

namespace {

const Vector3d kZero = Vector3d::Zero();

TEST(CollisionTime, UniformApproachHeadOn) {
  // |5 - t| = 2 at t = 3.
  const auto t = hs::first_contact_time(Vector3d(5, 0, 0), Vector3d(-1, 0, 0), kZero, 2.0, 10.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 3.0, 1e-14);
  const auto exact = hs::ballistic_contact_time(Vector3d(5, 0, 0), Vector3d(-1, 0, 0), 2.0);
  ASSERT_TRUE(exact.has_value());
  EXPECT_DOUBLE_EQ(*exact, 3.0);
}

TEST(CollisionTime, ConstantAccelerationFromRest) {
  // 3 - t^2 = 1  =>  t = sqrt(2).
  const auto t = hs::first_contact_time(Vector3d(3, 0, 0), kZero, Vector3d(-2, 0, 0), 1.0, 5.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, std::sqrt(2.0), 1e-14);
}

TEST(CollisionTime, SeparatingThenPulledBack) {
  // 2 + t - t^2 = 1  =>  t = (1 + sqrt 5) / 2; f rises first, so the first monotone piece is skipped.
  const auto t = hs::first_contact_time(Vector3d(2, 0, 0), Vector3d(1, 0, 0), Vector3d(-2, 0, 0), 1.0, 2.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.5 * (1.0 + std::sqrt(5.0)), 1e-14);
  EXPECT_FALSE(hs::first_contact_time(Vector3d(2, 0, 0), Vector3d(1, 0, 0), Vector3d(-2, 0, 0), 1.0, 1.6));
}

TEST(CollisionTime, PassingThroughReturnsEntryNotExit) {
  // Offset 0.5, sigma 1: inside for |x| < sqrt(0.75); entry at t = 3 - sqrt(0.75).
  const auto t = hs::first_contact_time(Vector3d(-3, 0.5, 0), Vector3d(1, 0, 0), kZero, 1.0, 10.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 3.0 - std::sqrt(0.75), 1e-14);
}

TEST(CollisionTime, GrazingExactTouchHitMissAndNearMiss) {
  const double sigma = 1.0;
  // Tangent trajectory: f has a double root at t = 1.
  const auto touch = hs::first_contact_time(Vector3d(-1, sigma, 0), Vector3d(1, 0, 0), kZero, sigma, 2.0);
  ASSERT_TRUE(touch.has_value());
  // A double root is fixed only to ~sqrt(eps) in t (f ~ (t-1)^2 drowns in round-off), but the
  // distance there, which is what the collider uses, is sigma to round-off.
  EXPECT_NEAR(*touch, 1.0, 1e-7);
  EXPECT_NEAR(Vector3d(-1 + *touch, sigma, 0).norm(), sigma, 1e-15);
  // Barely missing by 1e-9 sigma: no contact.
  EXPECT_FALSE(hs::first_contact_time(Vector3d(-1, sigma * (1 + 1e-9), 0), Vector3d(1, 0, 0), kZero, sigma, 2.0));
  // Barely hitting: entry at 1 - sqrt(sigma^2 - y^2).
  const double y = sigma * (1 - 1e-6);
  const auto hit = hs::first_contact_time(Vector3d(-1, y, 0), Vector3d(1, 0, 0), kZero, sigma, 2.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(*hit, 1.0 - std::sqrt(sigma * sigma - y * y), 1e-12);
  // The same with a tiny transverse acceleration (a true quartic).
  const auto hit_a = hs::first_contact_time(Vector3d(-1, y, 0), Vector3d(1, 0, 0), Vector3d(0, 1e-12, 0), sigma, 2.0);
  ASSERT_TRUE(hit_a.has_value());
  EXPECT_NEAR(*hit_a, *hit, 1e-9);
}

TEST(CollisionTime, AlreadyOverlapping) {
  // Approaching while overlapped: contact "now".
  EXPECT_EQ(hs::first_contact_time(Vector3d(0.9, 0, 0), Vector3d(-1, 0, 0), kZero, 1.0, 1.0), 0.0);
  EXPECT_EQ(hs::ballistic_contact_time(Vector3d(0.9, 0, 0), Vector3d(-1, 0, 0), 1.0), 0.0);
  EXPECT_EQ(hs::ballistic_contact_time_or_never(Vector3d(0.9, 0, 0), Vector3d(-1, 0, 0), 1.0), 0.0);
  EXPECT_TRUE(std::isinf(hs::ballistic_contact_time_or_never(Vector3d(0.9, 0, 0), Vector3d(1, 0, 0), 1.0)));
  // Separating while overlapped (just after an impulse): no new contact.
  EXPECT_FALSE(hs::first_contact_time(Vector3d(0.9, 0, 0), Vector3d(1, 0, 0), kZero, 1.0, 1.0));
  EXPECT_FALSE(hs::ballistic_contact_time(Vector3d(0.9, 0, 0), Vector3d(1, 0, 0), 1.0));
  // Separating while overlapped but turned round inside the step: contact when the approach starts.
  const auto turn = hs::first_contact_time(Vector3d(0.9, 0, 0), Vector3d(0.1, 0, 0), Vector3d(-1, 0, 0), 1.0, 1.0);
  ASSERT_TRUE(turn.has_value());
  EXPECT_NEAR(*turn, 0.1, 1e-12);  // x' = 0.1 - t = 0
}

TEST(CollisionTime, NoContact) {
  EXPECT_FALSE(hs::first_contact_time(Vector3d(3, 0, 0), Vector3d(1, 0, 0), kZero, 1.0, 10.0));  // apart
  EXPECT_FALSE(hs::first_contact_time(Vector3d(5, 0, 0), Vector3d(-1, 0, 0), kZero, 2.0, 2.5));   // too late
  EXPECT_FALSE(hs::first_contact_time(Vector3d(5, 0, 0), kZero, kZero, 2.0, 1.0));               // at rest
  EXPECT_FALSE(hs::ballistic_contact_time(Vector3d(-3, 1.5, 0), Vector3d(1, 0, 0), 1.0));        // passes by
}

TEST(CollisionTime, WallContact) {
  // h = 2 - 3 t - 2 t^2/2 ... reach h = r = 0.5: t^2 + 3 t - 1.5 = 0.
  const auto t = hs::wall_contact_time(2.0, -3.0, -2.0, 0.5, 1.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.5 * (-3.0 + std::sqrt(9.0 + 6.0)), 1e-14);
  EXPECT_FALSE(hs::wall_contact_time(2.0, 1.0, 0.0, 0.5, 1.0));
}

// Build trajectories that touch at a chosen t*: d = sigma n - u t* - a t*^2/2, approaching at t*,
// keep those that are apart on [0, t*) (checked densely), and recover t*.
TEST(CollisionTime, RandomTrajectoriesRecoverConstructedRoot) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  int checked = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 20000 && checked < 5000; ++trial) {
    const double sigma = 0.2 + uni(rng);
    const double t_star = uni(rng);
    const Vector3d n = Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Vector3d u(g(rng), g(rng), g(rng));
    const Vector3d a = 3.0 * Vector3d(g(rng), g(rng), g(rng));
    if ((u + a * t_star).dot(n) >= -1e-3) continue;  // must approach at t*
    const Vector3d d = sigma * n - u * t_star - 0.5 * a * t_star * t_star;
    bool earlier = false;
    for (int k = 0; k < 400 && !earlier; ++k) {
      const double t = t_star * k / 400.0;
      earlier = (d + u * t + 0.5 * a * t * t).norm() <= sigma * (1 + 1e-9);
    }
    if (earlier) continue;
    const auto t = hs::first_contact_time(d, u, a, sigma, 1.0);
    ASSERT_TRUE(t.has_value()) << "trial " << trial;
    worst = std::max(worst, std::abs(*t - t_star));
    // Returned on the non-overlapping side, up to the round-off of the quartic's coefficients
    // (terms of size |d|^2 cancel down to sigma^2), hence a few 1e-15 of |d|^2 / sigma^2.
    const Vector3d r = d + u * *t + 0.5 * a * *t * *t;
    ASSERT_GE(r.norm(), sigma * (1 - 1e-14 * (1 + d.squaredNorm() / (sigma * sigma))));
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(worst, 1e-12);
  RecordProperty("worst_root_error", std::to_string(worst));
  std::printf("random quartic roots: %d checked, worst |t - t*| = %.3g\n", checked, worst);
}

TEST(CollisionTime, EqualAccelerationQuarticMatchesClosedForm) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  int hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vector3d d = 3.0 * Vector3d(g(rng), g(rng), g(rng));
    const Vector3d u = Vector3d(g(rng), g(rng), g(rng));
    const double sigma = 1.0;
    if (d.norm() <= sigma) continue;
    const auto exact = hs::ballistic_contact_time(d, u, sigma);
    const auto numeric = hs::first_contact_time(d, u, kZero, sigma, 100.0);
    const double branch_free = hs::ballistic_contact_time_or_never(d, u, sigma);
    ASSERT_EQ(exact.has_value(), std::isfinite(branch_free));
    if (exact) {
      ASSERT_EQ(*exact, branch_free);
    }
    ASSERT_EQ(exact.has_value(), numeric.has_value()) << "trial " << trial;
    if (exact) {
      EXPECT_NEAR(*numeric, *exact, 1e-12 * (1 + *exact));
      ++hits;
    }
  }
  EXPECT_GT(hits, 300);
}

}  // namespace
