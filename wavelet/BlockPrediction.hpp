#pragma once
// Deslauriers-Dubuc prediction on the adaptive grid's blocks (002 §2.2.2; the conventions of
// AdaptiveGrid.hpp): the interpolation weights of an odd level index from the evens of its level,
// one-sided near bounded domain edges; per-axis stencils in block-array coordinates for a block's
// wavelet coefficients and for the children of a refined block; their tensor-product sums.
// Shared by AdaptiveGrid and by anything that predicts on blocks (fluid/ boundary treatment).
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/AxisStencil.hpp"
#include "wavelet/InterpolatingWavelet.hpp"

namespace grainwave::wavelet::prediction {
using GlobalIndex64 = std::int64_t;

/// Deslauriers-Dubuc prediction of the odd level index `odd` of a line of `n` points: the
/// `order` nearest evens, shifted inside [0, n) on a non-periodic line (one-sided rows of the
/// same order), left unwrapped on a periodic one. Nodes are relative integers, so the dyadic
/// weights are exact.
struct LineStencil {
  int size = 0;
  std::array<GlobalIndex64, kMaxPredictOrder> even{};
  std::array<double, kMaxPredictOrder> weight{};
};

inline LineStencil dd_line(int order, GlobalIndex64 odd, GlobalIndex64 n, bool periodic) {
  GlobalIndex64 first = odd - (order - 1);
  const GlobalIndex64 centred = first;
  if (!periodic) {
    const GlobalIndex64 last_even = (n - 1) - ((n - 1) % 2);
    first = std::clamp<GlobalIndex64>(first, 0, last_even - 2 * (order - 1));
  }
  LineStencil s;
  s.size = order;
  std::array<double, kMaxPredictOrder> nodes{};
  for (int m = 0; m < order; ++m) {
    const auto mu = static_cast<std::size_t>(m);
    s.even[mu] = first + 2 * m;
    nodes[mu] = static_cast<double>(s.even[mu] - odd);
  }
  // Centred rows (all but a few near bounded edges) share one set of weights: compute it once.
  static const auto centred_weights = [] {
    std::array<std::array<double, kMaxPredictOrder>, kMaxPredictOrder + 1> w{};
    for (int p = 2; p <= kMaxPredictOrder; p += 2) {
      std::array<double, kMaxPredictOrder> x{};
      for (int m = 0; m < p; ++m) x[static_cast<std::size_t>(m)] = 2.0 * m - (p - 1);
      lagrange_weights(std::span<const double>(x.data(), static_cast<std::size_t>(p)), 0.0,
                       std::span<double>(w[static_cast<std::size_t>(p)].data(), static_cast<std::size_t>(p)));
    }
    return w;
  }();
  if (first == centred) {
    s.weight = centred_weights[static_cast<std::size_t>(order)];
    return s;
  }
  lagrange_weights(std::span<const double>(nodes.data(), static_cast<std::size_t>(order)), 0.0,
                   std::span<double>(s.weight.data(), static_cast<std::size_t>(order)));
  return s;
}

/// sum over the tensor product of per-axis stencils of w * u (strides of an ArrayShape), at one
/// point: the definition separable_tensor_sums computes for a whole block (a test holds the two
/// bitwise equal).
template <int Dim>
double tensor_sum(const double* u, const std::array<std::ptrdiff_t, Dim>& stride,
                  const std::array<const AxisStencil*, Dim>& st) {
  double sum = 0;
  if constexpr (Dim == 1) {
    for (int p = 0; p < st[0]->size; ++p) sum += st[0]->w[p] * u[st[0]->at[p]];
  } else if constexpr (Dim == 2) {
    for (int q = 0; q < st[1]->size; ++q) {
      const double* row = u + st[1]->at[q] * stride[1];
      double line = 0;
      for (int p = 0; p < st[0]->size; ++p) line += st[0]->w[p] * row[st[0]->at[p]];
      sum += st[1]->w[q] * line;
    }
  } else {
    for (int r = 0; r < st[2]->size; ++r) {
      double plane = 0;
      for (int q = 0; q < st[1]->size; ++q) {
        const double* row = u + st[2]->at[r] * stride[2] + st[1]->at[q] * stride[1];
        double line = 0;
        for (int p = 0; p < st[0]->size; ++p) line += st[0]->w[p] * row[st[0]->at[p]];
        plane += st[1]->w[q] * line;
      }
      sum += st[2]->w[r] * plane;
    }
  }
  return sum;
}

/// tensor_sum at every interior point of a block (bs per axis, interior order, x fastest) into
/// out, in separable form: the x sums once per array line the other axes read, then across y
/// (and z) from those. Every partial sum is tensor_sum's (started at 0, accumulated in stencil
/// order), so each value is bitwise tensor_sum's; the x sums are not repeated per point (a
/// child of a refined block costs 2 x 6 terms a point instead of up to 6 x 6). scratch: any
/// size, resized here.
template <int Dim>
void separable_tensor_sums(const double* u, const std::array<std::ptrdiff_t, Dim>& stride,
                           const std::array<std::array<AxisStencil, kMaxBlockSize>, Dim>& st, int bs,
                           std::vector<double>& scratch, double* out) {
  const auto ubs = static_cast<std::size_t>(bs);
  auto line_sum = [&](const double* row, std::size_t i) {
    const AxisStencil& x = st[0][i];
    double line = 0;
    for (int p = 0; p < x.size; ++p) line += x.w[p] * row[x.at[p]];
    return line;
  };
  if constexpr (Dim == 1) {
    for (std::size_t i = 0; i < ubs; ++i) out[i] = line_sum(u, i);
  } else {
    // The array rows (y) and planes (z) the stencils read: a contiguous range each.
    auto reach = [&](int a) {
      int lo = st[static_cast<std::size_t>(a)][0].at[0], hi = lo;
      for (std::size_t j = 0; j < ubs; ++j)
        for (int q = 0; q < st[static_cast<std::size_t>(a)][j].size; ++q) {
          lo = std::min(lo, st[static_cast<std::size_t>(a)][j].at[q]);
          hi = std::max(hi, st[static_cast<std::size_t>(a)][j].at[q]);
        }
      return std::pair{lo, hi - lo + 1};
    };
    const auto [y0, ny] = reach(1);
    const auto [z0, nz] = Dim == 3 ? reach(2) : std::pair{0, 1};
    const auto rows = static_cast<std::size_t>(ny), planes = static_cast<std::size_t>(nz);
    // lines[(z * rows + y) * bs + i]: the x sums; then (3D) across y per plane.
    scratch.resize(planes * rows * ubs + (Dim == 3 ? planes * ubs * ubs : 0));
    double* lines = scratch.data();
    for (std::size_t z = 0; z < planes; ++z)
      for (std::size_t y = 0; y < rows; ++y) {
        const double* row = u + (static_cast<std::ptrdiff_t>(y) + y0) * stride[1];
        if constexpr (Dim == 3) row += (static_cast<std::ptrdiff_t>(z) + z0) * stride[2];
        for (std::size_t i = 0; i < ubs; ++i) lines[(z * rows + y) * ubs + i] = line_sum(row, i);
      }
    // Across y: plane z's sums at (j, i) into `to` (bs x bs).
    auto across_y = [&](std::size_t z, double* to) {
      for (std::size_t j = 0; j < ubs; ++j) {
        const AxisStencil& w = st[1][j];
        for (std::size_t i = 0; i < ubs; ++i) {
          double sum = 0;
          for (int q = 0; q < w.size; ++q)
            sum += w.w[q] * lines[(z * rows + static_cast<std::size_t>(w.at[q] - y0)) * ubs + i];
          to[j * ubs + i] = sum;
        }
      }
    };
    if constexpr (Dim == 2) {
      across_y(0, out);
    } else {
      double* across = lines + planes * rows * ubs;
      for (std::size_t z = 0; z < planes; ++z) across_y(z, across + z * ubs * ubs);
      for (std::size_t k = 0; k < ubs; ++k) {
        const AxisStencil& w = st[2][k];
        for (std::size_t p = 0; p < ubs * ubs; ++p) {
          double sum = 0;
          for (int r = 0; r < w.size; ++r) sum += w.w[r] * across[static_cast<std::size_t>(w.at[r] - z0) * ubs * ubs + p];
          out[k * ubs * ubs + p] = sum;
        }
      }
    }
  }
}

/// Per-axis prediction stencils of a block's own points from its even (level j-1) points,
/// in array coordinates of the block (identity rows at even points).
template <int Dim>
void detail_stencils(const BlockKey<Dim>& key, const GridConfig<Dim>& config, int ghosts,
                     std::array<std::array<AxisStencil, kMaxBlockSize>, Dim>& st) {
  const auto c = key.coords();
  const int bs = config.block_size;
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    const GlobalIndex64 start = static_cast<GlobalIndex64>(c[au]) * bs;
    const GlobalIndex64 n = static_cast<GlobalIndex64>(config.roots[au]) * bs << key.level;
    for (int i = 0; i < bs; ++i) {
      AxisStencil& s = st[au][static_cast<std::size_t>(i)];
      const GlobalIndex64 G = start + i;
      if (G % 2 == 0) {
        s.size = 1;
        s.at[0] = i + ghosts;
        s.w[0] = 1.0;
        continue;
      }
      const LineStencil line = dd_line(config.order, G, n, config.periodic[au]);
      s.size = line.size;
      for (int m = 0; m < line.size; ++m) {
        const auto mu = static_cast<std::size_t>(m);
        s.at[mu] = static_cast<int>(line.even[mu] - start) + ghosts;
        s.w[mu] = line.weight[mu];
      }
    }
  }
}

