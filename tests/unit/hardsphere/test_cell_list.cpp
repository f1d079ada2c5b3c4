// The cell list must find exactly the pairs an O(N^2) minimum-image search finds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <utility>
#include <vector>

#include "particles/hardsphere/CellList.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace gp = grainwave::particles;
namespace hs = grainwave::particles::hardsphere;
using gp::Vec3;

namespace {

using PairList = std::vector<std::pair<int, int>>;

PairList brute_force(const gp::Domain& domain, const std::vector<Vec3>& x, double cutoff) {
  PairList pairs;
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t j = i + 1; j < x.size(); ++j) {
      if (domain.separation(x[i], x[j]).norm() < cutoff) pairs.emplace_back(int(i), int(j));
    }
  }
  return pairs;
}

PairList from_cells(const gp::Domain& domain, const hs::CellList& cells, const std::vector<Vec3>& x,
                    double cutoff, long* visits) {
  PairList pairs;
  *visits = 0;
  cells.for_each_pair([&](int i, int j) {
    ++*visits;
    if (domain.separation(x[std::size_t(i)], x[std::size_t(j)]).norm() < cutoff)
      pairs.emplace_back(std::min(i, j), std::max(i, j));
  });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

struct BoxCase {
  int dimension;
  bool periodic;
  double length_x;  // box is [0, length_x] x [0, 3] x [0, 2.5]
  int n;
};

class CellListMatchesBruteForce : public ::testing::TestWithParam<BoxCase> {};

TEST_P(CellListMatchesBruteForce, SamePairs) {
  const BoxCase s = GetParam();
  gp::Domain domain;
  domain.dimension = s.dimension;
  domain.lo = Vec3(0, 0, 0);
  domain.hi = Vec3(s.length_x, 3.0, s.dimension == 3 ? 2.5 : 0.0);
  const gp::FaceKind kind = s.periodic ? gp::FaceKind::kPeriodic : gp::FaceKind::kWall;
  for (auto& face : domain.face) face = {kind, kind};
  const double cutoff = 0.6;
  std::mt19937_64 rng(11 + static_cast<unsigned>(s.n));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  hs::CellList cells;
  cells.configure(domain, cutoff);
  for (int repeat = 0; repeat < 3; ++repeat) {
    std::vector<Vec3> x(static_cast<std::size_t>(s.n));
    for (auto& p : x) {
      p = Vec3(s.length_x * u(rng), 3.0 * u(rng), s.dimension == 3 ? 2.5 * u(rng) : 0.0);
      // Non-periodic boxes: some particles slightly outside (clamped into edge cells).
      if (!s.periodic && u(rng) < 0.05) p.x() = -0.2 * u(rng);
    }
    cells.build(x);
    long visits = 0;
    const PairList found = from_cells(domain, cells, x, cutoff, &visits);
    const PairList expected = brute_force(domain, x, cutoff);
    EXPECT_EQ(found, expected) << "repeat " << repeat;
    EXPECT_GT(expected.size(), 10u);
    // No pair may be visited twice: the visits are at most all unordered pairs.
    EXPECT_LE(visits, long(s.n) * (s.n - 1) / 2);
    for (std::size_t k = 1; k < found.size(); ++k) ASSERT_NE(found[k], found[k - 1]);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Boxes, CellListMatchesBruteForce,
    ::testing::Values(BoxCase{3, true, 4.0, 400}, BoxCase{3, false, 4.0, 400},
                      BoxCase{3, true, 1.25, 150},   // two cells along x: wrapped offsets coincide
                      BoxCase{2, true, 5.0, 300}, BoxCase{2, false, 5.0, 300},
                      BoxCase{3, false, 0.5, 100}),  // one cell along x
    [](const auto& test_info) {
      const BoxCase& s = test_info.param;
      return std::to_string(s.dimension) + "D_" + (s.periodic ? "periodic" : "walls") + "_n" +
             std::to_string(s.n);
    });

// One list laid over box after box (configure() keeps the adjacency while the cell counts and
// periodic axes stay): walls, then the same box periodic (same counts, other adjacency), then a
// longer box, then back.
TEST(CellList, ReconfiguredForAnotherBoxFindsItsPairs) {
  const double cutoff = 0.6;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  hs::CellList cells;
  for (const auto& [length_x, periodic] : std::vector<std::pair<double, bool>>{
           {4.0, false}, {4.0, true}, {5.0, true}, {4.0, false}, {4.0, true}}) {
    gp::Domain domain;
    domain.hi = Vec3(length_x, 3.0, 2.5);
    const gp::FaceKind kind = periodic ? gp::FaceKind::kPeriodic : gp::FaceKind::kWall;
    for (auto& face : domain.face) face = {kind, kind};
    std::vector<Vec3> x(400);
    for (auto& p : x) p = Vec3(length_x * u(rng), 3.0 * u(rng), 2.5 * u(rng));
    cells.configure(domain, cutoff);
    cells.build(x);
    long visits = 0;
    EXPECT_EQ(from_cells(domain, cells, x, cutoff, &visits), brute_force(domain, x, cutoff))
        << "box " << length_x << (periodic ? " periodic" : " walls");
  }
}

TEST(CellList, CellsAreAtLeastTheCutoffWide) {
  gp::Domain domain;
  domain.hi = Vec3(10.0, 7.0, 3.4);
  hs::CellList cells;
  cells.configure(domain, 1.1);
  for (int k = 0; k < 3; ++k) {
    EXPECT_GE(cells.cell_size(k), 1.1);
    EXPECT_LT(cells.cell_size(k), 2.2);
  }
  EXPECT_EQ(cells.cells_along(0), 9);
  EXPECT_EQ(cells.cells_along(2), 3);
}

TEST(CellList, RejectsAmbiguousPeriodicImages) {
  gp::Domain domain;
  domain.hi = Vec3(1.0, 10.0, 10.0);
  hs::CellList cells;
  EXPECT_THROW(cells.configure(domain, 0.6), std::invalid_argument);
}

TEST(CellList, ForEachNearCoversEveryPartnerWithinCutoff) {
  gp::Domain domain;
  domain.hi = Vec3(4, 4, 4);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 4.0);
  std::vector<Vec3> x(300);
  for (auto& p : x) p = Vec3(u(rng), u(rng), u(rng));
  hs::CellList cells;
  cells.configure(domain, 0.7);
  cells.build(x);
  for (std::size_t i = 0; i < x.size(); ++i) {
    std::vector<int> near;
    cells.for_each_near(x[i], [&](int j) { near.push_back(j); });
    for (std::size_t j = 0; j < x.size(); ++j) {
      if (domain.separation(x[i], x[j]).norm() < 0.7) {
        ASSERT_NE(std::find(near.begin(), near.end(), int(j)), near.end()) << i << " " << j;
      }
    }
  }
}

}  // namespace

