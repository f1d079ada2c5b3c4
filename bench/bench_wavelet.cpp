// Throughput of wavelet/: lifting forward + inverse transform and the 4th-order derivative
// operator on single blocks (points per second), and on the adaptive grid (one rank) the
// wavelet coefficients of all blocks, the ghost fill and the adapt cycle (tag -> refine/coarsen -> balance -> repartition -> ghost plan),
// reported as blocks per second (counter `blocks_per_s`; its inverse is the time per block), in
// 2D and 3D.
#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/DetailKernels.hpp"
#include "wavelet/InterpolatingWavelet.hpp"
#include "wavelet/Stencils.hpp"

#include <benchmark/benchmark.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace gw = grainwave::wavelet;

namespace {

// Args: points per axis (non-periodic, 2^k + 1), DD order, update (0/1), levels.
template <int Dim>
void BM_LiftingForwardInverse(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::array<int, Dim> extent{};
  extent.fill(n);
  const gw::LiftingTransform<Dim> transform(
      extent, std::array<bool, Dim>{},
      {static_cast<int>(state.range(1)), state.range(2) != 0, static_cast<int>(state.range(3))});
  std::vector<double> data(transform.shape().size());
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = std::sin(0.01 * static_cast<double>(i));
  for (auto _ : state) {
    transform.forward(data);
    transform.inverse(data);
    benchmark::DoNotOptimize(data.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(data.size()));
}

// Args: interior points per axis. Ghosts 2, 4th order, central rows everywhere.
template <int Dim>
void BM_FirstDerivativeAllAxes(benchmark::State& state) {
  gw::BlockLayout<Dim> layout;
  layout.interior.fill(static_cast<int>(state.range(0)));
  layout.ghosts = 2;
  std::array<double, Dim> h{};
  h.fill(0.01);
  const gw::DerivativeOperator<Dim> op(layout, h, {});
  std::vector<double> u(layout.shape().size()), du(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = std::sin(0.01 * static_cast<double>(i));
  for (auto _ : state) {
    for (int a = 0; a < Dim; ++a) op.first(u, du, a);
    benchmark::DoNotOptimize(du.data());
    benchmark::ClobberMemory();
  }
  std::int64_t points = 1;
  for (int c : layout.interior) points *= c;
  state.SetItemsProcessed(state.iterations() * points);  // point-gradients per second
}

}  // namespace

BENCHMARK(BM_LiftingForwardInverse<2>)
    ->ArgNames({"n", "order", "update", "levels"})
    ->Args({17, 4, 0, 2})
    ->Args({17, 4, 1, 2})
    ->Args({33, 4, 0, 3})
    ->Args({33, 6, 0, 2})
    ->Args({33, 6, 1, 2});
BENCHMARK(BM_LiftingForwardInverse<3>)
    ->ArgNames({"n", "order", "update", "levels"})
    ->Args({17, 4, 0, 2})
    ->Args({17, 4, 1, 2})
    ->Args({33, 4, 0, 3})
    ->Args({33, 6, 0, 2})
    ->Args({33, 6, 1, 2});
BENCHMARK(BM_FirstDerivativeAllAxes<2>)->ArgName("n")->Arg(16)->Arg(32);
BENCHMARK(BM_FirstDerivativeAllAxes<3>)->ArgName("n")->Arg(16)->Arg(32);

namespace {

/// A disc (2D) or sphere (3D) interface on a periodic unit box, adapted to eps = 1e-3 (2D) or
/// 1e-2 (3D, to keep the grid small).
template <int Dim>
gw::AdaptiveGrid<Dim> disc_grid(int max_level, int block_size = 8) {
  gw::GridConfig<Dim> c;
  c.block_size = block_size;
  c.lo.fill(0.0);
  c.hi.fill(1.0);
  c.roots.fill(1);
  c.periodic.fill(true);
  c.max_level = max_level;
  c.fields = {"u", "v"};
  gw::AdaptiveGrid<Dim> grid(c);
  gw::ThresholdConfig th;
  th.epsilon = Dim == 3 ? 1e-2 : 1e-3;
  grid.adapt_to_function(th, [](const auto& x, std::span<double> v) {
    double r2 = 0;
    for (int a = 0; a < Dim; ++a) r2 += (x[a] - 0.5) * (x[a] - 0.5);
    v[0] = 0.5 * (1 - std::tanh((std::sqrt(r2) - 0.25) / 0.03));
    v[1] = x[0];
  });
  return grid;
}

// The grid's forward transform: the wavelet coefficients of every point of every block (ghosts
// filled), as the significance test computes them.
template <int Dim>
void BM_BlockCoefficients(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)));
  std::vector<double> d(grid.points_per_block());
  for (auto _ : state) {
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) grid.block_details(0, s, d);
    benchmark::DoNotOptimize(d.data());
  }
  state.counters["blocks"] = static_cast<double>(grid.global_blocks());
  state.counters["blocks_per_s"] = benchmark::Counter(static_cast<double>(grid.global_blocks()),
                                                      benchmark::Counter::kIsIterationInvariantRate);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(grid.global_blocks() * grid.points_per_block()));
}