/// Per-axis stencils giving child `child`'s points from its parent's array (parent at level j).
template <int Dim>
void child_stencils(const BlockKey<Dim>& parent, int child, const GridConfig<Dim>& config, int ghosts,
                    std::array<std::array<AxisStencil, kMaxBlockSize>, Dim>& st) {
  const auto c = parent.coords();
  const int bs = config.block_size;
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    const GlobalIndex64 pstart = static_cast<GlobalIndex64>(c[au]) * bs;
    const GlobalIndex64 n_fine = static_cast<GlobalIndex64>(config.roots[au]) * bs << (parent.level + 1);
    const int offset = ((child >> a) & 1) * bs;
    for (int i = 0; i < bs; ++i) {
      AxisStencil& s = st[au][static_cast<std::size_t>(i)];
      const GlobalIndex64 F = 2 * pstart + offset + i;
      if (F % 2 == 0) {
        s.size = 1;
        s.at[0] = static_cast<int>(F / 2 - pstart) + ghosts;
        s.w[0] = 1.0;
        continue;
      }
      const LineStencil line = dd_line(config.order, F, n_fine, config.periodic[au]);
      s.size = line.size;
      for (int m = 0; m < line.size; ++m) {
        const auto mu = static_cast<std::size_t>(m);
        s.at[mu] = static_cast<int>(line.even[mu] / 2 - pstart) + ghosts;
        s.w[mu] = line.weight[mu];
      }
    }
  }
}

