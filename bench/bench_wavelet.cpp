// Throughput of the block kernels of wavelet/: lifting forward + inverse transform and the
// 4th-order derivative operator, on single blocks of typical sizes (points per second).
#include "wavelet/InterpolatingWavelet.hpp"
#include "wavelet/Stencils.hpp"

#include <benchmark/benchmark.h>

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

BENCHMARK_MAIN();
