#include "fluid/BlockKernels.hpp"

#include "core/KernelClones.hpp"

// The 2D and 3D kernels are cloned up to AVX-512F, the 1D ones up to AVX2: their rows (a
// block's 16 points and the ghosts) are too short for 512-bit vectors, which took 6-9 % off
// their throughput in bench_fluid (2D and 3D gained 5-16 %).

namespace grainwave::fluid {

GRAINWAVE_CLONES_AVX2 long block_inviscid_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                               const BlockPrimitives<1>& w, const std::array<const double*, 3>& q,
                                               const std::array<double, 1>& h, const InviscidSettings& settings,
                                               BlockScratch<1>& scratch, double* out) {
  return add_block_inviscid<1>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_CLONES_AVX512 long block_inviscid_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                               const BlockPrimitives<2>& w, const std::array<const double*, 4>& q,
                                               const std::array<double, 2>& h, const InviscidSettings& settings,
                                               BlockScratch<2>& scratch, double* out) {
  return add_block_inviscid<2>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_CLONES_AVX512 long block_inviscid_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                               const BlockPrimitives<3>& w, const std::array<const double*, 5>& q,
                                               const std::array<double, 3>& h, const InviscidSettings& settings,
                                               BlockScratch<3>& scratch, double* out) {
  return add_block_inviscid<3>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_CLONES_AVX2 void block_viscous_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                              const std::array<double, 1>& h, const ViscousSettings& settings,
                                              const ViscousBlock<1>& block, double* out) {
  add_block_viscous<1>(shape, g, n, h, settings, block, out);
}
GRAINWAVE_CLONES_AVX512 void block_viscous_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                              const std::array<double, 2>& h, const ViscousSettings& settings,
                                              const ViscousBlock<2>& block, double* out) {
  add_block_viscous<2>(shape, g, n, h, settings, block, out);
}
GRAINWAVE_CLONES_AVX512 void block_viscous_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                              const std::array<double, 3>& h, const ViscousSettings& settings,
                                              const ViscousBlock<3>& block, double* out) {
  add_block_viscous<3>(shape, g, n, h, settings, block, out);
}

GRAINWAVE_CLONES_AVX2 void primitives_1d(const std::array<const double*, 3>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 1>& u, double* e, double* p) {
  block_primitives<1>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_CLONES_AVX2 double max_rate_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                           const std::array<const double*, 3>& q, const std::array<double, 1>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<1>(shape, g, n, q, h, settings, row);
}
GRAINWAVE_CLONES_AVX512 void primitives_2d(const std::array<const double*, 4>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 2>& u, double* e, double* p) {
  block_primitives<2>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_CLONES_AVX512 double max_rate_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                           const std::array<const double*, 4>& q, const std::array<double, 2>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<2>(shape, g, n, q, h, settings, row);
}
GRAINWAVE_CLONES_AVX512 void primitives_3d(const std::array<const double*, 5>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 3>& u, double* e, double* p) {
  block_primitives<3>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_CLONES_AVX512 double max_rate_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                           const std::array<const double*, 5>& q, const std::array<double, 3>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<3>(shape, g, n, q, h, settings, row);
}

}  // namespace grainwave::fluid