/// Walks the interior lines along x of a block array (Bs + 2 ghosts per axis) in interior
/// order: visit(at, p, j, k) with the array index `at` and interior index `p` of the line's first
/// point, and the line's interior indices j (y) and k (z), 0 on absent axes.
template <int Dim, class F>
void for_each_interior_line(int bs, int ghosts, F&& visit) {
  const auto ubs = static_cast<std::size_t>(bs), g = static_cast<std::size_t>(ghosts);
  const std::size_t width = ubs + 2 * g;
  std::size_t p = 0;
  for (std::size_t k = 0; k < (Dim == 3 ? ubs : 1); ++k)
    for (std::size_t j = 0; j < (Dim >= 2 ? ubs : 1); ++j, p += ubs) {
      std::size_t at = g;
      if constexpr (Dim >= 2) at += (j + g) * width;
      if constexpr (Dim == 3) at += (k + g) * width * width;
      visit(at, p, j, k);
    }
}

/// Walks the interior points of a block in interior order with their array index.
template <int Dim, class F>
void for_each_interior(int bs, int ghosts, const ArrayShape<Dim>& shape, F&& f) {
  std::array<int, Dim> i{};
  std::size_t p = 0;
  while (true) {
    std::array<int, Dim> q{};
    for (int a = 0; a < Dim; ++a) q[static_cast<std::size_t>(a)] = i[static_cast<std::size_t>(a)] + ghosts;
    f(p++, i, shape.index(q));
    int a = 0;
    for (; a < Dim; ++a) {
      if (++i[static_cast<std::size_t>(a)] < bs) break;
      i[static_cast<std::size_t>(a)] = 0;
    }
    if (a == Dim) break;
  }
}

}  // namespace grainwave::wavelet::prediction