namespace {

// The deepest overlap by the formula over every pair (minimum image, then the distance) and,
// on wall axes, every particle's gap to both walls.
double brute_force_overlap(const gp::ParticleStore& s, const gp::Domain& d) {
  double worst = 0.0;
  for (std::size_t a = 0; a < s.size(); ++a)
    for (std::size_t b = a + 1; b < s.size(); ++b) {
      const double overlap = s.radius[a] + s.radius[b] - d.separation(s.position[a], s.position[b]).norm();
      worst = std::max(worst, overlap / std::min(s.radius[a], s.radius[b]));
    }
  for (int k = 0; k < 3; ++k)
    if (!d.periodic(k))
      for (std::size_t a = 0; a < s.size(); ++a) {
        worst = std::max(worst, (s.radius[a] - (s.position[a][k] - d.lo[k])) / s.radius[a]);
        worst = std::max(worst, (s.radius[a] - (d.hi[k] - s.position[a][k])) / s.radius[a]);
      }
  return worst;
}

}  // namespace

// max_relative_overlap (the check after every hard-sphere step) skips the square root for pairs
// clearly apart and reads the box once: it must still give, bitwise, what the formula gives over
// all pairs, for pairs just touching (where rounding decides the sign), overlapping ones and
// ones across periodic faces.
TEST(CellList, OverlapCheckEqualsTheFormulaOverAllPairs) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int touching_positive = 0;
  for (const bool periodic : {true, false})
    for (int repeat = 0; repeat < 20; ++repeat) {
      gp::Domain d;
      d.hi = Vec3(6.0, 5.0, 4.0);
      const gp::FaceKind kind = periodic ? gp::FaceKind::kPeriodic : gp::FaceKind::kWall;
      for (auto& face : d.face) face = {kind, kind};
      gp::ParticleStore s;
      for (int i = 0; i < 40; ++i) {
        const double r = 0.2 + 0.1 * u(rng);
        Vec3 x(0.5 + 5.0 * u(rng), 0.5 + 4.0 * u(rng), 0.5 + 3.0 * u(rng));
        if (i % 2 == 1) {  // touching the previous one, or a hair inside it, sometimes across a face
          const Vec3 n = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
          const bool deep = i % 8 == 7 && repeat % 2 == 0;  // the odd repeats only touch
          x = s.position.back() + (s.radius.back() + r) * (deep ? 0.999 : 1.0) * n;
          if (periodic) d.wrap(x);
        }
        s.add(i, x, Vec3::Zero(), Vec3::Zero(), r, 1.0, 1.0);
      }
      hs::CellList cells;
      const double expected = brute_force_overlap(s, d);
      EXPECT_EQ(hs::max_relative_overlap(s, d, cells), expected) << (periodic ? "periodic" : "walls") << " " << repeat;
      touching_positive += expected > 0.0 && expected < 1e-12 ? 1 : 0;
    }
  std::printf("boxes whose deepest overlap was a touching pair's rounding: %d\n", touching_positive);
}
