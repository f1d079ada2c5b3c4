// The ghost plan's table of distinct weights (wavelet/WeightTable.hpp): every term of a fill
// reads its weight through it, so a wrong index is a wrong ghost value.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <stdexcept>
#include <vector>

#include "wavelet/WeightTable.hpp"

namespace gw = grainwave::wavelet;

TEST(WeightTable, OneIsIndexZeroAndRepeatsKeepTheirIndex) {
  gw::WeightTable table;
  EXPECT_EQ(table.index_of(1.0), gw::WeightTable::kOne);
  EXPECT_EQ(table[gw::WeightTable::kOne], 1.0);
  const auto a = table.index_of(9.0 / 16.0), b = table.index_of(-1.0 / 16.0);
  EXPECT_NE(a, b);
  EXPECT_EQ(table.index_of(9.0 / 16.0), a);
  EXPECT_EQ(table.index_of(-1.0 / 16.0), b);
  // Bits, not values, tell weights apart: -0 and +0 are two entries (a plan drops zero
  // weights, so neither occurs there).
  EXPECT_NE(table.index_of(0.0), table.index_of(-0.0));
}

TEST(WeightTable, ManyWeightsThroughSeveralGrowthsRoundTrip) {
  // The table starts with 256 slots and doubles past half full: 20 000 weights (products of
  // Deslauriers-Dubuc-like fractions, many sharing high bits) take it through seven growths.
  gw::WeightTable table;
  std::vector<double> weights;
  for (int k = 1; k <= 20000; ++k) weights.push_back(std::ldexp(static_cast<double>(k % 977) - 488.5, -(k % 23)) / 3.0 + k * 1e-9);
  std::vector<std::uint16_t> index;
  for (const double w : weights) index.push_back(table.index_of(w));
  std::set<double> distinct(weights.begin(), weights.end());
  std::set<std::uint16_t> indices(index.begin(), index.end());
  EXPECT_EQ(indices.size(), distinct.size());
  for (std::size_t k = 0; k < weights.size(); ++k) {
    ASSERT_EQ(table[index[k]], weights[k]) << "weight " << k;
    ASSERT_EQ(table.index_of(weights[k]), index[k]) << "weight " << k << " after the growths";
  }
  EXPECT_EQ(table.data()[index.back()], weights.back());
}

TEST(WeightTable, RefusesMoreThan65535Weights) {
  gw::WeightTable table;  // holds 1 already
  for (int k = 1; k < 65535; ++k) table.index_of(1.0 + k * 0x1p-40);
  EXPECT_THROW(table.index_of(-3.0), std::length_error);
  EXPECT_EQ(table.index_of(1.0 + 7 * 0x1p-40), 7);  // what it holds stays found
}
