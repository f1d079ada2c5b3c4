#pragma once
// One axis of a tensor-product prediction stencil in block-array coordinates (BlockPrediction.hpp
// builds them; AdaptiveGrid caches them per class of block).
#include <array>

#include "wavelet/InterpolatingWavelet.hpp"

namespace grainwave::wavelet {

/// Interpolation weights along one axis of a block array: value = sum_k w[k] u[at[k]].
struct AxisStencil {
  int size = 1;
  std::array<int, kMaxPredictOrder> at{};
  std::array<double, kMaxPredictOrder> w{};
};

}  // namespace grainwave::wavelet
