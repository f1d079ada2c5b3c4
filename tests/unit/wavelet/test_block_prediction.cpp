// BlockPrediction.hpp: the separable form of the refinement's prediction against the
// point-by-point tensor sums it replaced, bitwise, for every child of parents in the domain's
// interior and at bounded and periodic edges (one-sided stencils there).
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <random>
#include <vector>

#include "wavelet/BlockPrediction.hpp"

namespace gw = grainwave::wavelet;
namespace gp = grainwave::wavelet::prediction;

namespace {

template <int Dim>
void separable_sums_are_tensor_sums(int order, int block_size, bool periodic) {
  gw::GridConfig<Dim> c;
  for (std::size_t a = 0; a < Dim; ++a) {
    c.lo[a] = 0;
    c.hi[a] = 1;
    c.roots[a] = 2;
    c.periodic[a] = periodic;
  }
  c.block_size = block_size;
  c.order = order;
  const int g = 2 * order;  // more than any stencil reaches
  const int width = block_size + 2 * g;
  std::array<std::ptrdiff_t, Dim> stride{};
  std::ptrdiff_t volume = 1;
  for (std::size_t a = 0; a < Dim; ++a) {
    stride[a] = volume;
    volume *= width;
  }
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> value(-1, 1);
  std::vector<double> parent(static_cast<std::size_t>(volume));
  for (double& v : parent) v = value(rng);
  std::array<std::vector<double>, Dim> stages;
  std::array<std::array<gw::AxisStencil, gw::kMaxBlockSize>, Dim> st;
  // Level-1 parents: every block of a 4^Dim grid of them, so corners, edges and interiors.
  for (std::uint32_t code = 0; code < (1u << (2 * Dim)); ++code) {
    std::array<std::uint32_t, Dim> coords{};
    for (std::size_t a = 0; a < Dim; ++a) coords[a] = (code >> (2 * a)) & 3u;
    const auto key = gw::BlockKey<Dim>::from_coords(1, coords);
    for (int child = 0; child < (1 << Dim); ++child) {
      gp::child_stencils<Dim>(key, child, c, g, st);
      const double* separable = gp::separable_tensor_sums<Dim>(parent.data(), width, st, block_size, stages);
      std::size_t p = 0;
      gp::for_each_interior<Dim>(block_size, 0, gw::ArrayShape<Dim>{}, [&](std::size_t, const std::array<int, Dim>& i,
                                                                             std::ptrdiff_t) {
        std::array<const gw::AxisStencil*, Dim> row{};
        for (std::size_t a = 0; a < Dim; ++a) row[a] = &st[a][static_cast<std::size_t>(i[a])];
        const double tensor = gp::tensor_sum<Dim>(parent.data(), stride, row);
        ASSERT_EQ(std::memcmp(&tensor, &separable[p], sizeof tensor), 0)
            << "parent " << code << " child " << child << " point " << p << ": " << tensor << " vs " << separable[p];
        ++p;
      });
    }
  }
}

}  // namespace

TEST(BlockPrediction, SeparableSumsAreTensorSums2D) {
  for (const int order : {4, 6})
    for (const bool periodic : {false, true}) separable_sums_are_tensor_sums<2>(order, 8, periodic);
  separable_sums_are_tensor_sums<2>(6, 16, false);
}

TEST(BlockPrediction, SeparableSumsAreTensorSums3D) {
  for (const int order : {4, 6})
    for (const bool periodic : {false, true}) separable_sums_are_tensor_sums<3>(order, 8, periodic);
}

TEST(BlockPrediction, SeparableSumsAreTensorSums1D) {
  separable_sums_are_tensor_sums<1>(6, 8, false);
  separable_sums_are_tensor_sums<1>(4, 8, true);
}
