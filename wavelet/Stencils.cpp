#include "wavelet/Stencils.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace grainwave::wavelet {

void finite_difference_weights(std::span<const double> nodes, double x, int derivative,
                               std::span<double> weights) {
  constexpr int kMaxDerivative = 2;
  const int n = static_cast<int>(nodes.size());
  if (n > kMaxStencilWidth || derivative < 0 || derivative > kMaxDerivative || n <= derivative ||
      weights.size() != nodes.size())
    throw std::invalid_argument("finite_difference_weights: unsupported stencil");
  // c[j][m]: weight of node j for the m-th derivative, built up one node at a time.
  double c[kMaxStencilWidth][kMaxDerivative + 1] = {};
  c[0][0] = 1.0;
  double prev_product = 1.0;
  double prev_offset = nodes[0] - x;
  for (int i = 1; i < n; ++i) {
    const int m_top = std::min(i, derivative);
    double product = 1.0;
    const double offset_before = prev_offset;
    const double offset = nodes[static_cast<std::size_t>(i)] - x;
    for (int j = 0; j < i; ++j) {
      const double gap = nodes[static_cast<std::size_t>(i)] - nodes[static_cast<std::size_t>(j)];
      product *= gap;
      if (j == i - 1) {
        for (int m = m_top; m >= 1; --m)
          c[i][m] = prev_product * (m * c[i - 1][m - 1] - offset_before * c[i - 1][m]) / product;
        c[i][0] = -prev_product * offset_before * c[i - 1][0] / product;
      }
      for (int m = m_top; m >= 1; --m) c[j][m] = (offset * c[j][m] - m * c[j][m - 1]) / gap;
      c[j][0] = offset * c[j][0] / gap;
    }
    prev_product = product;
    prev_offset = offset;
  }
  for (int j = 0; j < n; ++j) weights[static_cast<std::size_t>(j)] = c[j][derivative];
}

namespace {

// Nodes are offsets relative to the row's point, which sits at 0.
StencilRow make_row(int first, int width, int derivative) {
  StencilRow row;
  row.first = first;
  row.width = width;
  std::array<double, kMaxStencilWidth> nodes{};
  for (int k = 0; k < width; ++k) nodes[static_cast<std::size_t>(k)] = first + k;
  finite_difference_weights(std::span<const double>(nodes.data(), static_cast<std::size_t>(width)),
                            0.0, derivative,
                            std::span<double>(row.weight.data(), static_cast<std::size_t>(width)));
  return row;
}

}  // namespace

DerivativeStencil1D::DerivativeStencil1D(int n, int derivative, int accuracy, bool one_sided_low,
                                         bool one_sided_high)
    : n_(n),
      derivative_(derivative),
      closure_rows_(accuracy / 2),
      one_sided_low_(one_sided_low),
      one_sided_high_(one_sided_high) {
  if (accuracy != 2 && accuracy != 4 && accuracy != 6)
    throw std::invalid_argument("derivative accuracy must be 2, 4 or 6, got " + std::to_string(accuracy));
  if (derivative != 1 && derivative != 2) throw std::invalid_argument("derivative must be 1 or 2");
  central_ = make_row(-closure_rows_, 2 * closure_rows_ + 1, derivative);
  // A row that cannot be centred uses `accuracy + derivative` nodes: on a uniform grid that many
  // nodes give the m-th derivative to order (nodes - m) = accuracy.
  const int one_sided_width = accuracy + derivative;
  if ((one_sided_low || one_sided_high) && n < one_sided_width)
    throw std::invalid_argument("block of " + std::to_string(n) + " points is too small for one-sided rows of width " +
                                std::to_string(one_sided_width));
  for (int i = 0; i < closure_rows_; ++i) {
    if (one_sided_low) low_rows_.push_back(make_row(-i, one_sided_width, derivative));
    const int i_high = n - closure_rows_ + i;
    if (one_sided_high) high_rows_.push_back(make_row((n - one_sided_width) - i_high, one_sided_width, derivative));
  }
}

template <int Dim>
DerivativeOperator<Dim>::DerivativeOperator(BlockLayout<Dim> layout, std::array<double, Dim> spacing,
                                            DerivativeConfig config)
    : layout_(layout), shape_(layout.shape()), spacing_(spacing) {
  for (int a = 0; a < Dim; ++a) {
    const auto& sides = config.one_sided[static_cast<std::size_t>(a)];
    const int n = layout.interior[static_cast<std::size_t>(a)];
    first_.emplace_back(n, 1, config.accuracy, sides[0], sides[1]);
    second_.emplace_back(n, 2, config.accuracy, sides[0], sides[1]);
    if ((!sides[0] || !sides[1]) && layout.ghosts < config.accuracy / 2)
      throw std::invalid_argument("central rows of order " + std::to_string(config.accuracy) + " need " +
                                  std::to_string(config.accuracy / 2) + " ghost layers, block has " +
                                  std::to_string(layout.ghosts));
  }
}

