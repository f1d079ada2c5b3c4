// Block-forest topology: keys, neighbours (same/coarser/finer, periodic wrap), refinement and
// coarsening under 2:1 balance, space-filling-curve order and partition.
#include "wavelet/BlockForest.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>
#include <set>

namespace gw = grainwave::wavelet;

namespace {

TEST(BlockKey, MortonRoundTripParentAndChildren) {
  using Key = gw::BlockKey<3>;
  const Key k = Key::from_coords(4, {5, 11, 2});
  EXPECT_EQ(k.coords(), (std::array<std::uint32_t, 3>{5, 11, 2}));
  EXPECT_EQ(k.parent().coords(), (std::array<std::uint32_t, 3>{2, 5, 1}));
  EXPECT_EQ(k.parent().level, 3);
  EXPECT_EQ(k.child_index(), 1 | 2);  // x odd, y odd, z even
  for (int c = 0; c < Key::kChildren; ++c) {
    EXPECT_EQ(k.child(c).parent(), k);
    EXPECT_EQ(k.child(c).child_index(), c);
    const auto cc = k.child(c).coords();
    EXPECT_EQ(cc[0], 10u + (c & 1));
    EXPECT_EQ(cc[2], 4u + ((c >> 2) & 1));
  }
}

// The interleave by masks against the definition, bit b of axis a at bit b * Dim + a.
template <int Dim>
void expect_interleave_matches_bit_by_bit() {
  using Key = gw::BlockKey<Dim>;
  std::mt19937_64 random(7);
  for (int trial = 0; trial < 2000; ++trial) {
    std::array<std::uint32_t, Dim> c{};
    for (auto& v : c) v = static_cast<std::uint32_t>(random()) >> (32 - Key::kBitsPerAxis);
    std::uint64_t morton = 0;
    for (int b = 0; b < Key::kBitsPerAxis; ++b)
      for (int a = 0; a < Dim; ++a)
        morton |= static_cast<std::uint64_t>((c[static_cast<std::size_t>(a)] >> b) & 1u) << (b * Dim + a);
    const Key key = Key::from_coords(3, c);
    ASSERT_EQ(key.morton, morton) << "trial " << trial;
    ASSERT_EQ(key.coords(), c) << "trial " << trial;
  }
}

TEST(BlockKey, InterleaveMatchesBitByBit) {
  expect_interleave_matches_bit_by_bit<1>();
  expect_interleave_matches_bit_by_bit<2>();
  expect_interleave_matches_bit_by_bit<3>();
}

template <int Dim>
void expect_hilbert_walks_face_neighbours(int bits) {
  const std::uint32_t n = 1u << bits;
  std::uint32_t total = 1;
  for (int a = 0; a < Dim; ++a) total *= n;
  std::vector<std::pair<std::uint64_t, std::array<std::uint32_t, Dim>>> cells;
  for (std::uint32_t idx = 0; idx < total; ++idx) {
    std::array<std::uint32_t, Dim> c{};
    std::uint32_t rest = idx;
    for (int a = 0; a < Dim; ++a) {
      c[a] = rest % n;
      rest /= n;
    }
    cells.emplace_back(gw::hilbert_index<Dim>(c, bits), c);
  }
  std::sort(cells.begin(), cells.end());
  for (std::uint32_t i = 0; i < total; ++i) {
    EXPECT_EQ(cells[i].first, i) << "Hilbert index is not a bijection onto 0.." << total - 1;
    if (i == 0) continue;
    int distance = 0;
    for (int a = 0; a < Dim; ++a)
      distance += std::abs(static_cast<int>(cells[i].second[a]) - static_cast<int>(cells[i - 1].second[a]));
    EXPECT_EQ(distance, 1) << "cells " << i - 1 << " and " << i << " are not face neighbours";
  }
}

TEST(HilbertIndex, ConsecutiveCellsAreFaceNeighbours2D) { expect_hilbert_walks_face_neighbours<2>(4); }
TEST(HilbertIndex, ConsecutiveCellsAreFaceNeighbours3D) { expect_hilbert_walks_face_neighbours<3>(3); }

TEST(BlockForest, RootForestOfARectangularDomain) {
  gw::BlockForest<2> forest({{3, 2}, {false, false}, 3, gw::CurveOrder::kMorton});
  EXPECT_EQ(forest.size(), 6u);
  EXPECT_TRUE(forest.tiles_domain());
  EXPECT_TRUE(forest.is_balanced());
  const auto corner = gw::BlockKey<2>::from_coords(0, {0, 0});
  EXPECT_EQ(forest.neighbours(corner).size(), 3u);  // +x face, +y face, +x+y corner
  const auto middle = gw::BlockKey<2>::from_coords(0, {1, 0});
  EXPECT_EQ(forest.neighbours(middle).size(), 5u);
}

TEST(BlockForest, PeriodicNeighboursWrap) {
  gw::BlockForest<2> forest({{4, 3}, {true, false}, 2, gw::CurveOrder::kHilbert});
  const auto left = gw::BlockKey<2>::from_coords(0, {0, 1});
  const auto n = forest.neighbours(left);
  EXPECT_EQ(n.size(), 8u);  // periodic in x, interior row in y
  bool found_wrapped_face = false;
  for (const auto& nb : n)
    if (nb.direction == std::array<int, 2>{-1, 0}) {
      EXPECT_EQ(nb.key.coords(), (std::array<std::uint32_t, 2>{3, 1}));
      EXPECT_EQ(nb.level_difference, 0);
      found_wrapped_face = true;
    }
  EXPECT_TRUE(found_wrapped_face);
  EXPECT_FALSE(forest.shifted(left, {0, 2}).has_value());
  const auto bottom = gw::BlockKey<2>::from_coords(0, {3, 0});
  EXPECT_EQ(forest.neighbours(bottom).size(), 5u);  // no neighbours below the non-periodic y edge

  // Refine the right column: the left column now sees two finer blocks across the wrapped face.
  std::vector<gw::AdaptTag> tags(forest.size(), gw::AdaptTag::kKeep);
  for (std::size_t i = 0; i < forest.size(); ++i)
    if (forest.leaves()[i].coords()[0] == 3) tags[i] = gw::AdaptTag::kRefine;
  forest.adapt(tags);
  int finer_across_wrap = 0;
  for (const auto& nb : forest.neighbours(left))
    if (nb.direction == std::array<int, 2>{-1, 0}) {
      EXPECT_EQ(nb.level_difference, 1);
      EXPECT_EQ(nb.key.coords()[0], 7u);
      ++finer_across_wrap;
    }
  EXPECT_EQ(finer_across_wrap, 2);
}

TEST(BlockForest, RefinementSpreadsToKeepTwoToOneAcrossCorners) {
  gw::BlockForest<2> forest({{2, 2}, {false, false}, 3, gw::CurveOrder::kMorton});
  std::vector<gw::AdaptTag> tags(forest.size(), gw::AdaptTag::kKeep);
  tags[*forest.find(gw::BlockKey<2>::from_coords(0, {0, 0}))] = gw::AdaptTag::kRefine;
  EXPECT_EQ(forest.adapt(tags).refined, 1);
  // The level-1 child at (1,1) touches all three other roots (two faces and one corner).
  tags.assign(forest.size(), gw::AdaptTag::kKeep);
  tags[*forest.find(gw::BlockKey<2>::from_coords(1, {1, 1}))] = gw::AdaptTag::kRefine;
  const auto counts = forest.adapt(tags);
  EXPECT_EQ(counts.refined, 4);
  EXPECT_FALSE(forest.is_leaf(gw::BlockKey<2>::from_coords(0, {1, 1})));  // corner neighbour
  EXPECT_EQ(forest.size(), 3u + 4u + 3u * 4u);
  EXPECT_TRUE(forest.is_balanced());
  EXPECT_TRUE(forest.tiles_domain());
}

TEST(BlockForest, CoarseningIsRefusedWhenItWouldBreakBalance) {
  using Key = gw::BlockKey<1>;
  gw::BlockForest<1> forest({{2}, {false}, 4, gw::CurveOrder::kMorton});
  forest.adapt(std::vector<gw::AdaptTag>(2, gw::AdaptTag::kRefine));  // four level-1 blocks
  std::vector<gw::AdaptTag> tags(forest.size(), gw::AdaptTag::kKeep);
  tags[*forest.find(Key::from_coords(1, {1}))] = gw::AdaptTag::kRefine;
  forest.adapt(tags);  // levels from the left: 1, 2, 2, 1, 1
  ASSERT_EQ(forest.size(), 5u);
  // All ask to coarsen. The level-2 pair may; root 1's family {2, 3} touches the level-2 block
  // at coords 3, so its parent (level 0) would sit two levels below it: refused this pass.
  const auto counts = forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kCoarsen));
  EXPECT_EQ(counts.coarsened, 1);
  EXPECT_TRUE(forest.is_leaf(Key::from_coords(1, {1})));
  EXPECT_TRUE(forest.is_leaf(Key::from_coords(1, {2})));
  EXPECT_FALSE(forest.is_leaf(Key::from_coords(0, {1})));
  EXPECT_TRUE(forest.is_balanced());
  // Next pass nothing stands in the way.
  EXPECT_EQ(forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kCoarsen)).coarsened, 2);
  EXPECT_EQ(forest.size(), 2u);
}

