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
#include <stdexcept>
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

/// tensor_sum at every interior point of a block array (bs interior points and `width` in all
/// per axis, strides powers of width), in separable form: along x on every array line the
/// other axes' stencils read, then along y from those sums, then along z. Each partial sum is
/// tensor_sum's (started at 0, accumulated in stencil order), so every value is bitwise
/// tensor_sum's, but a line's sum is formed once instead of once per point that reads it (a
/// child of a refined block: 2 x 6 terms a point instead of up to 6 x 6). stage: scratch, one
/// buffer per axis. Returns the values, bs^Dim in interior order (x fastest), in stage[Dim - 1].
template <int Dim>
const double* separable_tensor_sums(const double* u, int width,
                                    const std::array<std::array<AxisStencil, kMaxBlockSize>, Dim>& st, int bs,
                                    std::array<std::vector<double>, Dim>& stage) {
  const auto ubs = static_cast<std::size_t>(bs), uw = static_cast<std::size_t>(width);
  // Per axis beyond x, the array indices its stencils read (prediction reads only even ones:
  // the other lines are skipped).
  constexpr std::size_t kMaxWidth = 4 * kMaxBlockSize;  // an array reaches less than a block beyond
  if (uw > kMaxWidth) throw std::logic_error("separable_tensor_sums: block array too wide");
  std::array<std::array<char, kMaxWidth>, Dim> read;
  for (std::size_t a = 1; a < static_cast<std::size_t>(Dim); ++a) {
    read[a].fill(0);
    for (std::size_t j = 0; j < ubs; ++j)
      for (int k = 0; k < st[a][j].size; ++k) read[a][static_cast<std::size_t>(st[a][j].at[k])] = 1;
  }
  // Whether line `line` (its indices along axes first_axis.., width each) is read.
  auto line_read = [&](std::size_t line, std::size_t first_axis) {
    for (std::size_t a = first_axis; a < static_cast<std::size_t>(Dim); ++a, line /= uw)
      if (!read[a][line % uw]) return false;
    return true;
  };
  // stage[a]: axes 0..a summed (extent bs), the others still whole array lines (extent width).
  std::size_t lines = 1;
  for (int a = 1; a < Dim; ++a) lines *= uw;
  stage[0].resize(lines * ubs);  // the lines read later are written below
  // 4 or 6 where x's rows alternate between one term (even i) and that many (odd i), else 0.
  int odd_size = ubs > 1 ? st[0][1].size : 0;
  for (std::size_t i = 0; i < ubs; ++i)
    if (st[0][i].size != (i % 2 == 0 ? 1 : odd_size)) odd_size = 0;
  for (std::size_t line = 0; line < lines; ++line) {
    if (!line_read(line, 1)) continue;
    const double* row = u + line * uw;
    double* to = stage[0].data() + line * ubs;
    // Prediction rows alternate: a copy at even points, `order` terms at odd ones (fixed
    // counts the compiler unrolls); any other pattern term by term. The same sums either way.
    auto odd_rows = [&]<int kOrder>() {
      for (std::size_t i = 0; i < ubs; i += 2) to[i] = 0.0 + st[0][i].w[0] * row[st[0][i].at[0]];
      for (std::size_t i = 1; i < ubs; i += 2) {
        const AxisStencil& sx = st[0][i];
        double sum = 0;
        for (int k = 0; k < kOrder; ++k) sum += sx.w[k] * row[sx.at[k]];
        to[i] = sum;
      }
    };
    if (odd_size == 4) {
      odd_rows.template operator()<4>();
    } else if (odd_size == 6) {
      odd_rows.template operator()<6>();
    } else {
      for (std::size_t i = 0; i < ubs; ++i) {
        const AxisStencil& sx = st[0][i];
        double sum = 0;
        for (int k = 0; k < sx.size; ++k) sum += sx.w[k] * row[sx.at[k]];
        to[i] = sum;
      }
    }
  }
  const double* summed = stage[0].data();
  std::size_t done = ubs;  // values per line of the summed axes
  for (std::size_t a = 1; a < static_cast<std::size_t>(Dim); ++a) {
    // Axis a: lines of `done` contiguous values, `width` of them per outer index.
    std::size_t outer = 1;
    for (std::size_t b = a + 1; b < static_cast<std::size_t>(Dim); ++b) outer *= uw;
    std::vector<double>& next = stage[a];
    next.resize(outer * ubs * done);  // the lines read later are written below
    for (std::size_t o = 0; o < outer; ++o) {
      if (a + 1 < static_cast<std::size_t>(Dim) && !line_read(o, a + 1)) continue;  // o: the lines of axes a+1..
      for (std::size_t j = 0; j < ubs; ++j) {
        const AxisStencil& sa = st[a][j];
        double* to = next.data() + (o * ubs + j) * done;
        const double* from = summed + o * uw * done;
        // Each value's terms summed in a register, in stencil order (accumulating line by line
        // in `to` would store and reload it once per term); fixed counts for the prediction's
        // rows (a copy, or 4 or 6 terms) unroll.
        auto terms = [&]<int kTerms>(int size) {
          const int n = kTerms > 0 ? kTerms : size;
          for (std::size_t m = 0; m < done; ++m) {
            double sum = 0;
            for (int k = 0; k < n; ++k) sum += sa.w[k] * from[static_cast<std::size_t>(sa.at[k]) * done + m];
            to[m] = sum;
          }
        };
        switch (sa.size) {
          case 1: terms.template operator()<1>(1); break;
          case 4: terms.template operator()<4>(4); break;
          case 6: terms.template operator()<6>(6); break;
          default: terms.template operator()<0>(sa.size);
        }
      }
    }
    summed = next.data();
    done *= ubs;
  }
  return summed;
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
