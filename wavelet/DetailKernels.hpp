#pragma once
// The hot loop of the adaptation's tagging: the largest wavelet coefficient |u - P u| of a block
// array (002 §2.2.2; d = u - P u_{j-1} in AdaptiveGrid's conventions), for blocks whose every
// axis uses centred Deslauriers-Dubuc rows (all blocks not touching a bounded domain edge). The
// offsets are then fixed, so the separable prediction runs as contiguous loops; the kernels are
// compiled for AVX2 and the baseline, picked at run time. The sums are those of
// AdaptiveGrid::predict_array (started at 0, accumulated in stencil order, no FMA), so the
// maxima are bitwise those of the general path.
#include <array>
#include <utility>

#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/InterpolatingWavelet.hpp"

namespace grainwave::wavelet {

template <int Dim>
struct CentredRows {
  int block_size, ghosts, order;  ///< order 4 or 6
  const std::array<double, kMaxPredictOrder>& weights;  ///< the centred row's weights
  /// Per axis and interior index: whether the point's row reads only what a family of children
  /// holds (AdaptiveGrid::DetailStencils::near).
  const std::array<std::array<bool, kMaxBlockSize>, Dim>& near;
};

/// Largest |u - P u| over the interior points of the block array u (ghosts filled), and over
/// its near points. along_x: (bs + 2g)^(Dim-1) * bs values of scratch; last: bs (2D) or
/// (bs + 2g) * bs^2 + bs^2 (3D) values.
std::pair<double, double> centred_detail_maxima(const double* u, const CentredRows<1>& rows, double* along_x,
                                                double* last);
std::pair<double, double> centred_detail_maxima(const double* u, const CentredRows<2>& rows, double* along_x,
                                                double* last);
std::pair<double, double> centred_detail_maxima(const double* u, const CentredRows<3>& rows, double* along_x,
                                                double* last);

}  // namespace grainwave::wavelet
