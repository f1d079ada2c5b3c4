// Linked cells against an O(N²) search: every touching pair found exactly once, with the
// minimum-image separation, periodic or not.
#include "particles/dem/LinkedCells.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <utility>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {

std::set<std::pair<int, int>> brute_force(const gw::ParticleStore& s, const gw::Domain& d) {
  std::set<std::pair<int, int>> pairs;
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = i + 1; j < s.size(); ++j)
      if (d.separation(s.position[i], s.position[j]).norm() < s.radius[i] + s.radius[j])
        pairs.insert({static_cast<int>(i), static_cast<int>(j)});
  return pairs;
}

/// `outside` > 0 scatters centres up to that fraction of the box beyond its faces (as RK2's
/// unwrapped predicted positions are).
void check(const gw::Domain& domain, int n, double r_max, unsigned seed, double outside = 0.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-outside, 1.0 + outside);
  gw::ParticleStore s;
  double largest = 0.0;
  for (int k = 0; k < n; ++k) {
    Vec3 x = domain.lo + (domain.hi - domain.lo).cwiseProduct(Vec3(u(rng), u(rng), u(rng)));
    if (domain.dimension == 2) x.z() = 0.0;
    const double r = r_max * (0.5 + 0.5 * u(rng));
    largest = std::max(largest, r);
    s.add(k, x, Vec3::Zero(), Vec3::Zero(), r, 1.0, 1.0);
  }
  dem::LinkedCells cells;
  cells.build(s, domain, 2.0 * largest);
  std::multiset<std::pair<int, int>> found;
  double worst_separation_error = 0.0;
  cells.for_each_touching_pair([&](std::uint32_t i, std::uint32_t j, const Vec3& d, double d2) {
    const Vec3 expected_d = domain.separation(s.position[i], s.position[j]);
    worst_separation_error = std::max(
        {worst_separation_error, (d - expected_d).norm(), std::abs(d2 - expected_d.squaredNorm())});
    found.insert({static_cast<int>(std::min(i, j)), static_cast<int>(std::max(i, j))});
  });
  EXPECT_LT(worst_separation_error, 1e-12);
  const auto expected = brute_force(s, domain);
  EXPECT_GT(expected.size(), 0u);
  EXPECT_EQ(found.size(), expected.size()) << "a pair was reported twice or missed";
  const std::set<std::pair<int, int>> unique(found.begin(), found.end());
  EXPECT_EQ(unique, expected);
}

}  // namespace

TEST(LinkedCells, MatchesBruteForcePeriodic3D) {
  gw::Domain d;
  d.hi = Vec3(2.0, 1.5, 1.0);
  check(d, 600, 0.06, 1);
}

TEST(LinkedCells, MatchesBruteForcePeriodicWithCentresOutsideTheBox) {
  gw::Domain d;
  d.hi = Vec3(2.0, 1.5, 1.0);
  check(d, 600, 0.06, 5, 0.03);
}

TEST(LinkedCells, MatchesBruteForceWalls3D) {
  gw::Domain d;
  for (auto& axis : d.face) axis = {gw::FaceKind::kWall, gw::FaceKind::kWall};
  check(d, 500, 0.07, 2);
}

TEST(LinkedCells, MatchesBruteForceMixed2D) {
  gw::Domain d;
  d.dimension = 2;
  d.hi = Vec3(3.0, 1.0, 0.0);
  d.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kOpen};
  check(d, 700, 0.04, 3);
}

TEST(LinkedCells, ShortPeriodicAxesCountPairsOnce) {
  // Two cells along x and one along y: several stencil offsets wrap onto the same cell.
  gw::Domain d;
  d.dimension = 2;
  d.hi = Vec3(0.5, 0.3, 0.0);
  check(d, 40, 0.11, 4);
}

TEST(LinkedCells, ParticlesOutsideNonPeriodicBoxAreClamped) {
  gw::Domain d;
  for (auto& axis : d.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  gw::ParticleStore s;
  s.add(0, Vec3(1.30, 0.5, 0.5), Vec3::Zero(), Vec3::Zero(), 0.1, 1.0, 1.0);
  s.add(1, Vec3(1.45, 0.5, 0.5), Vec3::Zero(), Vec3::Zero(), 0.1, 1.0, 1.0);
  dem::LinkedCells cells;
  cells.build(s, d, 0.2);
  int pairs = 0;
  cells.for_each_touching_pair([&](std::uint32_t, std::uint32_t, const Vec3&, double) { ++pairs; });
  EXPECT_EQ(pairs, 1);
}