// The tagging's kernel: the largest coefficient (and the largest near one) of every block, what
// block_significance computes per field when the range bound decides nothing.
template <int Dim>
void BM_LargestDetails(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  double sum = 0;
  for (auto _ : state)
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) sum += grid.largest_details(0, s).largest;
  benchmark::DoNotOptimize(sum);
  state.counters["blocks"] = static_cast<double>(grid.global_blocks());
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(grid.global_blocks() * grid.points_per_block()));
}

// The range bound's kernel: every block's range of values (ghosts included) and interior
// magnitude, what field_scales computes per field for each block whose bound is tried.
template <int Dim>
void BM_BlockExtent(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const auto& config = grid.config();
  double sum = 0;
  for (auto _ : state)
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
      const auto e = gw::block_extent(grid.block(0, s).data(), Dim, config.block_size, grid.layout().ghosts);
      sum += e.high - e.low + e.interior_magnitude;
    }
  benchmark::DoNotOptimize(sum);
  state.counters["blocks"] = static_cast<double>(grid.global_blocks());
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(grid.global_blocks() * grid.points_per_block()));
}

template <int Dim>
void BM_GhostFill(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)));
  for (auto _ : state) grid.fill_ghosts();
  const double blocks = static_cast<double>(grid.global_blocks());
  state.counters["blocks"] = blocks;
  state.counters["blocks_per_s"] = benchmark::Counter(blocks, benchmark::Counter::kIsIterationInvariantRate);
  // What a fill computes (copies, weighted terms, the separable prolongation's scratch points).
  const auto plan = grid.ghost_plan_stats();
  state.counters["copies"] = static_cast<double>(plan.copies);
  state.counters["terms"] = static_cast<double>(plan.weighted_terms);
  state.counters["scratch"] = static_cast<double>(plan.scratch_points);
  state.counters["longest_row"] = plan.longest_row;
}

// The full cycle with data moving: refine every block at the coarsest level present (tag,
// refine, balance, predict the children, repartition, rebuild the ghost plan, fill ghosts), then
// coarsen those children back (injection). Time per block of the grid per adapt call.
template <int Dim>
void BM_AdaptCycle(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)));
  int coarsest = grid.config().max_level;
  for (const auto& k : grid.forest().leaves()) coarsest = std::min(coarsest, k.level);
  std::vector<gw::BlockKey<Dim>> refined;
  std::vector<gw::AdaptTag> tags;
  for (auto _ : state) {
    refined.clear();
    tags.assign(grid.global_blocks(), gw::AdaptTag::kKeep);
    for (std::size_t l = 0; l < tags.size(); ++l)
      if (grid.forest().leaves()[l].level == coarsest) {
        tags[l] = gw::AdaptTag::kRefine;
        refined.push_back(grid.forest().leaves()[l]);
      }
    grid.adapt_with_tags(tags);
    tags.assign(grid.global_blocks(), gw::AdaptTag::kKeep);
    for (std::size_t l = 0; l < tags.size(); ++l) {
      const auto& k = grid.forest().leaves()[l];
      if (k.level == coarsest + 1 && std::find(refined.begin(), refined.end(), k.parent()) != refined.end())
        tags[l] = gw::AdaptTag::kCoarsen;
    }
    grid.adapt_with_tags(tags);
  }
  const double blocks = static_cast<double>(grid.global_blocks());
  state.counters["blocks"] = blocks;
  state.counters["refined"] = static_cast<double>(refined.size());
  state.counters["blocks_per_s"] = benchmark::Counter(2 * blocks, benchmark::Counter::kIsIterationInvariantRate);
}

// A ghost plan built afresh for every block (what a changing cycle pays for the blocks around
// a change): the disc grid's leaves rebuilt, fields zeroed, plan resolved point by point where
// levels meet. Time per block.
template <int Dim>
void BM_GhostPlanBuild(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const std::vector<gw::BlockKey<Dim>> leaves(grid.forest().leaves().begin(), grid.forest().leaves().end());
  for (auto _ : state) grid.rebuild(leaves);
  const double blocks = static_cast<double>(grid.global_blocks());
  state.counters["blocks"] = blocks;
  state.counters["blocks_per_s"] = benchmark::Counter(blocks, benchmark::Counter::kIsIterationInvariantRate);
}