template <int Dim>
void DerivativeOperator<Dim>::apply(const DerivativeStencil1D& op, double scale, std::span<const double> u,
                                    std::span<double> out, int axis) const {
  const std::ptrdiff_t stride = shape_.stride(axis);
  const int n0 = layout_.interior[0];
  std::array<int, Dim> count = layout_.interior;
  count[0] = 1;
  std::array<int, Dim> at{};
  std::size_t lines = 1;
  for (int c : count) lines *= static_cast<std::size_t>(c);
  for (std::size_t line = 0; line < lines; ++line) {
    std::size_t rest = line;
    for (int a = 1; a < Dim; ++a) {
      at[static_cast<std::size_t>(a)] = static_cast<int>(rest % static_cast<std::size_t>(count[static_cast<std::size_t>(a)]));
      rest /= static_cast<std::size_t>(count[static_cast<std::size_t>(a)]);
    }
    at[0] = 0;
    const std::ptrdiff_t base = layout_.index(at);
    const double* in = u.data() + base;
    double* res = out.data() + base;
    if (axis == 0) {
      for (int i = 0; i < n0; ++i) {
        const StencilRow& row = op.row(i);
        double sum = 0.0;
        for (int k = 0; k < row.width; ++k) sum += row.weight[static_cast<std::size_t>(k)] * in[i + row.first + k];
        res[i] = scale * sum;
      }
    } else if constexpr (Dim > 1) {  // (Dim 1 has only axis 0; this keeps -Warray-bounds quiet)
      // One row for the whole x-line: sweep it weight by weight so the inner loop is contiguous.
      const StencilRow& row = op.row(at[static_cast<std::size_t>(axis)]);
      for (int i = 0; i < n0; ++i) res[i] = 0.0;
      for (int k = 0; k < row.width; ++k) {
        const double w = scale * row.weight[static_cast<std::size_t>(k)];
        const double* src = in + (row.first + k) * stride;
        for (int i = 0; i < n0; ++i) res[i] += w * src[i];
      }
    }
  }
}

template <int Dim>
void DerivativeOperator<Dim>::first(std::span<const double> u, std::span<double> out, int axis) const {
  const double h = spacing_[static_cast<std::size_t>(axis)];
  apply(first_[static_cast<std::size_t>(axis)], 1.0 / h, u, out, axis);
}

template <int Dim>
void DerivativeOperator<Dim>::second(std::span<const double> u, std::span<double> out, int axis) const {
  const double h = spacing_[static_cast<std::size_t>(axis)];
  apply(second_[static_cast<std::size_t>(axis)], 1.0 / (h * h), u, out, axis);
}

template <int Dim>
void DerivativeOperator<Dim>::mixed(std::span<const double> u, std::span<double> out, int axis_a,
                                    int axis_b) const {
  if (axis_a == axis_b || axis_a < 0 || axis_b < 0 || axis_a >= Dim || axis_b >= Dim)
    throw std::invalid_argument("mixed derivative needs two different axes");
  const auto& op_a = first_[static_cast<std::size_t>(axis_a)];
  const auto& op_b = first_[static_cast<std::size_t>(axis_b)];
  const double scale = 1.0 / (spacing_[static_cast<std::size_t>(axis_a)] * spacing_[static_cast<std::size_t>(axis_b)]);
  const std::ptrdiff_t stride_a = shape_.stride(axis_a);
  const std::ptrdiff_t stride_b = shape_.stride(axis_b);
  std::size_t points = 1;
  for (int c : layout_.interior) points *= static_cast<std::size_t>(c);
  const ArrayShape<Dim> interior_shape{layout_.interior};
  for (std::size_t p = 0; p < points; ++p) {
    const auto at = interior_shape.coords(static_cast<std::ptrdiff_t>(p));
    const StencilRow& row_a = op_a.row(at[static_cast<std::size_t>(axis_a)]);
    const StencilRow& row_b = op_b.row(at[static_cast<std::size_t>(axis_b)]);
    const std::ptrdiff_t centre = layout_.index(at);
    double sum = 0.0;
    for (int kb = 0; kb < row_b.width; ++kb) {
      const double* line = u.data() + centre + (row_b.first + kb) * stride_b + row_a.first * stride_a;
      double inner = 0.0;
      for (int ka = 0; ka < row_a.width; ++ka) inner += row_a.weight[static_cast<std::size_t>(ka)] * line[ka * stride_a];
      sum += row_b.weight[static_cast<std::size_t>(kb)] * inner;
    }
    out[static_cast<std::size_t>(centre)] = scale * sum;
  }
}

template class DerivativeOperator<1>;
template class DerivativeOperator<2>;
template class DerivativeOperator<3>;

}  // namespace grainwave::wavelet
