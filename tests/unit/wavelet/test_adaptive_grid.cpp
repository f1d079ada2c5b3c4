// AdaptiveGrid: coordinates, ghosts per interface type, thresholding and adaptation against
// analytic fields, perfect reconstruction, derivative orders on adapted grids. Runs on any number
// of ranks (ctest runs it on 1 and 2); every assertion holds globally.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <vector>

#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/DetailKernels.hpp"

namespace gw = grainwave::wavelet;

namespace {

constexpr double kPi = std::numbers::pi;

double global_max(double v) {
  double m = 0;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return m;
}
std::int64_t global_sum(std::int64_t v) {
  std::int64_t s = 0;
  MPI_Allreduce(&v, &s, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  return s;
}
bool root() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r == 0;
}

template <int Dim>
gw::GridConfig<Dim> unit_box(bool periodic, int min_level, int max_level, int order = 4) {
  gw::GridConfig<Dim> c;
  c.lo.fill(0.0);
  c.hi.fill(1.0);
  c.roots.fill(2);
  c.periodic.fill(periodic);
  c.min_level = min_level;
  c.max_level = max_level;
  c.order = order;
  c.fields = {"u", "du"};
  return c;
}

/// Max over every local point of |u - exact| (interior only, or ghosts of one kind).
template <int Dim, class F>
double max_error(const gw::AdaptiveGrid<Dim>& grid, int field, F&& exact, bool ghosts, gw::GhostKind kind) {
  const auto shape = grid.layout().shape();
  const int g = grid.layout().ghosts, bs = grid.config().block_size;
  double err = 0;
  for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
    const auto u = grid.block(field, s);
    for (std::size_t p = 0; p < shape.size(); ++p) {
      auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      bool interior = true;
      for (auto& c : i) {
        c -= g;
        interior = interior && c >= 0 && c < bs;
      }
      if (interior == ghosts) continue;
      if (ghosts && grid.ghost_kind(s, static_cast<std::ptrdiff_t>(p)) != kind) continue;
      err = std::max(err, std::abs(u[p] - exact(grid.position(s, i))));
    }
  }
  return global_max(err);
}

/// Refines the blocks whose lower corner lies in x < 0.5 (a fixed mixed-level pattern).
template <int Dim>
void refine_left_half(gw::AdaptiveGrid<Dim>& grid) {
  std::vector<gw::AdaptTag> tags(grid.global_blocks(), gw::AdaptTag::kKeep);
  for (std::size_t l = 0; l < tags.size(); ++l)
    if (grid.origin(grid.forest().leaves()[l])[0] < 0.5) tags[l] = gw::AdaptTag::kRefine;
  grid.adapt_with_tags(tags);
}

/// The moving-front set-up of the adaptation tests: blocks of 8 on the unit box, levels 0..4
/// (0..2 in 3D), field 0 a smoothed disc (sphere) whose centre moves along x by `shift`, field 1
/// smooth and left out of the thresholding.
template <int Dim>
gw::GridConfig<Dim> front_grid(bool periodic) {
  auto c = unit_box<Dim>(periodic, 0, Dim == 3 ? 2 : 4);
  c.block_size = 8;
  return c;
}
inline gw::ThresholdConfig front_threshold() {
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  th.groups = {0, -1};
  return th;
}
template <int Dim>
auto moving_front(double shift) {
  return [shift](const std::array<double, Dim>& x, std::span<double> v) {
    double r2 = 0;
    for (int a = 0; a < Dim; ++a) r2 += std::pow(x[static_cast<std::size_t>(a)] - (a == 0 ? 0.3 + shift : 0.5), 2);
    v[0] = 0.5 * (1 - std::tanh((std::sqrt(r2) - 0.2) / 0.03));
    v[1] = std::sin(3 * x[0]) * std::cos(2 * x[Dim - 1]);
  };
}

/// Every local block array of fields 0 and 1, ghosts included, field by field.
template <int Dim>
std::vector<std::vector<double>> snapshot(const gw::AdaptiveGrid<Dim>& grid) {
  std::vector<std::vector<double>> out(2);
  for (int f = 0; f < 2; ++f)
    for (std::size_t s = 0; s < grid.local_blocks(); ++s)
      out[static_cast<std::size_t>(f)].insert(out[static_cast<std::size_t>(f)].end(), grid.block(f, s).begin(),
                                              grid.block(f, s).end());
  return out;
}

/// visit(f, s, p, value, reference) for every point of fields 0 and 1 but the ghosts outside
/// the domain, with the value the snapshot holds there.
template <int Dim, class Visit>
void compare_with_snapshot(const gw::AdaptiveGrid<Dim>& grid, const std::vector<std::vector<double>>& reference,
                           Visit&& visit) {
  for (int f = 0; f < 2; ++f)
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
      const auto u = grid.block(f, s);
      for (std::size_t p = 0; p < u.size(); ++p) {
        if (grid.ghost_kind(s, static_cast<std::ptrdiff_t>(p)) == gw::GhostKind::kOutsideDomain) continue;
        visit(f, s, p, u[p], reference[static_cast<std::size_t>(f)][s * u.size() + p]);
      }
    }
}

/// The stencil-fill tests' grid: blocks of 8 on the unit box, the left half refined twice (ghosts
/// of every kind), and their two fields: a smooth pair, and another to overwrite it with.
template <int Dim>
gw::AdaptiveGrid<Dim> mixed_level_grid() {
  auto c = unit_box<Dim>(false, 0, 3);
  c.block_size = 8;
  gw::AdaptiveGrid<Dim> grid(c);
  refine_left_half(grid);
  refine_left_half(grid);
  return grid;
}
template <int Dim>
void smooth_pair(const std::array<double, Dim>& x, std::span<double> v) {
  double r = 0;
  for (int a = 0; a < Dim; ++a) r += std::sin(3.0 * (a + 1) * x[static_cast<std::size_t>(a)]);
  v[0] = r;
  v[1] = std::cos(2 * x[0]);
}
template <int Dim>
void other_pair(const std::array<double, Dim>& x, std::span<double> v) {
  v[0] = 1.0 + x[0];
  v[1] = -3.0;
}

/// Whether array point p of a block is an interior point or a ghost within a stencil reach of
/// `axis` layers beyond a face and `corner` along each of two axes (set_stencil_reach).
template <int Dim>
bool within_stencil_reach(const gw::AdaptiveGrid<Dim>& grid, std::size_t p, int axis, int corner) {
  const auto i = grid.layout().shape().coords(static_cast<std::ptrdiff_t>(p));
  const int g = grid.layout().ghosts, bs = grid.config().block_size;
  int outside = 0, deepest = 0;
  for (int a = 0; a < Dim; ++a) {
    const int local = i[static_cast<std::size_t>(a)] - g;
    const int depth = local < 0 ? -local : local >= bs ? local - bs + 1 : 0;
    outside += depth > 0 ? 1 : 0;
    deepest = std::max(deepest, depth);
  }
  return outside == 1 ? deepest <= axis : outside == 2 ? deepest <= corner : outside == 0;
}

}  // namespace

TEST(AdaptiveGrid, BlockOriginAndSpacingFollowLevelAndMorton) {
  auto c = unit_box<2>(false, 1, 3);
  c.hi = {2.0, 1.0};
  gw::AdaptiveGrid<2> grid(c);
  EXPECT_EQ(grid.global_blocks(), 16u);  // 2x2 roots refined once
  const auto h = grid.spacing(1);
  EXPECT_DOUBLE_EQ(h[0], 2.0 / (2 * 8 * 2));
  EXPECT_DOUBLE_EQ(h[1], 1.0 / (2 * 8 * 2));
  const auto key = gw::BlockKey<2>::from_coords(1, {3, 2});
  const auto x0 = grid.origin(key);
  EXPECT_DOUBLE_EQ(x0[0], 3 * 8 * h[0]);
  EXPECT_DOUBLE_EQ(x0[1], 2 * 8 * h[1]);
  EXPECT_DOUBLE_EQ(grid.uniform_points(), (2 * 8 * 8.0) * (2 * 8 * 8.0));
}

