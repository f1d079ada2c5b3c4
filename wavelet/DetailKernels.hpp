#pragma once
// The hot loop of the adaptation's tagging: the largest wavelet coefficient |u - P u| of a block
// array (002 §2.2.2; d = u - P u_{j-1} in AdaptiveGrid's conventions). Most rows of most blocks
// are centred Deslauriers-Dubuc rows with fixed offsets, so the separable prediction runs as
// contiguous loops; the few one-sided rows near a bounded domain edge are then computed from
// their own stencils. The kernels are compiled for AVX2 and the baseline (the 2D maxima also for
// AVX-512F), picked at run time.
// Every prediction is the sum AdaptiveGrid::predict_array forms (started at 0, accumulated in
// stencil order, no FMA), so the maxima are bitwise those of its coefficients.
#include <array>
#include <cstddef>
#include <utility>

#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/AxisStencil.hpp"
#include "wavelet/InterpolatingWavelet.hpp"

namespace grainwave::wavelet {

template <int Dim>
struct DetailRows {
  int block_size, ghosts, order;  ///< order 4 or 6
  const std::array<double, kMaxPredictOrder>& centred_weights;
  /// Per axis and interior index: whether the row is centred (AdaptiveGrid::DetailStencils).
  const std::array<std::array<bool, kMaxBlockSize>, Dim>& centred;
  /// Every row's stencil in block-array coordinates (read for the rows that are not centred).
  const std::array<std::array<AxisStencil, kMaxBlockSize>, Dim>& axis;
  /// Per axis and interior index: whether the point's row reads only what a family of children
  /// holds (AdaptiveGrid::DetailStencils::near).
  const std::array<std::array<bool, kMaxBlockSize>, Dim>& near;
};

/// Largest |u - P u| over the interior points of the block array u (ghosts filled), and over
/// its near points, and largest |u| over the interior points. along_x: (bs + 2g)^(Dim-1) * bs
/// values of scratch; last: bs (2D) or (bs + 2g) * bs^2 + bs^2 (3D) values.
DetailMaxima block_detail_maxima(const double* u, const DetailRows<1>& rows, double* along_x, double* last);
DetailMaxima block_detail_maxima(const double* u, const DetailRows<2>& rows, double* along_x, double* last);
DetailMaxima block_detail_maxima(const double* u, const DetailRows<3>& rows, double* along_x, double* last);

/// Smallest and largest of u[0 .. n) (n >= 1; NaNs are passed over). The range bound of the
/// tagging reads every value of a block array once per field, so it runs in packed lanes.
std::pair<double, double> value_range(const double* u, std::size_t n);

/// Largest |u| over the interior points of a block array of `dim` axes, bs interior points and
/// g ghost layers per side along each (0 if all are NaN): the linf scale of the threshold.
double interior_largest_magnitude(const double* u, int dim, int bs, int g);

/// value_range of the whole block array and interior_largest_magnitude, the same values (a
/// zero's sign in the range may differ; the tagging reads high - low and magnitudes), in one
/// call: the tagging needs both of every block and field, and the interior is read again while
/// the array's read has left it in cache.
struct BlockExtent {
  double low, high, interior_magnitude;
};
BlockExtent block_extent(const double* u, int dim, int bs, int g);

}  // namespace grainwave::wavelet
