#pragma once
// Finite-difference derivatives on one block: central first and second derivatives of order
// 2, 4 or 6 (design.md "Operators"; 4th order is the AWCM default of 002 §2.2.2), one-sided rows
// of the same order next to non-periodic domain edges, and mixed second derivatives as the tensor
// product of two first-derivative rows. All weights come from Fornberg's recursion (Math. Comp.
// 51, 1988) on integer node offsets, so central and one-sided rows are derived the same way.
//
// Block layout (ArrayShape order, axis 0 fastest): `interior[a]` points per axis plus `ghosts`
// layers on every side, so the array extent is interior[a] + 2 * ghosts and interior point i sits
// at array index i + ghosts. Point i has coordinate x0 + i * h (h = spacing at the block's level).
// A side whose ghosts are filled (neighbour block or periodic image) uses central rows and needs
// ghosts >= accuracy / 2; mixed derivatives also read the edge and corner ghosts. A side flagged
// one-sided never reads its ghosts: its first accuracy/2 rows use nodes inside the block only.
// Operators write interior points of the output and leave its ghost layers untouched.
#include "wavelet/ArrayShape.hpp"

#include <array>
#include <span>
#include <vector>

namespace grainwave::wavelet {

/// Widest row: a 6th-order one-sided second derivative uses 8 nodes.
inline constexpr int kMaxStencilWidth = 8;

/// Weights w_k with f^(derivative)(x) ≈ sum_k w_k f(nodes_k) (Fornberg's recursion).
void finite_difference_weights(std::span<const double> nodes, double x, int derivative,
                               std::span<double> weights);

/// One row: f^(m)(x_i) ≈ sum_{k < width} weight[k] f(x_{i + first + k}) / h^m.
struct StencilRow {
  int first = 0;
  int width = 0;
  std::array<double, kMaxStencilWidth> weight{};
};

/// All rows of one derivative along a line of n interior points.
class DerivativeStencil1D {
 public:
  DerivativeStencil1D(int n, int derivative, int accuracy, bool one_sided_low, bool one_sided_high);
  const StencilRow& row(int i) const {
    if (i < closure_rows_ && one_sided_low_) return low_rows_[static_cast<std::size_t>(i)];
    if (i >= n_ - closure_rows_ && one_sided_high_)
      return high_rows_[static_cast<std::size_t>(i - (n_ - closure_rows_))];
    return central_;
  }
  int half_width() const { return closure_rows_; }  ///< ghosts needed on a side with central rows
  int derivative() const { return derivative_; }

 private:
  int n_;
  int derivative_;
  int closure_rows_;
  bool one_sided_low_;
  bool one_sided_high_;
  StencilRow central_;
  std::vector<StencilRow> low_rows_;
  std::vector<StencilRow> high_rows_;
};

template <int Dim>
struct BlockLayout {
  std::array<int, Dim> interior{};
  int ghosts = 0;

  ArrayShape<Dim> shape() const {
    ArrayShape<Dim> s;
    for (int a = 0; a < Dim; ++a) s.extent[static_cast<std::size_t>(a)] = interior[static_cast<std::size_t>(a)] + 2 * ghosts;
    return s;
  }
  /// Array index of interior point i (i may step into the ghosts: -ghosts <= i_a < n_a + ghosts).
  std::ptrdiff_t index(const std::array<int, Dim>& i) const {
    std::array<int, Dim> shifted = i;
    for (int& c : shifted) c += ghosts;
    return shape().index(shifted);
  }
};

struct DerivativeConfig {
  int accuracy = 4;  ///< 2, 4 or 6
  /// one_sided[a][0]: low side of axis a is a non-periodic domain edge; [a][1]: high side.
  std::array<std::array<bool, 2>, 3> one_sided{};
};

/// First, second and mixed derivatives on blocks of one layout and spacing.
template <int Dim>
class DerivativeOperator {
 public:
  DerivativeOperator(BlockLayout<Dim> layout, std::array<double, Dim> spacing, DerivativeConfig config);

  void first(std::span<const double> u, std::span<double> out, int axis) const;
  void second(std::span<const double> u, std::span<double> out, int axis) const;
  /// d^2 u / dx_a dx_b for a != b.
  void mixed(std::span<const double> u, std::span<double> out, int axis_a, int axis_b) const;

  const BlockLayout<Dim>& layout() const { return layout_; }

 private:
  void apply(const DerivativeStencil1D& op, double scale, std::span<const double> u, std::span<double> out,
             int axis) const;

  BlockLayout<Dim> layout_;
  ArrayShape<Dim> shape_;
  std::array<double, Dim> spacing_;
  std::vector<DerivativeStencil1D> first_;   // one per axis
  std::vector<DerivativeStencil1D> second_;  // one per axis
};

extern template class DerivativeOperator<1>;
extern template class DerivativeOperator<2>;
extern template class DerivativeOperator<3>;

}  // namespace grainwave::wavelet