// Polynomials of degree < order along each axis are predicted exactly (the prediction is a
// tensor product), so every ghost of a mixed-level non-periodic grid equals the polynomial:
// same level (copy), fine -> coarse (injection) and coarse -> fine (prediction) alike, in 1D,
// 2D and 3D, at ghost order 4 and 6. The product term, of full degree along every axis, is what
// a ghost odd along several axes sees: flattened or cascaded through the block's other ghost
// rows (cascade_rows), a wrong term or weight there shows up far above round-off.
template <int Dim>
void ghosts_exact_for_polynomials(int ghost_order, int block_size) {
  auto c = unit_box<Dim>(false, 0, 3);
  c.ghost_order = ghost_order;
  c.block_size = block_size;
  gw::AdaptiveGrid<Dim> grid(c);
  refine_left_half(grid);
  refine_left_half(grid);  // levels 0, 1, 2 side by side
  const int degree = ghost_order - 1;
  auto polynomial = [&](const std::array<double, Dim>& x) {
    double sum = 1, product = 1;
    for (int a = 0; a < Dim; ++a) {
      const double t = x[static_cast<std::size_t>(a)];
      sum += (0.3 + a) * t * t * t - t * t + 0.7 * t;
      product *= 0.5 + std::pow(t - 0.4, degree) + 0.2 * t;
    }
    return sum + product;
  };
  grid.sample([&](const auto& x, std::span<double> v) { v[0] = polynomial(x); v[1] = 0; });
  grid.fill_ghosts();
  const auto n = grid.ghost_counts();
  for (int k = 0; k < 4; ++k) EXPECT_GT(global_sum(n[static_cast<std::size_t>(k)]), 0) << "ghost kind " << k;
  for (auto kind : {gw::GhostKind::kSameLevel, gw::GhostKind::kFromFiner, gw::GhostKind::kFromCoarser})
    EXPECT_LT(max_error(grid, 0, polynomial, true, kind), 1e-12)
        << "kind " << static_cast<int>(kind) << ", ghost order " << ghost_order << ", block size " << block_size;
  // Ghosts odd along several axes are cascaded, not flattened: no row has the full tensor's
  // ghost_order^Dim terms, only those of a prediction along one axis (and, in 3D, the scratch
  // points' predictions along two).
  const auto stats = grid.ghost_plan_stats();
  int longest = ghost_order;
  for (int a = 2; a < Dim; ++a) longest *= ghost_order;
  EXPECT_LE(stats.longest_row, longest) << "ghost order " << ghost_order << ", block size " << block_size;
  if (Dim > 1) {
    EXPECT_GT(global_sum(stats.scratch_points), 0);
  }
}
TEST(AdaptiveGrid, GhostsExactForPolynomials1D) {
  ghosts_exact_for_polynomials<1>(4, 8);
  ghosts_exact_for_polynomials<1>(6, 8);
}
TEST(AdaptiveGrid, GhostsExactForPolynomials2D) {
  for (int order : {4, 6})
    for (int bs : {8, 16}) ghosts_exact_for_polynomials<2>(order, bs);
}
TEST(AdaptiveGrid, GhostsExactForPolynomials3D) {
  ghosts_exact_for_polynomials<3>(4, 8);
  ghosts_exact_for_polynomials<3>(6, 8);
}

// A fill copies same-level ghosts by rectangles (GhostPlan::CopyRun): on a uniform periodic grid
// of 4 x 4 blocks each block reads its eight neighbours, one rectangle each, although in array
// order the rows of its left and right faces alternate. Across ranks the copies are remote rows
// instead, so the count is exact on one rank and at most that on more.
TEST(AdaptiveGrid, SameLevelCopiesFormOneRectanglePerNeighbour) {
  auto c = unit_box<2>(true, 1, 1);
  c.block_size = 8;
  gw::AdaptiveGrid<2> grid(c);
  ASSERT_EQ(grid.global_blocks(), 16u);
  const auto stats = grid.ghost_plan_stats();
  const auto ghosts = static_cast<std::int64_t>(grid.local_blocks() * (14 * 14 - 8 * 8));
  EXPECT_EQ(stats.rows, ghosts);
  const auto rectangles = global_sum(stats.copy_rectangles);
  int ranks = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  if (ranks == 1) {
    EXPECT_EQ(stats.copies, ghosts);
    EXPECT_EQ(rectangles, 8 * 16);
  } else {
    EXPECT_LE(rectangles, 8 * 16);
    EXPECT_GT(rectangles, 0);
  }
}

// Periodic images and smooth non-polynomial data: copies and injections stay exact, predicted
// ghosts converge at the interpolation order (4 and 6) when every level moves up by one.
template <int Dim>
void periodic_ghost_orders(int order) {
  auto field = [](const std::array<double, Dim>& x) {
    double v = 0;
    for (int a = 0; a < Dim; ++a) v += std::sin(2 * kPi * x[a] + a + 0.4);  // no node of sin at x = 0.5
    return v;
  };
  std::array<double, 2> err{};
  for (int shift = 0; shift < 2; ++shift) {
    gw::AdaptiveGrid<Dim> grid(unit_box<Dim>(true, 1 + shift, 4, order));
    refine_left_half(grid);
    grid.sample([&](const auto& x, std::span<double> v) { v[0] = field(x); v[1] = 0; });
    grid.fill_ghosts();
    EXPECT_EQ(global_sum(grid.ghost_counts()[3]), 0) << "a periodic domain has no outside";
    EXPECT_LT(max_error(grid, 0, field, true, gw::GhostKind::kSameLevel), 1e-14);
    EXPECT_LT(max_error(grid, 0, field, true, gw::GhostKind::kFromFiner), 1e-14);
    err[static_cast<std::size_t>(shift)] = max_error(grid, 0, field, true, gw::GhostKind::kFromCoarser);
  }
  const double measured = std::log2(err[0] / err[1]);
  if (root()) std::printf("periodic %dD coarse->fine ghosts, order %d: errors %.3e %.3e, order %.2f\n", Dim, order, err[0], err[1], measured);
  EXPECT_NEAR(measured, order, 0.3);
}
TEST(AdaptiveGrid, PeriodicGhostOrder2D) {
  periodic_ghost_orders<2>(4);
  periodic_ghost_orders<2>(6);
}
TEST(AdaptiveGrid, PeriodicGhostOrder1D) { periodic_ghost_orders<1>(4); }

// Coarsening a refined grid restores the original values exactly (injection of the copied even
// points), and refining by prediction reproduces a cubic exactly.
TEST(AdaptiveGrid, RefineThenCoarsenIsIdentity) {
  gw::AdaptiveGrid<2> grid(unit_box<2>(false, 1, 3));
  grid.sample([](const auto& x, std::span<double> v) { v[0] = std::exp(std::sin(5 * x[0]) * x[1]); v[1] = x[0] * x[0] * x[0] + x[1]; });
  grid.fill_ghosts();
  const gw::AdaptiveGrid<2> original(grid);
  grid.refine_to_uniform();
  EXPECT_EQ(grid.global_blocks(), 4u * 64u);
  EXPECT_LT(max_error(grid, 1, [](const auto& x) { return x[0] * x[0] * x[0] + x[1]; }, false, gw::GhostKind::kSameLevel), 1e-12);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<gw::AdaptTag> tags(grid.global_blocks(), gw::AdaptTag::kCoarsen);
    grid.adapt_with_tags(tags);
  }
  ASSERT_EQ(grid.global_blocks(), original.global_blocks());
  for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
    ASSERT_EQ(grid.key(s), original.key(s));
    const std::span<const double> a = grid.block(0, s), b = original.block(0, s);
    const auto shape = grid.layout().shape();
    for (std::size_t p = 0; p < shape.size(); ++p) {
      auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      bool interior = true;
      for (int c : i) interior = interior && c >= grid.layout().ghosts && c < grid.layout().ghosts + 8;
      if (interior) {
        ASSERT_EQ(a[p], b[p]);
      }
    }
  }
}

