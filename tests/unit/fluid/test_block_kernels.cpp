// The per-block right-hand-side kernels as the solver calls them (BlockKernels.hpp: compiled once
// per instruction set, AVX-512F or AVX2 where the CPU has it) against the same templates called directly,
// which are compiled for the baseline instruction set: BlockKernels.hpp promises bitwise the same
// results on any x86-64 machine. (Checked to fail when the clone is built with FMA contraction:
// 9-167 entries then differ.) The state is rough enough to switch on the shock sensor's dissipation in both
// directions, and a second state with a strong pressure jump makes the positivity limiter redo the block,
// so every branch of the kernels is compared. (Under the sanitizers the kernels are not cloned and
// the comparison is of one code with itself.)
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <algorithm>
#include <vector>

#include "fluid/BlockKernels.hpp"
#include "fluid/IdealGas.hpp"

namespace gf = grainwave::fluid;

namespace {

constexpr double kGamma = 1.4;

/// One block of n^Dim interior points with ghosts, its conserved fields, primitives, scratch and
/// the viscous kernel's arrays, and the outputs of the two codes.
template <int Dim>
struct Block {
  static constexpr int kFields = Dim + 2;
  int n, g;
  grainwave::wavelet::ArrayShape<Dim> shape;
  std::array<std::vector<double>, kFields> q;
  std::vector<double> rho, p, e, temperature, mu, kinetic;
  std::array<std::vector<double>, Dim> u;
  std::array<std::array<std::vector<double>, Dim>, Dim> gradient;
  std::array<std::vector<double>, Dim + 1> flux;

  Block(int points, bool near_vacuum) : n(points), g(gf::kStencilReach) {
    shape.extent.fill(n + 2 * g);
    const std::size_t volume = shape.size();
    for (auto& f : q) f.resize(volume);
    for (auto* v : {&rho, &p, &e, &temperature, &mu, &kinetic}) v->assign(volume, 0.0);
    for (auto& v : u) v.assign(volume, 0.0);
    for (auto& row : gradient)
      for (auto& v : row) v.assign(volume, 0.0);
    for (auto& v : flux) v.assign(volume, 0.0);
    for (std::size_t at = 0; at < volume; ++at) {
      const auto c = shape.coords(static_cast<std::ptrdiff_t>(at));
      double phase = 0;
      for (int a = 0; a < Dim; ++a) phase += (0.7 + 0.3 * a) * c[static_cast<std::size_t>(a)];
      gf::Primitive<Dim> w;
      w.rho = 1 + 0.4 * std::sin(phase) + (c[0] > n / 2 + g ? 0.5 : 0.0);  // a jump: the sensor acts
      for (int a = 0; a < Dim; ++a) w.u[static_cast<std::size_t>(a)] = 0.3 * std::cos(phase + a);
      w.p = 0.7 + 0.2 * std::cos(1.3 * phase);
      if (near_vacuum) w.p = c[0] < g + n / 2 ? 1000 : 0.01;  // the Woodward-Colella blast's left jump
      const auto state = gf::to_conserved(w, kGamma);
      for (std::size_t f = 0; f < static_cast<std::size_t>(kFields); ++f) q[f][at] = state[f];
    }
  }

  std::array<const double*, kFields> conserved() const {
    std::array<const double*, kFields> out{};
    for (std::size_t f = 0; f < static_cast<std::size_t>(kFields); ++f) out[f] = q[f].data();
    return out;
  }