// What a moving grid's changing cycle costs when it changes little (most blocks reused): one
// leaf in the middle of the curve refined, then its children coarsened back, on the disc grid.
// Time per change (two per iteration), most of it the ghost plan's rebuild and the blocks'
// storage for the leaves that did not change.
template <int Dim>
void BM_ChangingAdaptCycle(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  using Key = gw::BlockKey<Dim>;
  const auto start = grid.forest().leaves();
  // The leaf nearest the middle of the curve that can be refined.
  std::size_t pick = start.size();
  for (std::size_t d = 0; d < start.size() && pick == start.size(); ++d)
    for (const std::size_t l : {start.size() / 2 + d, start.size() / 2 - d})
      if (l < start.size() && start[l].level < static_cast<int>(state.range(0)) && pick == start.size()) pick = l;
  const Key chosen = start[pick];
  std::vector<gw::AdaptTag> tags;
  for (auto _ : state) {
    const auto leaves = grid.forest().leaves();
    tags.assign(leaves.size(), gw::AdaptTag::kKeep);
    tags[static_cast<std::size_t>(std::find(leaves.begin(), leaves.end(), chosen) - leaves.begin())] = gw::AdaptTag::kRefine;
    grid.adapt_with_tags(tags);
    const auto refined = grid.forest().leaves();
    tags.assign(refined.size(), gw::AdaptTag::kKeep);
    for (std::size_t l = 0; l < refined.size(); ++l)
      if (refined[l].level == chosen.level + 1 && refined[l].morton >> Dim == chosen.morton) tags[l] = gw::AdaptTag::kCoarsen;
    grid.adapt_with_tags(tags);
  }
  if (grid.forest().leaves().size() != start.size()) state.SkipWithError("the leaf set did not come back");
  state.counters["blocks"] = static_cast<double>(grid.global_blocks());
  state.counters["changes_per_s"] = benchmark::Counter(2.0, benchmark::Counter::kIsIterationInvariantRate);
}

// What a time-stepping solver pays per step once its grid has settled: one adapt_cycle (coarsen
// and refine passes with their tagging, nothing to change) on the disc grid, its safety zone in.
template <int Dim>
void BM_SettledAdaptCycle(benchmark::State& state) {
  auto grid = disc_grid<Dim>(static_cast<int>(state.range(0)));
  gw::ThresholdConfig th;
  th.epsilon = Dim == 3 ? 1e-2 : 1e-3;
  for (int k = 0; k < 10; ++k) {
    const auto counts = grid.adapt_cycle(th);
    if (counts.refined + counts.coarsened == 0) break;
  }
  int changes = 0;
  for (auto _ : state) {
    const auto counts = grid.adapt_cycle(th);
    changes += counts.refined + counts.coarsened;
  }
  state.counters["blocks"] = static_cast<double>(grid.global_blocks());
  state.counters["changes"] = changes;
  state.counters["blocks_per_s"] =
      benchmark::Counter(static_cast<double>(grid.global_blocks()), benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

BENCHMARK(BM_BlockCoefficients<2>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlockCoefficients<3>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LargestDetails<2>)->ArgNames({"max_level", "bs"})->Args({4, 8})->Args({3, 16})->Args({2, 32})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LargestDetails<3>)->ArgNames({"max_level", "bs"})->Args({4, 8})->Args({3, 16})->Args({2, 32})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlockExtent<2>)->ArgNames({"max_level", "bs"})->Args({4, 8})->Args({3, 16})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlockExtent<3>)->ArgNames({"max_level", "bs"})->Args({3, 8})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GhostFill<2>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GhostFill<3>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AdaptCycle<2>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AdaptCycle<3>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK(BM_GhostPlanBuild<2>)->ArgNames({"max_level", "bs"})->Args({4, 8})->Args({4, 16})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GhostPlanBuild<3>)->ArgNames({"max_level", "bs"})->Args({3, 8})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ChangingAdaptCycle<2>)->ArgNames({"max_level", "bs"})->Args({5, 8})->Args({4, 16})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SettledAdaptCycle<2>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SettledAdaptCycle<3>)->ArgName("max_level")->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(3);

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);  // the adaptive grid distributes over MPI_COMM_WORLD
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  MPI_Finalize();
  return 0;
}