namespace {
/// A steep front and a bump (1D), or a smoothed disc (2D).
double front_1d(const std::array<double, 1>& x) {
  return std::tanh((x[0] - 0.4) / 0.02) + std::exp(-std::pow((x[0] - 0.7) / 0.05, 2));
}
double disc_2d(const std::array<double, 2>& x) {
  const double r = std::hypot(x[0] - 0.5, x[1] - 0.45);
  return 0.5 * (1 - std::tanh((r - 0.25) / 0.04));
}
double sphere_3d(const std::array<double, 3>& x) {
  const double r = std::sqrt(std::pow(x[0] - 0.5, 2) + std::pow(x[1] - 0.45, 2) + std::pow(x[2] - 0.52, 2));
  return 0.5 * (1 - std::tanh((r - 0.25) / 0.04));
}

struct Adapted {
  double error;
  std::int64_t significant, blocks;
};

template <int Dim, class F>
Adapted adapt_and_reconstruct(gw::GridConfig<Dim> c, double eps, F&& exact) {
  gw::AdaptiveGrid<Dim> grid(c);
  gw::ThresholdConfig th;
  th.epsilon = eps;
  th.groups = {0, -1};
  grid.adapt_to_function(th, [&](const auto& x, std::span<double> v) { v[0] = exact(x); v[1] = 0; });
  Adapted out{0, grid.significant_points(th), static_cast<std::int64_t>(grid.global_blocks())};
  gw::AdaptiveGrid<Dim> uniform(grid);
  uniform.refine_to_uniform();
  out.error = max_error(uniform, 0, exact, false, gw::GhostKind::kSameLevel);
  return out;
}
}  // namespace

// Error control: the adapted grid, reconstructed to the uniform finest grid by prediction, is
// within C * eps of the field (scale max |u| = 1..2). The active set grows like eps^(-d/p).
/// Adapts to `exact` at each eps and reconstructs on the uniform finest grid: the error is below
/// C eps with C < 2 (field scale `scale`), and the significant set grows between eps[from] and
/// the last eps like eps^(-d/p) within `tolerance`.
template <int Dim, class F>
void check_error_control(const gw::GridConfig<Dim>& c, const std::vector<double>& eps, F&& exact, double scale,
                         std::size_t from, double d_over_p, double tolerance) {
  double worst = 0;
  std::vector<double> sig;
  for (double e : eps) {
    const auto r = adapt_and_reconstruct<Dim>(c, e, exact);
    const double C = r.error / (e * scale);
    worst = std::max(worst, C);
    sig.push_back(static_cast<double>(r.significant));
    if (root()) std::printf("%dD eps %.0e: error %.3e, C %.2f, significant %lld, blocks %lld\n", Dim, e, r.error, C, static_cast<long long>(r.significant), static_cast<long long>(r.blocks));
  }
  EXPECT_LT(worst, 2.0);
  const double slope = std::log(sig.back() / sig[from]) / std::log(eps[from] / eps.back());
  if (root()) std::printf("%dD significant ~ eps^-%.3f (d/p = %.2f)\n", Dim, slope, d_over_p);
  EXPECT_NEAR(slope, d_over_p, tolerance);
}

TEST(AdaptiveGrid, ReconstructionErrorBoundedByEpsilon1D) {
  // Growth over the two finest decades (the coarser ones hold only a handful of coefficients);
  // scale: max |u| ~ 2.
  check_error_control<1>(unit_box<1>(false, 0, 9), {1e-2, 1e-3, 1e-4, 1e-5, 1e-6}, front_1d, 2.0, 2, 0.25, 0.1);
}

TEST(AdaptiveGrid, ReconstructionErrorBoundedByEpsilon2D) {
  // The finest decade: at eps = 1e-2 the front holds too few coefficients to be asymptotic.
  check_error_control<2>(unit_box<2>(true, 1, 4), {1e-2, 1e-3, 1e-4}, disc_2d, 1.0, 1, 0.5, 0.15);
}

// The 3D smoothed sphere over three decades of eps (levels 0..3, blocks of 8^3: 128^3 points at
// the finest level; the deeper sweep to 1e-6 is in scripts/validate). Between the two finest
// decades the significant set grows like eps^(-d/p), d/p = 3/4, as in 1D and 2D (measured 0.79).
TEST(AdaptiveGrid, ReconstructionErrorBoundedByEpsilon3D) {
  check_error_control<3>(unit_box<3>(true, 0, 3), {1e-2, 1e-3, 1e-4}, sphere_3d, 1.0, 1, 0.75, 0.15);
}

// A right-hand side whose stencils reach 2 layers along an axis and 1 x 1 into corners fills
// only those ghosts (fill_stencil_ghosts): they equal a full fill's bitwise, and every other
// ghost point keeps what it held, on a mixed-level grid with ghosts of every kind.
template <int Dim>
void stencil_ghosts_are_those_of_a_full_fill() {
  auto grid = mixed_level_grid<Dim>();
  grid.sample(smooth_pair<Dim>);
  grid.fill_ghosts();
  const auto full = snapshot(grid);
  // Every ghost and every intermediate point of the separable prolongation (stored beside the
  // blocks) then holds another field's values: a stencil fill that read one it does not fill
  // would show it.
  grid.sample(other_pair<Dim>);
  grid.fill_ghosts();
  grid.sample(smooth_pair<Dim>);
  constexpr int kAxis = 2, kCorner = 1;
  grid.set_stencil_reach(kAxis, kCorner);
  const auto shape = grid.layout().shape();
  const int g = grid.layout().ghosts, bs = grid.config().block_size;
  auto within = [&](std::size_t p) { return within_stencil_reach<Dim>(grid, p, kAxis, kCorner); };
  // Poison every ghost, fill the stencil ghosts, and compare.
  for (int f = 0; f < 2; ++f)
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
      auto u = grid.block(f, s);
      for (std::size_t p = 0; p < u.size(); ++p)
        if (grid.ghost_kind(s, static_cast<std::ptrdiff_t>(p)) != gw::GhostKind::kOutsideDomain && !within(p)) u[p] = -7.0;
      for (std::size_t p = 0; p < u.size(); ++p) {
        const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
        bool interior = true;
        for (int a = 0; a < Dim; ++a) interior = interior && i[static_cast<std::size_t>(a)] >= g && i[static_cast<std::size_t>(a)] < g + bs;
        if (!interior && within(p)) u[p] = std::numeric_limits<double>::quiet_NaN();
      }
    }
  grid.fill_stencil_ghosts();
  std::int64_t filled = 0, kept = 0, wrong = 0;
  compare_with_snapshot(grid, full, [&](int, std::size_t, std::size_t p, double value, double expected) {
    if (within(p)) {
      wrong += std::memcmp(&value, &expected, sizeof(double)) != 0 ? 1 : 0;
      ++filled;
    } else {
      wrong += value != -7.0 ? 1 : 0;
      ++kept;
    }
  });
  EXPECT_EQ(global_sum(wrong), 0);
  EXPECT_GT(global_sum(kept), 0);
  EXPECT_GT(global_sum(filled), global_sum(kept));
  // A full fill afterwards fills the rest again.
  grid.fill_ghosts();
  std::int64_t refilled_wrong = 0;
  compare_with_snapshot(grid, full, [&](int, std::size_t, std::size_t, double value, double expected) {
    refilled_wrong += std::memcmp(&value, &expected, sizeof(double)) != 0 ? 1 : 0;
  });
  EXPECT_EQ(global_sum(refilled_wrong), 0);
}
TEST(AdaptiveGrid, StencilGhostsAreThoseOfAFullFill2D) { stencil_ghosts_are_those_of_a_full_fill<2>(); }
TEST(AdaptiveGrid, StencilGhostsAreThoseOfAFullFill3D) { stencil_ghosts_are_those_of_a_full_fill<3>(); }

