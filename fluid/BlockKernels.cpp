#include "fluid/BlockKernels.hpp"

// Each kernel is cloned for AVX-512F, AVX2 and the baseline; `flatten` inlines the templates
// into each clone, so each is compiled for its instruction set as a whole. The 1D kernels stop
// at AVX2: their rows (a block's 16 points and the ghosts) are too short for 512-bit vectors,
// which took 6-9 % off their throughput in bench_fluid (2D and 3D gained 5-16 %).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_ADDRESS__)
#define GRAINWAVE_KERNEL_CLONES __attribute__((target_clones("avx512f", "avx2", "default"), flatten))
#define GRAINWAVE_KERNEL_CLONES_1D __attribute__((target_clones("avx2", "default"), flatten))
#else
#define GRAINWAVE_KERNEL_CLONES
#define GRAINWAVE_KERNEL_CLONES_1D
#endif

namespace grainwave::fluid {

GRAINWAVE_KERNEL_CLONES_1D long block_inviscid_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                               const BlockPrimitives<1>& w, const std::array<const double*, 3>& q,
                                               const std::array<double, 1>& h, const InviscidSettings& settings,
                                               BlockScratch<1>& scratch, double* out) {
  return add_block_inviscid<1>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_KERNEL_CLONES long block_inviscid_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                               const BlockPrimitives<2>& w, const std::array<const double*, 4>& q,
                                               const std::array<double, 2>& h, const InviscidSettings& settings,
                                               BlockScratch<2>& scratch, double* out) {
  return add_block_inviscid<2>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_KERNEL_CLONES long block_inviscid_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                               const BlockPrimitives<3>& w, const std::array<const double*, 5>& q,
                                               const std::array<double, 3>& h, const InviscidSettings& settings,
                                               BlockScratch<3>& scratch, double* out) {
  return add_block_inviscid<3>(shape, g, n, w, q, h, settings, scratch, out);
}
GRAINWAVE_KERNEL_CLONES_1D void block_viscous_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                              const std::array<double, 1>& h, const ViscousSettings& settings,
                                              const ViscousBlock<1>& block, double* out) {
  add_block_viscous<1>(shape, g, n, h, settings, block, out);
}
GRAINWAVE_KERNEL_CLONES void block_viscous_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                              const std::array<double, 2>& h, const ViscousSettings& settings,
                                              const ViscousBlock<2>& block, double* out) {
  add_block_viscous<2>(shape, g, n, h, settings, block, out);
}
GRAINWAVE_KERNEL_CLONES void block_viscous_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                              const std::array<double, 3>& h, const ViscousSettings& settings,
                                              const ViscousBlock<3>& block, double* out) {
  add_block_viscous<3>(shape, g, n, h, settings, block, out);
}

GRAINWAVE_KERNEL_CLONES_1D void primitives_1d(const std::array<const double*, 3>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 1>& u, double* e, double* p) {
  block_primitives<1>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_KERNEL_CLONES_1D double max_rate_1d(const wavelet::ArrayShape<1>& shape, int g, int n,
                                           const std::array<const double*, 3>& q, const std::array<double, 1>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<1>(shape, g, n, q, h, settings, row);
}
GRAINWAVE_KERNEL_CLONES void primitives_2d(const std::array<const double*, 4>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 2>& u, double* e, double* p) {
  block_primitives<2>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_KERNEL_CLONES double max_rate_2d(const wavelet::ArrayShape<2>& shape, int g, int n,
                                           const std::array<const double*, 4>& q, const std::array<double, 2>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<2>(shape, g, n, q, h, settings, row);
}
GRAINWAVE_KERNEL_CLONES void primitives_3d(const std::array<const double*, 5>& q, std::size_t volume, double gamma,
                                           double* rho, const std::array<double*, 3>& u, double* e, double* p) {
  block_primitives<3>(q, volume, gamma, rho, u, e, p);
}
GRAINWAVE_KERNEL_CLONES double max_rate_3d(const wavelet::ArrayShape<3>& shape, int g, int n,
                                           const std::array<const double*, 5>& q, const std::array<double, 3>& h,
                                           const StableRateSettings& settings, double* row) {
  return block_max_rate<3>(shape, g, n, q, h, settings, row);
}

}  // namespace grainwave::fluid