template <int Dim>
void expect_symmetric_neighbours(const gw::BlockForest<Dim>& forest) {
  std::set<std::pair<std::size_t, std::size_t>> pairs;
  std::vector<gw::Neighbour<Dim>> around;
  for (std::size_t i = 0; i < forest.size(); ++i) {
    forest.neighbours(forest.leaves()[i], around);
    for (const auto& nb : around) {
      const auto j = forest.find(nb.key);
      ASSERT_TRUE(j.has_value()) << "neighbour is not a leaf";
      EXPECT_EQ(nb.leaf, *j) << "neighbour's leaf index";
      EXPECT_EQ(nb.key.level - forest.leaves()[i].level, nb.level_difference);
      EXPECT_LE(std::abs(nb.level_difference), 1);
      pairs.emplace(i, *j);
    }
  }
  for (const auto& [i, j] : pairs) EXPECT_TRUE(pairs.contains({j, i})) << "leaf " << i << " sees " << j << " but not back";
  // The cached lists are the same as the computed ones.
  for (std::size_t i = 0; i < forest.size(); ++i) {
    forest.neighbours(forest.leaves()[i], around);
    const auto& cached = forest.leaf_neighbours(i);
    ASSERT_EQ(cached.size(), around.size());
    for (std::size_t k = 0; k < around.size(); ++k) {
      EXPECT_EQ(cached[k].key, around[k].key);
      EXPECT_EQ(cached[k].leaf, around[k].leaf);
    }
  }
}