// write_and_fill_stencil_ghosts fills each block's ghosts as soon as the blocks they read are
// written (its copies and sums as soon as the blocks each joins are): its interiors and stencil
// ghosts must be bitwise those of writing every block and then fill_stencil_ghosts. Before it,
// every point holds another field's values, so a ghost filled before one of its sources was
// written would show (a sum made when only its destination is written fails it). Checked again
// after each of two adaptations (a refinement, then its coarsening back), whose new plans (one
// of them the storage of the first) must order their fill afresh.
template <int Dim>
void filling_while_writing_is_writing_then_filling() {
  auto grid = mixed_level_grid<Dim>();
  constexpr int kAxis = 2, kCorner = 1;
  grid.set_stencil_reach(kAxis, kCorner);
  for (int adaptation = 0; adaptation < 3; ++adaptation) {
    if (adaptation == 1) refine_left_half(grid);
    if (adaptation == 2) {
      int finest = 0;
      for (const auto& key : grid.forest().leaves()) finest = std::max(finest, key.level);
      std::vector<gw::AdaptTag> tags(grid.global_blocks(), gw::AdaptTag::kKeep);
      for (std::size_t l = 0; l < tags.size(); ++l)
        if (grid.forest().leaves()[l].level == finest) tags[l] = gw::AdaptTag::kCoarsen;
      grid.adapt_with_tags(tags);
    }
    grid.sample(smooth_pair<Dim>);
    grid.fill_stencil_ghosts();
    const auto reference = snapshot(grid);
    grid.sample(other_pair<Dim>);
    grid.fill_ghosts();
    const auto shape = grid.layout().shape();
    const int g = grid.layout().ghosts, bs = grid.config().block_size;
    std::vector<std::size_t> written;
    const double seconds = grid.write_and_fill_stencil_ghosts([&](std::size_t s) {
      written.push_back(s);
      for (int f = 0; f < 2; ++f) {
        auto u = grid.block(f, s);
        for (std::size_t p = 0; p < u.size(); ++p) {
          const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
          bool interior = true;
          for (int a = 0; a < Dim; ++a) interior = interior && i[static_cast<std::size_t>(a)] >= g && i[static_cast<std::size_t>(a)] < g + bs;
          if (interior) u[p] = reference[static_cast<std::size_t>(f)][s * u.size() + p];
        }
      }
    });
    EXPECT_GE(seconds, 0.0);
    ASSERT_EQ(written.size(), grid.local_blocks());
    for (std::size_t s = 0; s < written.size(); ++s) EXPECT_EQ(written[s], s);
    std::int64_t compared = 0, wrong = 0;
    compare_with_snapshot(grid, reference, [&](int, std::size_t, std::size_t p, double value, double expected) {
      if (!within_stencil_reach<Dim>(grid, p, kAxis, kCorner)) return;
      wrong += std::memcmp(&value, &expected, sizeof(double)) != 0 ? 1 : 0;
      ++compared;
    });
    EXPECT_EQ(global_sum(wrong), 0) << "after " << adaptation << " adaptation(s)";
    EXPECT_GT(global_sum(compared), 0);
  }
}
TEST(AdaptiveGrid, FillingWhileWritingIsWritingThenFilling2D) { filling_while_writing_is_writing_then_filling<2>(); }
TEST(AdaptiveGrid, FillingWhileWritingIsWritingThenFilling3D) { filling_while_writing_is_writing_then_filling<3>(); }

// After an adaptation the ghost rows of blocks whose neighbourhood did not change are copied
// from the previous plan, the others resolved again: after every cycle of a moving front the
// ghosts must equal, bitwise, those of a plan built from scratch for the same leaves. On two
// ranks, blocks that read another rank are always rebuilt, and repartitioning moves blocks.
// A reused block's copy runs and packed sums are taken from the old plan's grouping, its
// scratch points moved (group_ghost_rows); with a stencil reach set (reach > 0) they fall in two
// lists, both filled, and the reach changes every cycle (the plan is then built afresh, and
// reused by the next adaptation). `reused`: how many blocks the rebuilds reused, over all ranks.
template <int Dim>
void reused_ghost_rows_match_a_fresh_plan(std::int64_t& reused, bool periodic, int reach = 0, bool keep_pages_in_order = false) {
  auto c = front_grid<Dim>(periodic);
  c.keep_pages_in_order = keep_pages_in_order;  // off: every cycle reuses what it can
  c.pages_in_order_above_bytes = 0;               // on: whatever the size of this small grid
  gw::AdaptiveGrid<Dim> grid(c);
  if (reach > 0) grid.set_stencil_reach(reach, 1);
  const auto th = front_threshold();
  std::int64_t checked = 0;
  reused = 0;
  for (int cycle = 0; cycle < 6; ++cycle) {
    const auto field = moving_front<Dim>(0.06 * cycle);
    grid.sample(field);
    grid.fill_ghosts();
    grid.adapt(th, gw::AdaptPass::kRefine);
    reused += grid.ghost_plan_stats().reused_blocks;
    grid.sample(field);
    grid.fill_ghosts();
    grid.adapt(th, gw::AdaptPass::kCoarsen);
    reused += grid.ghost_plan_stats().reused_blocks;
    // A new stencil reach: the plan is built afresh, and the next adaptation reuses from it.
    if (reach > 0) grid.set_stencil_reach(cycle % 2 == 0 ? reach - 1 : reach, 1);
    grid.sample(field);
    grid.fill_ghosts();
    gw::AdaptiveGrid<Dim> fresh(c);
    const std::vector<gw::BlockKey<Dim>> leaves(grid.forest().leaves().begin(), grid.forest().leaves().end());
    fresh.rebuild(leaves);
    ASSERT_EQ(fresh.local_blocks(), grid.local_blocks());
    for (std::size_t s = 0; s < grid.local_blocks(); ++s)
      for (int f = 0; f < 2; ++f) std::ranges::copy(grid.block(f, s), fresh.block(f, s).begin());
    fresh.fill_ghosts();
    for (std::size_t s = 0; s < grid.local_blocks(); ++s)
      for (int f = 0; f < 2; ++f) {
        const auto a = grid.block(f, s), b = fresh.block(f, s);
        for (std::size_t p = 0; p < a.size(); ++p) {
          if (grid.ghost_kind(s, static_cast<std::ptrdiff_t>(p)) == gw::GhostKind::kOutsideDomain) continue;
          ASSERT_EQ(a[p], b[p]) << "cycle " << cycle << " block " << s << " field " << f << " point " << p;
          ASSERT_EQ(grid.ghost_kind(s, static_cast<std::ptrdiff_t>(p)), fresh.ghost_kind(s, static_cast<std::ptrdiff_t>(p)));
          ++checked;
        }
      }
  }
  EXPECT_GT(global_sum(checked), 0);
  reused = global_sum(reused);
}
TEST(AdaptiveGrid, ReusedGhostRowsMatchAFreshPlan2D) {
  // Each run must have reused blocks, or it compared fresh plans with fresh plans.
  std::int64_t reused = 0, kept_scattered = 0, put_in_order = 0;
  for (const bool periodic : {true, false}) {
    reused_ghost_rows_match_a_fresh_plan<2>(reused, periodic);
    EXPECT_GT(reused, 0) << "periodic " << periodic;
  }
  reused_ghost_rows_match_a_fresh_plan<2>(kept_scattered, true, 2);
  EXPECT_GT(kept_scattered, 0);
  // The pages put in order when scattered: those rebuilds start afresh, so fewer blocks are
  // reused than over the same cycles left scattered.
  reused_ghost_rows_match_a_fresh_plan<2>(put_in_order, true, 2, true);
  EXPECT_LT(put_in_order, kept_scattered);
}
TEST(AdaptiveGrid, ReusedGhostRowsMatchAFreshPlan3D) {
  std::int64_t reused = 0;
  reused_ghost_rows_match_a_fresh_plan<3>(reused, false);
  EXPECT_GT(reused, 0);
}

