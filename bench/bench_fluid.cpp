// Throughput of the fluid right-hand side on one block (items = point-RHS evaluations per
// second): primitives over the block with ghosts, then the flux-form split convection along every
// axis with the shock sensor, dissipation, sixth-difference background dissipation and positivity
// check (the solver's default), and for Navier-Stokes the viscous and heat-conduction terms, in
// 1D, 2D and 3D. Arguments: block size, shock capturing (sensor, both dissipations) and
// positivity check on (1) or off (0). Whole runs, with ghosts, adaptation and time stepping,
// report point_rhs_per_s in summary.json (bench/adapt_cost.py prints it).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "fluid/BlockKernels.hpp"
#include "fluid/IdealGas.hpp"
#include "fluid/SplitConvection.hpp"
#include "fluid/ViscousTerms.hpp"
#include "wavelet/ArrayShape.hpp"

namespace gf = grainwave::fluid;

namespace {

template <int Dim, bool kViscous>
void fluid_rhs_block(benchmark::State& state) {
  constexpr int kFields = Dim + 2;
  const int bs = static_cast<int>(state.range(0)), g = kViscous ? std::max(gf::kViscousReach, gf::kStencilReach) : gf::kStencilReach;
  const bool capturing = state.range(1) != 0;
  grainwave::wavelet::ArrayShape<Dim> shape;
  shape.extent.fill(bs + 2 * g);
  const std::size_t volume = shape.size();
  std::array<std::vector<double>, kFields> q;
  for (auto& f : q) f.resize(volume);
  for (std::size_t at = 0; at < volume; ++at) {
    gf::Primitive<Dim> w;
    w.rho = 1 + 0.1 * std::sin(0.1 * static_cast<double>(at));
    for (auto& u : w.u) u = 0.2 * std::cos(0.07 * static_cast<double>(at));
    w.p = 0.7 + 0.05 * std::sin(0.13 * static_cast<double>(at));
    const auto c = gf::to_conserved(w, 1.4);
    for (int f = 0; f < kFields; ++f) q[static_cast<std::size_t>(f)][at] = c[static_cast<std::size_t>(f)];
  }
  std::vector<double> rho(volume), p(volume), e(volume);
  std::array<std::vector<double>, Dim> u;
  for (auto& v : u) v.resize(volume);
  std::size_t points = 1;
  for (int a = 0; a < Dim; ++a) points *= static_cast<std::size_t>(bs);
  std::vector<double> out(points * kFields);
  gf::BlockScratch<Dim> scratch(volume);
  gf::BlockPrimitives<Dim> w{rho.data(), {}, p.data(), e.data()};
  for (int a = 0; a < Dim; ++a) w.u[static_cast<std::size_t>(a)] = u[static_cast<std::size_t>(a)].data();
  std::array<const double*, kFields> qp{};
  for (int f = 0; f < kFields; ++f) qp[static_cast<std::size_t>(f)] = q[static_cast<std::size_t>(f)].data();
  std::array<double*, Dim> u_out{};
  for (int a = 0; a < Dim; ++a) u_out[static_cast<std::size_t>(a)] = u[static_cast<std::size_t>(a)].data();
  gf::InviscidSettings settings;
  settings.capturing = capturing;
  settings.coefficient = 1.2;
  settings.threshold = 1e-3;
  settings.background = capturing ? 1.0 / 256 : 0.0;  // the background dissipation goes with capturing
  settings.limiter_dt = capturing ? 0.4 * 0.01 / 2 : 0.0;  // a CFL-0.4 step's check (it limits nothing here)
  std::array<double, Dim> h{};
  h.fill(0.01);
  // Viscous scratch, as the solver holds it.
  std::array<std::array<std::vector<double>, Dim>, Dim> gradient;
  std::vector<double> temperature(volume), mu(volume), kinetic(volume);
  std::array<std::vector<double>, Dim + 1> flux;
  gf::ViscousBlock<Dim> block;
  for (std::size_t i = 0; i < static_cast<std::size_t>(Dim); ++i) {
    block.u[i] = u[i].data();
    for (std::size_t a = 0; a < static_cast<std::size_t>(Dim); ++a) {
      gradient[i][a].resize(volume);
      block.gradient[i][a] = gradient[i][a].data();
    }
  }
  for (std::size_t f = 0; f <= static_cast<std::size_t>(Dim); ++f) {
    flux[f].resize(volume);
    block.flux[f] = flux[f].data();
  }
  block.rho = rho.data();
  block.p = p.data();
  block.temperature = temperature.data();
  block.mu = mu.data();
  block.kinetic = kinetic.data();
  const gf::ViscousSettings viscous{1.4, 1000.0, 0.72, 110.4 / 300.0};
  for (auto _ : state) {
    gf::primitives<Dim>(qp, volume, 1.4, rho.data(), u_out, e.data(), p.data());
    gf::block_inviscid<Dim>(shape, g, bs, w, qp, h, settings, scratch, out.data());
    if constexpr (kViscous) gf::block_viscous<Dim>(shape, g, bs, h, viscous, block, out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(points));
}

template <int Dim>
void BM_EulerRhsBlock(benchmark::State& state) {
  fluid_rhs_block<Dim, false>(state);
}
template <int Dim>
void BM_NavierStokesRhsBlock(benchmark::State& state) {
  fluid_rhs_block<Dim, true>(state);
}

}  // namespace

BENCHMARK_TEMPLATE(BM_EulerRhsBlock, 1)->Args({16, 0})->Args({16, 1});
BENCHMARK_TEMPLATE(BM_EulerRhsBlock, 2)->Args({16, 0})->Args({16, 1})->Args({32, 1});
BENCHMARK_TEMPLATE(BM_EulerRhsBlock, 3)->Args({16, 0})->Args({16, 1});
BENCHMARK_TEMPLATE(BM_NavierStokesRhsBlock, 1)->Args({16, 1});
BENCHMARK_TEMPLATE(BM_NavierStokesRhsBlock, 2)->Args({16, 1})->Args({32, 1});
BENCHMARK_TEMPLATE(BM_NavierStokesRhsBlock, 3)->Args({16, 1});
BENCHMARK_MAIN();