// The family tables (found once per leaf set, kept until the leaves change) against the leaf
// index and the neighbour lists, asked after every adaptation.
template <int Dim>
void expect_families_as_found(const gw::BlockForest<Dim>& forest) {
  using Key = gw::BlockKey<Dim>;
  std::vector<gw::Neighbour<Dim>> around;
  for (std::size_t i = 0; i < forest.size(); ++i) {
    const Key& leaf = forest.leaves()[i];
    std::array<std::size_t, Key::kChildren> members{};
    bool complete = leaf.level > 0;
    for (int k = 0; k < Key::kChildren && complete; ++k) {
      const auto j = forest.find(leaf.parent().child(k));
      complete = j.has_value();
      if (complete) members[static_cast<std::size_t>(k)] = *j;
    }
    if (!complete) {
      EXPECT_EQ(forest.family_first(i), gw::BlockForest<Dim>::kNoFamily) << "leaf " << i;
      continue;
    }
    ASSERT_EQ(forest.family_first(i), members[0]) << "leaf " << i;
    EXPECT_EQ(forest.family_members(members[0]), members) << "leaf " << i;
    bool finer = false;
    for (const std::size_t m : members) {
      forest.neighbours(forest.leaves()[m], around);
      for (const auto& nb : around) finer = finer || nb.level_difference == +1;
    }
    EXPECT_EQ(forest.family_touches_finer(members[0]), finer) << "leaf " << i;
  }
  // families_beside, found from the flagged side, against its definition from the other: every
  // third complete family flagged.
  std::vector<char> flagged(forest.size(), 0), expected(forest.size(), 0);
  int complete = 0;
  for (std::size_t i = 0; i < forest.size(); ++i)
    if (forest.family_first(i) == i) flagged[i] = complete++ % 3 == 0;
  for (std::size_t i = 0; i < forest.size(); ++i) {
    if (forest.family_first(i) != i) continue;
    for (const std::size_t m : forest.family_members(i)) {
      forest.neighbours(forest.leaves()[m], around);
      for (const auto& nb : around) {
        const std::size_t first = forest.family_first(nb.leaf);
        if (nb.level_difference <= 0 && first != gw::BlockForest<Dim>::kNoFamily && flagged[first]) expected[i] = 1;
      }
    }
  }
  EXPECT_EQ(forest.families_beside(flagged), expected);
}