// An adaptation fills the ghosts of the blocks whose rows it built afresh, and keeps those of
// the blocks whose rows it copied (they and every leaf they read are unchanged): after each
// cycle of a moving front, every ghost equals what a full fill then gives, bitwise.
template <int Dim>
void ghosts_after_adaptation_are_filled() {
  gw::AdaptiveGrid<Dim> grid(front_grid<Dim>(false));
  const auto th = front_threshold();
  std::int64_t checked = 0, changes = 0;
  for (int cycle = 0; cycle < 6; ++cycle) {
    grid.sample(moving_front<Dim>(0.05 * cycle));
    grid.fill_ghosts();
    const auto counts = grid.adapt_cycle(th);
    changes += counts.refined + counts.coarsened;
    const auto after = snapshot(grid);
    grid.fill_ghosts();
    std::int64_t differing = 0;
    compare_with_snapshot(grid, after, [&](int f, std::size_t s, std::size_t p, double filled, double kept) {
      if (std::memcmp(&kept, &filled, sizeof(double)) != 0 && differing++ == 0)
        ADD_FAILURE() << "cycle " << cycle << " block " << s << " field " << f << " point " << p;
      ++checked;
    });
    EXPECT_EQ(differing, 0) << "cycle " << cycle;
  }
  EXPECT_GT(global_sum(checked), 0);
  EXPECT_GT(changes, 0) << "the front must move the grid";
}
TEST(AdaptiveGrid, GhostsAfterAdaptationAreFilled2D) { ghosts_after_adaptation_are_filled<2>(); }
TEST(AdaptiveGrid, GhostsAfterAdaptationAreFilled3D) { ghosts_after_adaptation_are_filled<3>(); }

// A time-stepping solver adapts by cycles: a coarsen pass, then a refine pass, on the same
// data. Two lone passes on data that does not change coarsen the safety zone the refine pass
// adds and refine it again, every cycle. A cycle's coarsen pass keeps the families whose parent
// its refine pass would refine, so once settled, a cycle leaves the grid as it is. The settled
// grid still reconstructs the field within C eps.
template <int Dim, class F>
void settled_cycle_changes_nothing(const gw::GridConfig<Dim>& c, double eps, F&& field) {
  gw::ThresholdConfig th;
  th.epsilon = eps;
  th.groups = {0, -1};
  auto sample = [&](const auto& x, std::span<double> v) { v[0] = field(x); v[1] = 0; };
  {
    gw::AdaptiveGrid<Dim> lone(c);
    lone.adapt_to_function(th, sample);
    const auto refined = lone.adapt(th, gw::AdaptPass::kRefine).refined;
    const auto coarsened = lone.adapt(th, gw::AdaptPass::kCoarsen).coarsened;
    if (root()) std::printf("%dD lone passes on unchanged data: %d refined, then %d coarsened\n", Dim, refined, coarsened);
    EXPECT_GT(refined, 0);  // the setting shows the churn the cycle avoids
    EXPECT_GT(coarsened, 0);
  }
  gw::AdaptiveGrid<Dim> grid(c);
  grid.adapt_to_function(th, sample);
  const auto lone_blocks = grid.global_blocks();
  const auto first = grid.adapt_cycle(th);
  for (int k = 0; k < 4; ++k) {
    const auto later = grid.adapt_cycle(th);
    EXPECT_EQ(later.refined, 0) << "cycle " << k + 2;
    EXPECT_EQ(later.coarsened, 0) << "cycle " << k + 2;
  }
  gw::AdaptiveGrid<Dim> uniform(grid);
  uniform.refine_to_uniform();
  const double error = max_error(uniform, 0, field, false, gw::GhostKind::kSameLevel);
  if (root())
    std::printf("%dD first cycle: %d refined, %d coarsened; blocks %zu (lone passes %zu); error %.3e = %.2f eps\n", Dim,
                first.refined, first.coarsened, grid.global_blocks(), lone_blocks, error, error / eps);
  EXPECT_GE(grid.global_blocks(), lone_blocks);
  EXPECT_LT(error, 2 * eps);
}
TEST(AdaptiveGrid, SettledCycleChangesNothing1D) {
  settled_cycle_changes_nothing<1>(unit_box<1>(false, 0, 9), 1e-4, front_1d);
}
TEST(AdaptiveGrid, SettledCycleChangesNothing2D) {
  settled_cycle_changes_nothing<2>(unit_box<2>(true, 1, 5), 1e-3, disc_2d);
}

// adapt_pass keeps the leaves each pass tests from one call to the next while the layout, the
// forced leaves and the adjacency stay the same. A layout change that keeps the leaf count (a
// family coarsened, another leaf refined) with no forced leaves must still find them again: a
// leaf below the finest level where a finest one was before must be tested, and refined where
// its field is significant, as on a grid built with that layout from the start.
TEST(AdaptiveGrid, TestedLeavesFollowALayoutOfTheSameSize) {
  const auto c = unit_box<2>(true, 1, 2);
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  th.adjacent_blocks = false;  // each leaf tested for its own tag only
  th.groups = {0, -1};
  gw::AdaptiveGrid<2> grid(c);
  ASSERT_EQ(grid.global_blocks(), 16u);
  std::vector<gw::AdaptTag> tags(16, gw::AdaptTag::kKeep);
  tags[0] = gw::AdaptTag::kRefine;
  grid.adapt_with_tags(tags);
  const std::vector<gw::BlockKey<2>> before(grid.forest().leaves().begin(), grid.forest().leaves().end());
  ASSERT_EQ(before.size(), 19u);
  // A refine pass on zero fields: nothing is significant, nothing changes, the tested leaves are
  // found for this layout.
  grid.fill_ghosts();
  EXPECT_EQ(grid.adapt(th, gw::AdaptPass::kRefine).refined, 0);
  // The first leaf's children coarsened, the last leaf refined: 19 leaves again.
  tags.assign(19, gw::AdaptTag::kKeep);
  for (std::size_t l = 0; l < 19; ++l)
    if (before[l].level == 2) tags[l] = gw::AdaptTag::kCoarsen;
  tags[18] = gw::AdaptTag::kRefine;
  grid.adapt_with_tags(tags);
  const std::vector<gw::BlockKey<2>> after(grid.forest().leaves().begin(), grid.forest().leaves().end());
  ASSERT_EQ(after.size(), 19u);
  // A leaf of level 1 now where the layout before had one of level 2 (which the refine pass did
  // not test): a sharp front inside it.
  std::size_t target = 19;
  for (std::size_t l = 0; l < 19 && target == 19; ++l)
    if (after[l].level == 1 && before[l].level == 2) target = l;
  ASSERT_LT(target, 19u);
  const auto lo = grid.origin(after[target]);
  const auto h = grid.spacing(1);
  const double centre = lo[0] + 0.5 * c.block_size * h[0];
  auto front = [&](const auto& x, std::span<double> v) {
    v[0] = std::tanh((x[0] - centre) / h[0]);
    v[1] = 0;
  };
  gw::AdaptiveGrid<2> fresh(c);
  fresh.rebuild(after);
  for (auto* g : {&grid, &fresh}) {
    g->sample(front);
    g->fill_ghosts();
  }
  const auto fresh_refined = fresh.adapt(th, gw::AdaptPass::kRefine).refined;
  EXPECT_GT(fresh_refined, 0);
  EXPECT_EQ(grid.adapt(th, gw::AdaptPass::kRefine).refined, fresh_refined);
  EXPECT_TRUE(std::equal(grid.forest().leaves().begin(), grid.forest().leaves().end(), fresh.forest().leaves().begin(),
                         fresh.forest().leaves().end()));
}

