#pragma once
// Second-generation interpolating wavelets by lifting (Sweldens 1996; the AWCM of Vasilyev &
// Bowman used by Goetsch 2015, 002 §2.2.2, and design.md "The adaptive grid").
//
// One lifting step on a line of level-local samples u_0..u_{n-1} (stride s in the array):
//   split    evens u_{2k} (the next coarser level) and odds u_{2k+1}
//   predict  d_{2k+1} = u_{2k+1} - sum_m w_m u_{e_m}       (Deslauriers-Dubuc: Lagrange
//            interpolation of order p = 4 or 6 through the p nearest evens)
//   update   c_{e}    = u_{e} + 1/2 sum_{odd o ∋ e} w_{o,e} d_o   (optional; U = P^T / 2, which in
//            the interior is the (p, p) biorthogonal lifting; extrapolated odds are left out)
// The inverse runs the same steps backwards with the signs flipped, so reconstruction is exact up
// to round-off on any data. Near a non-periodic edge the p evens are shifted inwards (one-sided
// Lagrange interpolation of the same order), so polynomials of degree < p still give zero details.
//
// Layout conventions (see ArrayShape.hpp for index order):
// - Periodic axis: extent n = n_coarse * 2^levels points at x_i = i h; the point at i = n is i = 0.
// - Non-periodic axis: any extent n. The grid of step t is every index that is a multiple of
//   2^t, anchored at index 0. With n = m * 2^levels + 1 both end points stay on every level (a
//   "redundant" grid whose block edges are shared points); otherwise the last odd points of a step
//   are predicted by one-sided extrapolation of the same order. Each step needs >= order evens.
// - After `forward` with L levels a point with multi-index i holds
//     * a scaling coefficient (the sample, or its lifted value) if every i_a is a multiple of 2^L;
//     * otherwise the detail of step t = min_a trailing_zeros(i_a) (t = 0 finest; level-j details
//       of design.md are step Jmax - j). `LiftingTransform::detail_step` computes t.
// - Multi-D is the non-standard tensor product: at each step the 1D step runs along axis 0, then
//   axis 1, ..., over every point of that step's grid (coords multiples of 2^t).
#include "wavelet/ArrayShape.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <span>
#include <vector>

namespace grainwave::wavelet {

inline constexpr int kMaxPredictOrder = 6;

/// Lagrange interpolation weights w_k such that p(x) = sum_k w_k f(nodes_k) for the polynomial of
/// degree nodes.size()-1 through the nodes. Numerator and denominator are accumulated separately,
/// so for integer nodes (as used here) the dyadic weights come out exact.
void lagrange_weights(std::span<const double> nodes, double x, std::span<double> weights);

/// Predict stencil of one odd sample: `size` level-local even indices and their weights.
struct PredictStencil {
  int size = 0;
  std::array<int, kMaxPredictOrder> even{};
  std::array<double, kMaxPredictOrder> weight{};
};

/// Deslauriers-Dubuc predict stencil of `order` (even, 2..6) for the odd level-local index `odd`
/// on a line of `n_local` samples. Periodic: n_local even, indices wrap. Non-periodic: the
/// stencil is shifted inward near the ends (needs (n_local + 1) / 2 >= order evens).
PredictStencil deslauriers_dubuc_stencil(int order, int odd, int n_local, bool periodic);

struct LiftingConfig {
  int order = 4;        ///< Deslauriers-Dubuc order: 4 (default) or 6
  bool update = false;  ///< apply the update step U = P^T / 2
  int levels = 1;       ///< number of lifting steps (the coarsest grid has stride 2^levels)
};

/// Multi-level lifting transform on a dense Dim-dimensional array, in place.
/// Stencil tables are built once in the constructor; forward/inverse allocate nothing.
template <int Dim>
class LiftingTransform {
 public:
  LiftingTransform(std::array<int, Dim> extent, std::array<bool, Dim> periodic, LiftingConfig config);

  void forward(std::span<double> data) const;
  void inverse(std::span<double> data) const;
  /// One step t (0 = finest): acts on the grid of stride 2^t, leaves details on stride 2^t odds.
  void forward_step(std::span<double> data, int step) const;
  void inverse_step(std::span<double> data, int step) const;

  const ArrayShape<Dim>& shape() const { return shape_; }
  const LiftingConfig& config() const { return config_; }

  /// Step whose detail sits at multi-index i, or `levels` for a coarse scaling coefficient.
  int detail_step(const std::array<int, Dim>& i) const {
    int t = config_.levels;
    for (int a = 0; a < Dim; ++a) {
      const int c = i[static_cast<std::size_t>(a)];
      if (c != 0) t = std::min(t, std::countr_zero(static_cast<unsigned>(c)));
    }
    return t;
  }

 private:
  struct LineStencils {  // all odd stencils of one axis at one step, flattened
    int n_local = 0;
    int order = 0;
    std::vector<int> even;        // n_odd * order level-local even indices
    std::vector<double> weight;   // n_odd * order
  };
  const LineStencils& stencils(int axis, int step) const {
    return tables_[static_cast<std::size_t>(step * Dim + axis)];
  }
  template <class LineOp>
  void for_each_line(int axis, int step, LineOp&& op) const;
  /// One predict (or update) pass along `axis` over every line of step `step`'s grid.
  template <bool Predict>
  void sweep(std::span<double> data, int axis, int step, double sign) const;

  ArrayShape<Dim> shape_;
  std::array<bool, Dim> periodic_;
  LiftingConfig config_;
  std::vector<LineStencils> tables_;
};

extern template class LiftingTransform<1>;
extern template class LiftingTransform<2>;
extern template class LiftingTransform<3>;

}  // namespace grainwave::wavelet