template <int Dim>
void random_adaptation(std::array<int, Dim> roots, std::array<bool, Dim> periodic, gw::CurveOrder curve,
                       int steps, unsigned seed, double p_refine) {
  gw::BlockForest<Dim> forest({roots, periodic, 4, curve});
  const auto root_leaves = std::vector<gw::BlockKey<Dim>>(forest.leaves().begin(), forest.leaves().end());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t largest = 0;
  for (int step = 0; step < steps; ++step) {
    std::vector<gw::AdaptTag> tags(forest.size());
    const auto old = std::vector<gw::BlockKey<Dim>>(forest.leaves().begin(), forest.leaves().end());
    for (auto& t : tags) {
      const double r = u(rng);
      t = r < p_refine ? gw::AdaptTag::kRefine : (r < p_refine + 0.55 ? gw::AdaptTag::kCoarsen : gw::AdaptTag::kKeep);
    }
    forest.adapt(tags);
    largest = std::max(largest, forest.size());
    ASSERT_TRUE(forest.is_balanced()) << "step " << step;
    ASSERT_TRUE(forest.tiles_domain()) << "step " << step;
    for (std::size_t i = 0; i < old.size(); ++i)  // every requested refinement happened
      if (tags[i] == gw::AdaptTag::kRefine && old[i].level < 4) {
        EXPECT_FALSE(forest.is_leaf(old[i]));
        EXPECT_TRUE(forest.is_leaf(old[i].child(0)));
      }
    for (std::size_t i = 1; i < forest.size(); ++i)
      ASSERT_LT(forest.curve_index(forest.leaves()[i - 1]), forest.curve_index(forest.leaves()[i]));
    expect_symmetric_neighbours(forest);
    expect_families_as_found(forest);
  }
  EXPECT_GT(largest, 4 * root_leaves.size()) << "the random sequence never refined much";
  // Coarsening everything, one level per pass, must give back the root forest.
  for (int pass = 0; pass < 4; ++pass)
    forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kCoarsen));
  EXPECT_EQ(std::vector<gw::BlockKey<Dim>>(forest.leaves().begin(), forest.leaves().end()), root_leaves);
}

TEST(BlockForest, RandomAdaptationKeepsBalance1D) {
  random_adaptation<1>({3}, {true}, gw::CurveOrder::kMorton, 30, 1, 0.35);
  random_adaptation<1>({2}, {false}, gw::CurveOrder::kHilbert, 30, 2, 0.35);
}
TEST(BlockForest, RandomAdaptationKeepsBalance2D) {
  random_adaptation<2>({3, 2}, {true, false}, gw::CurveOrder::kHilbert, 25, 3, 0.2);
  random_adaptation<2>({1, 1}, {true, true}, gw::CurveOrder::kMorton, 25, 4, 0.2);
}
TEST(BlockForest, RandomAdaptationKeepsBalance3D) {
  random_adaptation<3>({2, 1, 1}, {false, true, false}, gw::CurveOrder::kHilbert, 12, 5, 0.15);
  random_adaptation<3>({1, 1, 1}, {true, true, true}, gw::CurveOrder::kMorton, 12, 6, 0.15);
}