// field_scales reads the whole block array (ghosts too) only for the blocks whose range bound
// the tagging will try next; where the bound rests (it decided nothing on that block lately) the
// interiors alone give the scale and the range is left NaN. Where given, the range is the whole
// array's; either way the scale is the interiors' largest magnitude.
TEST(AdaptiveGrid, FieldScalesGiveRangesWhereTheBoundWillBeTried) {
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  th.groups = {0, -1};
  gw::AdaptiveGrid<2> grid(unit_box<2>(true, 1, 5));
  grid.adapt_to_function(th, [](const auto& x, std::span<double> v) { v[0] = disc_2d(x); v[1] = 0; });
  for (int k = 0; k < 3; ++k) grid.adapt_cycle(th);
  grid.fill_ghosts();
  std::vector<std::pair<double, double>> ranges;
  const auto scale = grid.field_scales(th, &ranges);
  EXPECT_EQ(scale, grid.field_scales(th));
  ASSERT_EQ(ranges.size(), 2 * grid.local_blocks());
  std::size_t given = 0, resting = 0;
  for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
    const auto [low, high] = ranges[s];  // field 0
    if (std::isnan(low)) {
      EXPECT_TRUE(std::isnan(high)) << "block " << s;
      ++resting;
      continue;
    }
    const auto u = grid.block(0, s);
    const auto [expected_low, expected_high] = gw::value_range(u.data(), u.size());
    EXPECT_EQ(low, expected_low) << "block " << s;
    EXPECT_EQ(high, expected_high) << "block " << s;
    ++given;
  }
  const auto all_given = global_sum(static_cast<std::int64_t>(given)), all_resting = global_sum(static_cast<std::int64_t>(resting));
  if (root()) std::printf("ranges given for %lld blocks, left out for %lld resting ones\n", static_cast<long long>(all_given), static_cast<long long>(all_resting));
  EXPECT_GT(all_given, 0);
  EXPECT_GT(all_resting, 0);
}

// The detail maxima field_scales takes ahead (for the fields each block's test computed last
// time, where its range bound rests) decide as the test's own would: a grid following two
// moving discs, cycle after cycle, against a copy made just before each cycle (a copy has no
// history, so its first pass takes nothing ahead). Leaves and values must come out the same.
TEST(AdaptiveGrid, MaximaTakenAheadDecideAsComputedOnes) {
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  gw::AdaptiveGrid<2> grid(unit_box<2>(true, 1, 5));
  auto discs_at = [](double shift) {
    return [shift](const std::array<double, 2>& x, std::span<double> v) {
      v[0] = disc_2d({x[0] - shift, x[1]});
      v[1] = 0.3 * disc_2d({x[1] + shift, 1.1 - x[0]});  // another disc, moving the other way
    };
  };
  grid.adapt_to_function(th, discs_at(0.0));
  std::int64_t changes = 0;
  for (int k = 1; k <= 10; ++k) {
    grid.sample(discs_at(0.015 * k));
    grid.fill_ghosts();
    gw::AdaptiveGrid<2> fresh(grid);
    const auto counts = grid.adapt_cycle(th);
    const auto fresh_counts = fresh.adapt_cycle(th);
    changes += counts.refined + counts.coarsened;
    ASSERT_EQ(counts.refined, fresh_counts.refined) << "cycle " << k;
    ASSERT_EQ(counts.coarsened, fresh_counts.coarsened) << "cycle " << k;
    ASSERT_TRUE(std::ranges::equal(grid.forest().leaves(), fresh.forest().leaves())) << "cycle " << k;
    for (int f = 0; f < 2; ++f)
      for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
        const auto a = grid.block(f, s), b = fresh.block(f, s);
        ASSERT_EQ(std::memcmp(a.data(), b.data(), a.size_bytes()), 0) << "cycle " << k << " field " << f << " block " << s;
      }
  }
  if (root()) std::printf("blocks refined or coarsened over the cycles: %lld\n", static_cast<long long>(changes));
  EXPECT_GT(changes, 0);  // the grid followed the discs
}

TEST(AdaptiveGrid, ForcedRegionSitsAtFinestLevel) {
  gw::AdaptiveGrid<2> grid(unit_box<2>(false, 0, 3));
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  auto region = [](const std::array<double, 2>& lo, const std::array<double, 2>& hi) {
    return lo[0] <= 0.3 && hi[0] >= 0.3 && lo[1] <= 0.6 && hi[1] >= 0.6;  // holds (0.3, 0.6)
  };
  grid.adapt_to_function(th, [](const auto&, std::span<double> v) { v[0] = 1; v[1] = 0; }, region);
  int found = 0;
  for (const auto& k : grid.forest().leaves()) {
    const auto lo = grid.origin(k);
    const double w = 8 * grid.spacing(k.level)[0];
    if (region(lo, {lo[0] + w, lo[1] + w})) {
      ++found;
      EXPECT_EQ(k.level, 3);
    }
  }
  EXPECT_GE(found, 1);
  EXPECT_TRUE(grid.forest().is_balanced());
  // A constant field has no significant coefficient: far from the region the grid is coarse.
  EXPECT_LT(grid.global_blocks(), 40u);
}

// Normalised L-infinity per field: a small-amplitude field refines as much as a large one when
// normalised separately, and not at all when grouped with the large one or judged absolutely.
TEST(AdaptiveGrid, GroupedAndSeparateNormalisation) {
  auto c = unit_box<2>(true, 1, 4);
  auto run = [&](gw::Normalisation norm, std::vector<int> groups, int field) {
    gw::AdaptiveGrid<2> grid(c);
    gw::ThresholdConfig th;
    th.epsilon = 1e-3;
    th.normalisation = norm;
    th.groups = std::move(groups);
    grid.adapt_to_function(th, [&](const auto& x, std::span<double> v) {
      v[0] = field == 0 ? disc_2d(x) : 0.0;
      v[1] = field == 1 ? 1e-4 * disc_2d(x) : 0.0;
      if (field == 2) {
        v[0] = disc_2d(x);
        v[1] = 1e-4 * std::exp(-(std::pow(x[0] - 0.15, 2) + std::pow(x[1] - 0.8, 2)) / 0.0025);
      }
    });
    return grid.global_blocks();
  };
  const auto big = run(gw::Normalisation::kLinf, {}, 0);
  const auto small_separate = run(gw::Normalisation::kLinf, {}, 1);
  const auto small_absolute = run(gw::Normalisation::kAbsolute, {}, 1);
  const auto both_separate = run(gw::Normalisation::kLinf, {0, 1}, 2);
  const auto both_grouped = run(gw::Normalisation::kLinf, {0, 0}, 2);
  if (root()) std::printf("blocks: big %zu, small separate %zu, small absolute %zu, two separate %zu, grouped %zu\n", big, small_separate, small_absolute, both_separate, both_grouped);
  EXPECT_EQ(big, small_separate);
  EXPECT_EQ(small_absolute, 16u);  // 1e-4 amplitude: nothing above 1e-3 absolute
  EXPECT_GT(both_separate, both_grouped);
}