  /// The inviscid and (unless `inviscid_only`) viscous right-hand side, by the dispatched
  /// kernels or by the templates. Returns the faces the limiter changed.
  long rhs(bool dispatched, std::vector<double>& out, bool capturing = true, bool inviscid_only = false) {
    std::size_t per_block = 1;
    for (int a = 0; a < Dim; ++a) per_block *= static_cast<std::size_t>(n);
    out.assign(per_block * kFields, 0.0);
    std::array<double*, Dim> u_out{};
    for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) u_out[a] = u[a].data();
    if (dispatched) gf::primitives<Dim>(conserved(), shape.size(), kGamma, rho.data(), u_out, e.data(), p.data());
    else gf::block_primitives<Dim>(conserved(), shape.size(), kGamma, rho.data(), u_out, e.data(), p.data());
    gf::BlockPrimitives<Dim> w{rho.data(), {}, p.data(), e.data()};
    for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) w.u[a] = u[a].data();
    gf::InviscidSettings settings;
    settings.gamma = kGamma;
    settings.capturing = capturing;
    settings.coefficient = 1.2;
    settings.threshold = 1e-3;
    settings.background = 1.0 / 256;  // the solver's default with capturing
    const double h_value = 1.0 / n;
    settings.limiter_dt = 0.4 * h_value / gf::sound_speed(1.0, 1000, kGamma);  // CFL 0.4 of the blast
    std::array<double, Dim> h{};
    h.fill(h_value);
    gf::BlockScratch<Dim> scratch(shape.size());
    const long limited = dispatched ? gf::block_inviscid<Dim>(shape, g, n, w, conserved(), h, settings, scratch, out.data())
                                    : gf::add_block_inviscid<Dim>(shape, g, n, w, conserved(), h, settings, scratch, out.data());
    if (inviscid_only) return limited;
    gf::ViscousBlock<Dim> block;
    for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
      block.u[i] = u[i].data();
      for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) block.gradient[i][a] = gradient[i][a].data();
    }
    for (std::size_t f = 0; f <= static_cast<std::size_t>(Dim); ++f) block.flux[f] = flux[f].data();
    block.rho = rho.data();
    block.p = p.data();
    block.temperature = temperature.data();
    block.mu = mu.data();
    block.kinetic = kinetic.data();
    const gf::ViscousSettings viscous{kGamma, 100.0, 0.72, 110.4 / 300.0};
    if (dispatched) gf::block_viscous<Dim>(shape, g, n, h, viscous, block, out.data());
    else gf::add_block_viscous<Dim>(shape, g, n, h, viscous, block, out.data());
    return limited;
  }
};

template <int Dim>
void expect_bitwise_equal_kernels(bool near_vacuum) {
  Block<Dim> block(8, near_vacuum);
  std::vector<double> dispatched, baseline;
  const long limited_dispatched = block.rhs(true, dispatched);
  const long limited_baseline = block.rhs(false, baseline);
  EXPECT_EQ(limited_dispatched, limited_baseline);
  if (near_vacuum) EXPECT_GT(limited_baseline, 0) << "the state must make the limiter act";
  else EXPECT_EQ(limited_baseline, 0);
  ASSERT_EQ(dispatched.size(), baseline.size());
  std::size_t differing = 0;
  for (std::size_t k = 0; k < dispatched.size(); ++k) {
    EXPECT_TRUE(std::isfinite(baseline[k])) << "entry " << k;
    differing += std::memcmp(&dispatched[k], &baseline[k], sizeof(double)) != 0;
  }
  EXPECT_EQ(differing, 0u) << "of " << dispatched.size() << " right-hand-side entries";
}

}  // namespace

TEST(BlockKernels, DispatchedKernelsEqualTheTemplatesBitwise1D) {
  expect_bitwise_equal_kernels<1>(false);
  expect_bitwise_equal_kernels<1>(true);
}
TEST(BlockKernels, DispatchedKernelsEqualTheTemplatesBitwise2D) {
  expect_bitwise_equal_kernels<2>(false);
  expect_bitwise_equal_kernels<2>(true);
}
TEST(BlockKernels, DispatchedKernelsEqualTheTemplatesBitwise3D) {
  expect_bitwise_equal_kernels<3>(false);
  expect_bitwise_equal_kernels<3>(true);
}