TEST(BlockForest, RefineAllThenCoarsenAllReturnsTheRoots) {
  gw::BlockForest<3> forest({{2, 1, 3}, {false, true, false}, 3, gw::CurveOrder::kHilbert});
  const auto roots = std::vector<gw::BlockKey<3>>(forest.leaves().begin(), forest.leaves().end());
  for (int pass = 0; pass < 2; ++pass) forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kRefine));
  EXPECT_EQ(forest.size(), roots.size() * 64);
  for (const auto& nb : forest.neighbours(forest.leaves()[5])) EXPECT_EQ(nb.level_difference, 0);
  for (int pass = 0; pass < 2; ++pass) {
    const auto counts = forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kCoarsen));
    EXPECT_EQ(counts.coarsened, static_cast<int>(forest.size()));
  }
  EXPECT_EQ(std::vector<gw::BlockKey<3>>(forest.leaves().begin(), forest.leaves().end()), roots);
}

TEST(BlockForest, UniformHilbertForestIsAFaceConnectedWalk) {
  gw::BlockForest<2> forest({{1, 1}, {false, false}, 3, gw::CurveOrder::kHilbert});
  for (int pass = 0; pass < 3; ++pass) forest.adapt(std::vector<gw::AdaptTag>(forest.size(), gw::AdaptTag::kRefine));
  ASSERT_EQ(forest.size(), 64u);
  for (std::size_t i = 1; i < forest.size(); ++i) {
    const auto a = forest.leaves()[i - 1].coords(), b = forest.leaves()[i].coords();
    EXPECT_EQ(std::abs(static_cast<int>(a[0]) - static_cast<int>(b[0])) +
                  std::abs(static_cast<int>(a[1]) - static_cast<int>(b[1])),
              1);
  }
}

TEST(BlockForest, PartitionIsContiguousBalancedAndKeepsFamilies) {
  gw::BlockForest<2> forest({{2, 2}, {true, true}, 3, gw::CurveOrder::kHilbert});
  std::vector<gw::AdaptTag> tags(forest.size(), gw::AdaptTag::kKeep);
  tags[1] = gw::AdaptTag::kRefine;
  forest.adapt(tags);  // 7 leaves: 3 roots and one family of 4
  for (int ranks : {1, 2, 3, 7, 10}) {
    const auto offsets = forest.partition(ranks);
    ASSERT_EQ(offsets.size(), static_cast<std::size_t>(ranks) + 1);
    EXPECT_EQ(offsets.front(), 0u);
    EXPECT_EQ(offsets.back(), forest.size());
    std::size_t smallest = forest.size(), largest = 0;
    for (int r = 0; r < ranks; ++r) {
      EXPECT_LE(offsets[r], offsets[r + 1]);
      smallest = std::min(smallest, offsets[r + 1] - offsets[r]);
      largest = std::max(largest, offsets[r + 1] - offsets[r]);
      // No cut between two siblings: the coarsen pass judges a family on one rank.
      const std::size_t cut = offsets[r + 1];
      if (cut > 0 && cut < forest.size()) {
        EXPECT_FALSE(forest.leaves()[cut].level > 0 && forest.leaves()[cut - 1].parent() == forest.leaves()[cut].parent())
            << ranks << " ranks, cut " << r + 1;
      }
    }
    // Equal chunks, but for cuts moved to the nearer end of a family (at most 2^Dim / 2 leaves).
    EXPECT_LE(largest - smallest, ranks > 1 ? 5u : 0u) << ranks << " ranks";
  }
  // Without families to keep together the chunks differ by at most one.
  gw::BlockForest<2> roots({{5, 3}, {true, true}, 3, gw::CurveOrder::kHilbert});
  const auto offsets = roots.partition(4);
  for (int r = 0; r < 4; ++r) EXPECT_NEAR(static_cast<double>(offsets[r + 1] - offsets[r]), 15.0 / 4, 0.76);
}

}  // namespace