// Derivatives at every active point of a mixed-level periodic grid (one-sided closures are
// tested in test_stencils.cpp), every level moved up by one. The scheme is the finite
// differences of order `accuracy` together with the ghosts a fine block predicts from a coarser
// neighbour, whose error is O(h^p) for ghost interpolation of order p, divided by h or h^2:
// orders min(accuracy, p - 1) and min(accuracy, p - 2). The field's phase keeps its fourth derivative
// (the predicted ghosts' leading error) away from zero at the level interfaces (x = 0, 1/2); a
// pure sine there hid that error and showed one order more.
template <int Dim>
void derivative_orders(int accuracy, int order, std::array<double, 2> expected, int ghost_order = 0) {
  std::array<std::array<double, 3>, 2> err{};
  auto u = [](const std::array<double, Dim>& x) {
    double v = 0;
    for (int a = 0; a < Dim; ++a) v += std::sin(2 * kPi * x[a] + 0.3 * a + 0.7) * (1 + 0.2 * a);
    return v;
  };
  auto du = [](const std::array<double, Dim>& x) { return 2 * kPi * std::cos(2 * kPi * x[0] + 0.7); };
  auto d2u = [](const std::array<double, Dim>& x) { return -4 * kPi * kPi * std::sin(2 * kPi * x[0] + 0.7); };
  for (int shift = 0; shift < 3; ++shift) {
    auto c = unit_box<Dim>(true, 1 + shift, 5, order);
    c.derivative_accuracy = accuracy;
    c.ghost_order = ghost_order;
    gw::AdaptiveGrid<Dim> grid(c);
    refine_left_half(grid);
    grid.sample([&](const auto& x, std::span<double> v) { v[0] = u(x); v[1] = 0; });
    grid.fill_ghosts();
    grid.first_derivative(0, 0, 1);
    err[0][static_cast<std::size_t>(shift)] = max_error(grid, 1, du, false, gw::GhostKind::kSameLevel);
    grid.second_derivative(0, 0, 1);
    err[1][static_cast<std::size_t>(shift)] = max_error(grid, 1, d2u, false, gw::GhostKind::kSameLevel);
  }
  for (int m = 0; m < 2; ++m) {
    // The last pair: the coarsest grid (16 points across) is not yet asymptotic.
    const double measured = std::log2(err[m][1] / err[m][2]);
    if (root()) std::printf("%dD d%d/dx%d, accuracy %d, interpolation %d, ghosts %d: errors %.3e %.3e %.3e, order %.2f\n", Dim, m + 1, m + 1, accuracy, order, ghost_order ? ghost_order : order, err[m][0], err[m][1], err[m][2], measured);
    EXPECT_NEAR(measured, expected[static_cast<std::size_t>(m)], 0.2) << "derivative " << m + 1;
  }
}
TEST(AdaptiveGrid, DerivativeOrders1D) {
  derivative_orders<1>(2, 4, {2, 2});
  derivative_orders<1>(4, 6, {4, 4});
  // 4th-order derivatives with 4th-order ghost interpolation are of order 3 for first and 2 for
  // second derivatives at coarse-fine interfaces (4 away from them); with 6th-order ghosts (the
  // fluid's default) and 4th-order wavelets, of order 4.
  derivative_orders<1>(4, 4, {3, 2});
  derivative_orders<1>(4, 4, {4, 4}, 6);
}
TEST(AdaptiveGrid, DerivativeOrders2D) {
  derivative_orders<2>(4, 6, {4, 4});
  derivative_orders<2>(4, 4, {3, 2});
  derivative_orders<2>(4, 4, {4, 4}, 6);
}

// The ghost interpolation order changes only odd ghosts, which no wavelet coefficient reads: grids
// adapted to the same field with 4th- and 6th-order ghosts have the same blocks, before and after
// adaptation cycles, while the derivatives next to level interfaces do differ.
TEST(AdaptiveGrid, GhostOrderLeavesThresholdingAlone) {
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  th.groups = {0, -1};
  auto sample = [](const auto& x, std::span<double> v) { v[0] = disc_2d(x); v[1] = 0; };
  std::vector<std::vector<gw::BlockKey<2>>> keys;
  std::vector<std::vector<double>> derivatives;
  for (const int ghost_order : {4, 6}) {
    auto c = unit_box<2>(false, 1, 4);
    c.ghost_order = ghost_order;
    gw::AdaptiveGrid<2> grid(c);
    grid.adapt_to_function(th, sample);
    for (int k = 0; k < 3; ++k) grid.adapt_cycle(th);
    keys.emplace_back();
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) keys.back().push_back(grid.key(s));
    grid.first_derivative(0, 0, 1);
    derivatives.emplace_back();
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
      const auto d = grid.block(1, s);
      derivatives.back().insert(derivatives.back().end(), d.begin(), d.end());
    }
  }
  EXPECT_EQ(keys[0], keys[1]);
  EXPECT_NE(derivatives[0], derivatives[1]);
}

TEST(AdaptiveGrid, RebuildFromLeavesReproducesTheForest) {
  gw::AdaptiveGrid<2> grid(unit_box<2>(true, 1, 4));
  gw::ThresholdConfig th;
  grid.adapt_to_function(th, [](const auto& x, std::span<double> v) { v[0] = disc_2d(x); v[1] = 0; });
  const std::vector<gw::BlockKey<2>> leaves(grid.forest().leaves().begin(), grid.forest().leaves().end());
  gw::AdaptiveGrid<2> other(unit_box<2>(true, 1, 4));
  other.rebuild(leaves);
  EXPECT_TRUE(std::equal(leaves.begin(), leaves.end(), other.forest().leaves().begin()));
  EXPECT_EQ(other.local_blocks(), grid.local_blocks());
  std::vector<gw::BlockKey<2>> broken(leaves.begin() + 1, leaves.end());
  EXPECT_THROW(other.rebuild(broken), std::invalid_argument);
}

// One root block on a periodic axis is its own neighbour: its ghosts are its own wrapped points.
TEST(AdaptiveGrid, SingleBlockPeriodicGhostsWrap) {
  gw::GridConfig<2> c = unit_box<2>(true, 0, 2);
  c.roots = {1, 1};
  gw::AdaptiveGrid<2> grid(c);
  ASSERT_EQ(grid.global_blocks(), 1u);
  auto field = [](const std::array<double, 2>& x) { return std::sin(2 * kPi * x[0]) * std::cos(2 * kPi * x[1]); };
  grid.sample([&](const auto& x, std::span<double> v) { v[0] = field(x); v[1] = 0; });
  grid.fill_ghosts();
  EXPECT_EQ(global_sum(grid.ghost_counts()[0]), static_cast<std::int64_t>(grid.layout().shape().size() - 64));
  EXPECT_LT(max_error(grid, 0, field, true, gw::GhostKind::kSameLevel), 1e-14);
}

namespace {

/// The tagging kernel (fixed centred offsets, one-sided rows from their stencils, AVX2 or AVX-512F where
/// available) against the general separable prediction: on adapted grids with bounded and
/// periodic edges, every block's largest coefficient is bitwise the largest |block_details|.
/// Block sizes 8 and 16 in 2D: on AVX-512F CPUs rows of 16 or more take eight lanes at a time.
template <int Dim>
void largest_details_match_block_details(bool periodic, int order, int block_size = 8) {
  auto c = unit_box<Dim>(periodic, 1, Dim == 3 ? 2 : block_size == 8 ? 4 : 3, order);
  c.block_size = block_size;
  gw::AdaptiveGrid<Dim> grid(c);
  gw::ThresholdConfig th;
  th.epsilon = 1e-3;
  grid.adapt_to_function(th, [](const auto& x, std::span<double> v) {
    double r2 = 0, s = 0;
    for (int a = 0; a < Dim; ++a) {
      r2 += (x[a] - 0.4) * (x[a] - 0.4);
      s += std::sin(3 * x[a] + a);
    }
    v[0] = std::tanh((std::sqrt(r2) - 0.25) / 0.04);
    v[1] = s;
  });
  grid.fill_ghosts();
  std::vector<double> d(grid.points_per_block());
  long compared = 0;
  for (std::size_t slot = 0; slot < grid.local_blocks(); ++slot)
    for (int f = 0; f < 2; ++f) {
      grid.block_details(f, slot, d);
      double largest = 0;
      for (const double v : d) largest = std::max(largest, std::abs(v));
      const gw::DetailMaxima found = grid.largest_details(f, slot);
      ASSERT_EQ(found.largest, largest) << "block " << slot << " field " << f;
      EXPECT_LE(found.largest_near, found.largest);
      const auto u = grid.block(f, slot);
      ASSERT_EQ(found.magnitude, gw::interior_largest_magnitude(u.data(), Dim, c.block_size, grid.layout().ghosts))
          << "block " << slot << " field " << f;
      ++compared;
    }
  EXPECT_GT(compared, 0);
}

}  // namespace