namespace {

/// Ghost points of a block array the right-hand side may read: within `axis_reach` layers when
/// outside the interior along one axis, within `corner_reach` layers along each of two axes, and
/// never outside along three.
template <int Dim>
bool within_reach(const grainwave::wavelet::ArrayShape<Dim>& shape, int g, int n, std::ptrdiff_t at, int axis_reach,
                  int corner_reach) {
  const auto c = shape.coords(at);
  int outside = 0, deepest = 0;
  for (int a = 0; a < Dim; ++a) {
    const int i = c[static_cast<std::size_t>(a)] - g;
    const int depth = i < 0 ? -i : i >= n ? i - n + 1 : 0;
    outside += depth > 0;
    deepest = std::max(deepest, depth);
  }
  return outside == 0 || (outside == 1 && deepest <= axis_reach) || (outside == 2 && deepest <= corner_reach);
}

/// The kernels read no ghost beyond their stated reach: with every other ghost point NaN the
/// right-hand side is finite and bitwise the same. (The solver's stencil ghost fill,
/// AdaptiveGrid::fill_stencil_ghosts, leaves those points as they were.)
template <int Dim>
std::size_t entries_changed_by_poison(int axis_reach, int corner_reach, bool near_vacuum, bool capturing = true,
                                      bool inviscid_only = false) {
  Block<Dim> clean(8, near_vacuum), poisoned(8, near_vacuum);
  for (std::size_t at = 0; at < poisoned.shape.size(); ++at)
    if (!within_reach<Dim>(poisoned.shape, poisoned.g, poisoned.n, static_cast<std::ptrdiff_t>(at), axis_reach, corner_reach))
      for (auto& f : poisoned.q) f[at] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> a, b;
  clean.rhs(true, a, capturing, inviscid_only);
  poisoned.rhs(true, b, capturing, inviscid_only);
  std::size_t changed = 0;
  for (std::size_t k = 0; k < a.size(); ++k) changed += std::memcmp(&a[k], &b[k], sizeof(double)) != 0;
  return changed;
}

}  // namespace

TEST(BlockKernels, ReadNoGhostBeyondTheirReach) {
  for (bool near_vacuum : {false, true}) {
    EXPECT_EQ(entries_changed_by_poison<1>(gf::kStencilReach, 0, near_vacuum), 0u);
    EXPECT_EQ(entries_changed_by_poison<2>(gf::kStencilReach, gf::kViscousReach, near_vacuum), 0u);
    EXPECT_EQ(entries_changed_by_poison<3>(gf::kStencilReach, gf::kViscousReach, near_vacuum), 0u);
  }
  // The inviscid terms alone read along the axes only (the sensor too); without the sensor's
  // dissipation kCentralReach layers, also where the positivity limiter redoes faces.
  for (bool near_vacuum : {false, true}) {
    for (bool capturing : {false, true}) {
      EXPECT_EQ(entries_changed_by_poison<2>(gf::kStencilReach, 0, near_vacuum, capturing, true), 0u);
      EXPECT_EQ(entries_changed_by_poison<3>(gf::kStencilReach, 0, near_vacuum, capturing, true), 0u);
    }
    EXPECT_EQ(entries_changed_by_poison<1>(gf::kCentralReach, 0, near_vacuum, false, true), 0u);
    EXPECT_EQ(entries_changed_by_poison<2>(gf::kCentralReach, 0, near_vacuum, false, true), 0u);
    EXPECT_EQ(entries_changed_by_poison<3>(gf::kCentralReach, 0, near_vacuum, false, true), 0u);
  }
  {
    Block<2> blast(8, true);
    std::vector<double> out;
    EXPECT_GT(blast.rhs(true, out, false, true), 0) << "the limiter must act without the sensor too";
  }
  EXPECT_GT(entries_changed_by_poison<2>(gf::kCentralReach - 1, 0, false, false, true), 0u);
  EXPECT_GT(entries_changed_by_poison<2>(gf::kCentralReach, 0, false, true, true), 0u) << "the sensor reads layer 3";
  // And the reach is not smaller than stated: poisoning one layer more changes the result.
  EXPECT_GT(entries_changed_by_poison<2>(gf::kStencilReach - 1, gf::kViscousReach, false), 0u);
  EXPECT_GT(entries_changed_by_poison<2>(gf::kStencilReach, gf::kViscousReach - 1, false), 0u);
  EXPECT_GT(entries_changed_by_poison<3>(gf::kStencilReach, gf::kViscousReach - 1, false), 0u);
}
