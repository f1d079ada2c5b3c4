#pragma once
// The per-block right-hand-side kernels (SplitConvection.hpp, ViscousTerms.hpp) compiled once per
// instruction set: AVX-512F or AVX2 where the CPU has it, the baseline (SSE2) otherwise, chosen
// at load time (GCC function multiversioning, target_clones). Without FMA (-ffp-contract=off,
// fluid/CMakeLists.txt): every version does the same roundings in the same order, so results
// are bitwise the same on any x86-64 machine. (The 512-bit clones, 2D and 3D only: bench_fluid's
// 2D Navier-Stokes on 16^2 blocks went from 19.7 to 22.8 M point-RHS/s on an AVX-512 Xeon,
// medians of five alternating runs.)
#include <array>

#include "fluid/SplitConvection.hpp"
#include "fluid/ViscousTerms.hpp"

namespace grainwave::fluid {

long block_inviscid_1d(const wavelet::ArrayShape<1>& shape, int g, int n, const BlockPrimitives<1>& w,
                       const std::array<const double*, 3>& q, const std::array<double, 1>& h,
                       const InviscidSettings& settings, BlockScratch<1>& scratch, double* out);
long block_inviscid_2d(const wavelet::ArrayShape<2>& shape, int g, int n, const BlockPrimitives<2>& w,
                       const std::array<const double*, 4>& q, const std::array<double, 2>& h,
                       const InviscidSettings& settings, BlockScratch<2>& scratch, double* out);
long block_inviscid_3d(const wavelet::ArrayShape<3>& shape, int g, int n, const BlockPrimitives<3>& w,
                       const std::array<const double*, 5>& q, const std::array<double, 3>& h,
                       const InviscidSettings& settings, BlockScratch<3>& scratch, double* out);
void block_viscous_1d(const wavelet::ArrayShape<1>& shape, int g, int n, const std::array<double, 1>& h,
                      const ViscousSettings& settings, const ViscousBlock<1>& block, double* out);
void block_viscous_2d(const wavelet::ArrayShape<2>& shape, int g, int n, const std::array<double, 2>& h,
                      const ViscousSettings& settings, const ViscousBlock<2>& block, double* out);
void block_viscous_3d(const wavelet::ArrayShape<3>& shape, int g, int n, const std::array<double, 3>& h,
                      const ViscousSettings& settings, const ViscousBlock<3>& block, double* out);

void primitives_1d(const std::array<const double*, 3>& q, std::size_t volume, double gamma, double* rho,
                   const std::array<double*, 1>& u, double* e, double* p);
void primitives_2d(const std::array<const double*, 4>& q, std::size_t volume, double gamma, double* rho,
                   const std::array<double*, 2>& u, double* e, double* p);
void primitives_3d(const std::array<const double*, 5>& q, std::size_t volume, double gamma, double* rho,
                   const std::array<double*, 3>& u, double* e, double* p);
double max_rate_1d(const wavelet::ArrayShape<1>& shape, int g, int n, const std::array<const double*, 3>& q,
                   const std::array<double, 1>& h, const StableRateSettings& settings, double* row);
double max_rate_2d(const wavelet::ArrayShape<2>& shape, int g, int n, const std::array<const double*, 4>& q,
                   const std::array<double, 2>& h, const StableRateSettings& settings, double* row);
double max_rate_3d(const wavelet::ArrayShape<3>& shape, int g, int n, const std::array<const double*, 5>& q,
                   const std::array<double, 3>& h, const StableRateSettings& settings, double* row);

/// block_primitives<Dim>, dispatched to the instruction set at hand.
template <int Dim>
inline void primitives(const std::array<const double*, Dim + 2>& q, std::size_t volume, double gamma, double* rho,
                       const std::array<double*, Dim>& u, double* e, double* p) {
  if constexpr (Dim == 1) primitives_1d(q, volume, gamma, rho, u, e, p);
  else if constexpr (Dim == 2) primitives_2d(q, volume, gamma, rho, u, e, p);
  else primitives_3d(q, volume, gamma, rho, u, e, p);
}

/// block_max_rate<Dim>, dispatched to the instruction set at hand.
template <int Dim>
inline double max_rate(const wavelet::ArrayShape<Dim>& shape, int g, int n, const std::array<const double*, Dim + 2>& q,
                       const std::array<double, Dim>& h, const StableRateSettings& settings, double* row) {
  if constexpr (Dim == 1) return max_rate_1d(shape, g, n, q, h, settings, row);
  else if constexpr (Dim == 2) return max_rate_2d(shape, g, n, q, h, settings, row);
  else return max_rate_3d(shape, g, n, q, h, settings, row);
}

/// add_block_inviscid<Dim>, dispatched to the instruction set at hand.
template <int Dim>
inline long block_inviscid(const wavelet::ArrayShape<Dim>& shape, int g, int n, const BlockPrimitives<Dim>& w,
                           const std::array<const double*, Dim + 2>& q, const std::array<double, Dim>& h,
                           const InviscidSettings& settings, BlockScratch<Dim>& scratch, double* out) {
  if constexpr (Dim == 1) return block_inviscid_1d(shape, g, n, w, q, h, settings, scratch, out);
  else if constexpr (Dim == 2) return block_inviscid_2d(shape, g, n, w, q, h, settings, scratch, out);
  else return block_inviscid_3d(shape, g, n, w, q, h, settings, scratch, out);
}

/// add_block_viscous<Dim>, dispatched to the instruction set at hand.
template <int Dim>
inline void block_viscous(const wavelet::ArrayShape<Dim>& shape, int g, int n, const std::array<double, Dim>& h,
                          const ViscousSettings& settings, const ViscousBlock<Dim>& block, double* out) {
  if constexpr (Dim == 1) block_viscous_1d(shape, g, n, h, settings, block, out);
  else if constexpr (Dim == 2) block_viscous_2d(shape, g, n, h, settings, block, out);
  else block_viscous_3d(shape, g, n, h, settings, block, out);
}

}  // namespace grainwave::fluid