TEST(AdaptiveGrid, LargestDetailsMatchBlockDetails1D) {
  for (const bool periodic : {false, true})
    for (const int order : {4, 6}) largest_details_match_block_details<1>(periodic, order);
}
TEST(AdaptiveGrid, LargestDetailsMatchBlockDetails2D) {
  for (const bool periodic : {false, true})
    for (const int order : {4, 6})
      for (const int block_size : {8, 16}) largest_details_match_block_details<2>(periodic, order, block_size);
}
TEST(AdaptiveGrid, LargestDetailsMatchBlockDetails3D) {
  for (const int order : {4, 6}) largest_details_match_block_details<3>(false, order);
}

// Hysteresis: with coarsen_fraction c < 1 a coarsen pass keeps every block whose largest
// coefficient lies above c * epsilon, blocks that a single threshold (c = 1) coarsens.
TEST(AdaptiveGrid, CoarsenFractionKeepsBlocksInTheHysteresisBand) {
  constexpr double kTwoPi = 2 * std::numbers::pi;
  auto sample = [&](const auto& x, std::span<double> v) {
    v[0] = std::sin(kTwoPi * x[0]) * std::sin(2 * kTwoPi * x[1]) + 0.3 * std::cos(3 * kTwoPi * x[0]);
    v[1] = 0;
  };
  gw::AdaptiveGrid<2> fine(unit_box<2>(true, 0, 3));
  fine.refine_to_uniform();
  fine.sample(sample);
  fine.fill_ghosts();
  double largest = 0;
  for (std::size_t s = 0; s < fine.local_blocks(); ++s) largest = std::max(largest, fine.largest_details(0, s).largest);
  largest = global_max(largest);
  ASSERT_GT(largest, 0);
  gw::ThresholdConfig th;
  th.normalisation = gw::Normalisation::kAbsolute;
  th.epsilon = 1.2 * largest;  // every block below epsilon: one threshold coarsens them all
  const double fraction = 0.5;
  std::vector<gw::BlockKey<2>> in_band;  // above fraction * epsilon: kept by the hysteresis
  for (std::size_t s = 0; s < fine.local_blocks(); ++s)
    if (fine.largest_details(0, s).largest > fraction * th.epsilon) in_band.push_back(fine.key(s));
  ASSERT_GT(global_sum(static_cast<std::int64_t>(in_band.size())), 0);

  gw::AdaptiveGrid<2> single(fine), hysteresis(fine);
  single.adapt(th, gw::AdaptPass::kCoarsen);
  th.coarsen_fraction = fraction;
  hysteresis.adapt(th, gw::AdaptPass::kCoarsen);
  EXPECT_LT(single.global_blocks(), fine.global_blocks());
  EXPECT_GT(hysteresis.global_blocks(), single.global_blocks());
  for (const auto& key : in_band) EXPECT_TRUE(hysteresis.forest().find(key).has_value()) << "a block in the band coarsened";
}

/// Calls check(dim, bs, g, u) for block arrays of 1 to 3 axes, with the block sizes the kernels
/// are compiled for (8, 16, 32) and a general one (10), g = 3: u holds sin-like values.
template <class Check>
void for_each_block_array(double frequency, Check&& check) {
  for (const int dim : {1, 2, 3})
    for (const int bs : {8, 10, 16, 32}) {
      if (dim == 3 && bs == 32) continue;
      const int g = 3, w = bs + 2 * g;
      const std::size_t volume = static_cast<std::size_t>(std::pow(w, dim));
      std::vector<double> u(volume);
      for (std::size_t p = 0; p < volume; ++p)
        u[p] =
            std::sin(frequency * static_cast<double>(p)) * (1 + 1e-3 * static_cast<double>(p % 7));
      check(dim, bs, g, u);
    }
}

// Which points of a block array (dim axes, bs interior points and g ghost layers per side) are
// interior ones, and the largest |u| over them by a plain loop (NaNs passed over).
std::vector<char> interior_points(int dim, int bs, int g) {
  const int w = bs + 2 * g;
  const auto volume = static_cast<std::size_t>(std::pow(w, dim));
  std::vector<char> interior(volume, 1);
  for (std::size_t p = 0; p < volume; ++p) {
    std::size_t rest = p;
    for (int a = 0; a < dim; ++a) {
      const int i = static_cast<int>(rest % static_cast<std::size_t>(w));
      rest /= static_cast<std::size_t>(w);
      if (i < g || i >= g + bs) interior[p] = 0;
    }
  }
  return interior;
}
double plain_interior_magnitude(const std::vector<double>& u, const std::vector<char>& interior) {
  double largest = 0;
  for (std::size_t p = 0; p < u.size(); ++p)
    if (interior[p] && !std::isnan(u[p])) largest = std::max(largest, std::abs(u[p]));
  return largest;
}

// The linf scale's kernel (compiled for block sizes 8, 16 and 32, general otherwise) against a
// plain loop over the interior points: the same maximum, ghosts never read, NaNs passed over.
TEST(DetailKernels, InteriorLargestMagnitudeMatchesPlainLoop) {
  for_each_block_array(0.37, [](int dim, int bs, int g, std::vector<double>& u) {
    const auto interior = interior_points(dim, bs, g);
    for (std::size_t p = 0; p < u.size(); ++p)
      if (!interior[p]) u[p] = 1e3;  // a ghost: never read
    const auto first_interior =
        static_cast<std::size_t>(std::find(interior.begin(), interior.end(), 1) - interior.begin());
    u[first_interior] = std::numeric_limits<double>::quiet_NaN();  // passed over
    EXPECT_EQ(gw::interior_largest_magnitude(u.data(), dim, bs, g), plain_interior_magnitude(u, interior))
        << "dim " << dim << " bs " << bs;
  });
}

// The extent the tagging reads (field_scales hands its ranges to the range bound), and
// value_range, which takes the range the same way, against extremes placed in the array and a
// plain loop (a zero's sign aside, which EXPECT_EQ does not tell apart and the tagging never
// reads): the range of the whole array (ghosts included, NaNs passed over, a NaN first value
// kept) and the interior's largest magnitude, for the sizes compiled apart and a general one. The
// extremes are moved through the array (the first and last 64 positions and every 37th), so
// each group of lanes and the overlapping last one decides them somewhere.
TEST(DetailKernels, BlockExtentIsValueRangeAndInteriorMagnitude) {
  for_each_block_array(0.91, [](int dim, int bs, int g, std::vector<double>& u) {
    const std::size_t volume = u.size(), skipped = volume / 2 + 1;
    u[skipped] = std::numeric_limits<double>::quiet_NaN();  // passed over
    const auto interior = interior_points(dim, bs, g);
    for (std::size_t p = 0; p < volume; ++p) {
      if (!(p < 64 || p + 64 >= volume || p % 37 == 0) || p == skipped) continue;
      const std::size_t q = (p * 7 + 3) % volume == skipped || (p * 7 + 3) % volume == p ? (p + 1) % volume : (p * 7 + 3) % volume;
      if (q == skipped) continue;
      const double at_p = u[p], at_q = u[q];
      u[p] = -7.5;
      u[q] = 9.25;
      const auto extent = gw::block_extent(u.data(), dim, bs, g);
      const auto [low, high] = gw::value_range(u.data(), volume);
      EXPECT_EQ(extent.low, -7.5) << "dim " << dim << " bs " << bs << " at " << p;
      EXPECT_EQ(extent.high, 9.25) << "dim " << dim << " bs " << bs << " at " << q;
      EXPECT_EQ(low, -7.5);
      EXPECT_EQ(high, 9.25);
      EXPECT_EQ(extent.interior_magnitude, plain_interior_magnitude(u, interior)) << "dim " << dim << " bs " << bs << " at " << p << ", " << q;
      u[p] = at_p;
      u[q] = at_q;
    }
    u[0] = std::numeric_limits<double>::quiet_NaN();  // a NaN first value stays, in both
    const auto first_nan = gw::block_extent(u.data(), dim, bs, g);
    EXPECT_TRUE(std::isnan(first_nan.low) && std::isnan(gw::value_range(u.data(), volume).first));
  });
}
