#include "wavelet/DetailKernels.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <type_traits>

#include "core/KernelClones.hpp"

// The kernels are cloned up to AVX2 (core/KernelClones.hpp), and the 2D detail maxima up to
// AVX-512F: only they gained from 512-bit vectors in bench_wavelet's BM_LargestDetails (6-30 %
// less time, the most on 8^2 blocks); the 3D ones lost 2-6 %.

namespace grainwave::wavelet {

namespace {

/// kernel(std::integral_constant<int, B>{}) with B = bs where bs is one of kSizes, the common
/// block sizes a kernel is compiled for (their short rows unroll), B = 0 (any size) otherwise.
template <int... kSizes, class Kernel>
decltype(auto) with_block_size(int bs, Kernel&& kernel) {
  using Result = decltype(kernel(std::integral_constant<int, 0>{}));
  Result result{};
  const bool known = ((bs == kSizes && (result = kernel(std::integral_constant<int, kSizes>{}), true)) || ...);
  return known ? result : kernel(std::integral_constant<int, 0>{});
}

/// Four doubles in GCC's vector types: selects on them become packed min/max (left to the
/// auto-vectoriser, lanes kept in arrays stayed scalar, with stack spills). The helpers passing
/// them by value live in this file's anonymous namespace and are inlined into the cloned
/// kernels (flatten), so the ABI GCC warns about for the baseline clone is never crossed.
#pragma GCC diagnostic ignored "-Wpsabi"
typedef double Lanes __attribute__((vector_size(4 * sizeof(double))));
typedef long long LaneBits __attribute__((vector_size(4 * sizeof(long long))));  // Lanes' bits
/// Eight doubles, for the 2D maxima's second stage: one register in the AVX-512 clone, two (or
/// four) operations of the same lanes' arithmetic in the others.
typedef double WideLanes __attribute__((vector_size(8 * sizeof(double))));
typedef long long WideLaneBits __attribute__((vector_size(8 * sizeof(long long))));

/// V (a double or Lanes) from / to possibly unaligned memory.
template <class V>
V load(const double* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V>
void store(double* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}

/// |v| (v a double or Lanes) by clearing the sign bits: one AND where `v < 0 ? -v : v` took a
/// compare, an XOR and a blend. The maxima below only ask `>` of the magnitudes, to which the
/// sign of a zero or of a NaN makes no difference, so they come out bitwise the same.
template <class V>
V magnitude_of(const V& v) {
  if constexpr (std::is_same_v<V, double>) {
    return std::abs(v);
  } else {
    using Bits = std::conditional_t<sizeof(V) == sizeof(LaneBits), LaneBits, WideLaneBits>;
    static_assert(sizeof(V) == sizeof(Bits));
    constexpr long long kAllButSign = 0x7fffffffffffffffLL;
    return std::bit_cast<V>(std::bit_cast<Bits>(v) & (Bits{} + kAllButSign));
  }
}

// The 2D second stage takes eight lanes at a time only where WideLanes is one register
// (cpu_has_avx512f), on rows of 16 or more (BM_LargestDetails 2D, medians of five, three
// alternating rounds: 16^2 blocks 0.012 -> 0.010-0.011 ms, 32^2 0.010-0.012 -> 0.008-0.009 ms;
// 8^2 ones lost, 0.019-0.021 -> 0.021-0.022 ms: one group of lanes per row leaves its maxima one
// dependent chain). Elsewhere each of its operations would be two or four, with twice the
// registers held, so the four-lane form stays.

template <int Dim, int kOrder, int kBlockSize>
DetailMaxima maxima(const double* u, const DetailRows<Dim>& rows, double* along_x, double* last) {
  // The prediction and the maxima in one pass: along x the prediction is taken at every index with
  // the centred offsets (a contiguous loop), the evens selected as copies, then the one-sided
  // rows overwritten by their own sums; along y (and z) each line of the previous stage is read
  // at the centred line offsets, or at the row's own, four lanes at a time where the block size
  // allows; the last axis's predictions go straight into the maxima.
  // kBlockSize > 0: the block size the caller has, known here so that the compiler unrolls the
  // short lines and keeps the lanes in registers; 0: any block size.
  const std::size_t ubs = kBlockSize > 0 ? static_cast<std::size_t>(kBlockSize) : static_cast<std::size_t>(rows.block_size);
  const auto ug = static_cast<std::size_t>(rows.ghosts);
  const std::size_t uw = ubs + 2 * ug;
  std::array<double, kOrder> w{};
  for (std::size_t m = 0; m < w.size(); ++m) w[m] = rows.centred_weights[m];
  // The odd x indices whose rows are not centred (a few near a bounded edge, none elsewhere).
  std::array<std::size_t, kMaxBlockSize> one_sided{};
  std::size_t one_sided_count = 0;
  for (std::size_t i = 0; i < ubs; ++i)
    if (!rows.centred[0][i]) one_sided[one_sided_count++] = i;
  // Odd index i reads i + g + 2m - (kOrder - 1): from `first` on, every other point.
  const std::size_t first = ug - static_cast<std::size_t>(kOrder - 1);
  const auto& near = rows.near;
  std::array<double, kMaxBlockSize> all{}, inner{}, magnitude{}, row_mask{};
  for (std::size_t i = 0; i < ubs; ++i) row_mask[i] = near[0][i] ? 1.0 : 0.0;
  // |u - P u| of a group of lanes m.. (V: one double, or Lanes) into its maxima top, top_near,
  // and |u| into top_u (selects: NaN lanes, which the absolute value keeps NaN, are ignored as
  // std::max over the coefficients would; the near maximum leaves out lines and lanes whose rows
  // are not all near, by selects, so an unread NaN cannot get through).
  auto fold = [&]<class V>(std::size_t m, V& top, V& top_near, V& top_u, const double* u_line, const V& predicted,
                           bool near_line) {
    const V zero{};
    const V value = load<V>(u_line + m);
    const V size = magnitude_of(value);
    top_u = size > top_u ? size : top_u;
    V d = value - predicted;
    d = magnitude_of(d);
    top = d > top ? d : top;
    const V dn = near_line ? (load<V>(row_mask.data() + m) != 0 ? d : zero) : zero;
    top_near = dn > top_near ? dn : top_near;
  };
  auto predict_line = [&](const double* row, double* to) {
    const double* at = row + first;
    // Evens are copies: selected in the same vector, not stored over it (a narrower store over
    // a wider one stalls the next stage's wide reads of it).
    for (std::size_t i = 0; i < ubs; ++i) {
      double sum = 0;
      for (std::size_t m = 0; m < w.size(); ++m) sum += w[m] * at[i + 2 * m];
      to[i] = i % 2 == 0 ? 0.0 + row[ug + i] : sum;
    }
    for (std::size_t k = 0; k < one_sided_count; ++k) {
      const AxisStencil& st = rows.axis[0][one_sided[k]];
      double sum = 0;
      for (int m = 0; m < st.size; ++m) sum += st.w[static_cast<std::size_t>(m)] * row[st.at[static_cast<std::size_t>(m)]];
      to[one_sided[k]] = sum;
    }
  };
  // Lines later stages read: even array index + g on every axis beyond x (block starts are even).
  auto even_line = [&](std::size_t r) { return (r + ug) % 2 == 0; };
  if constexpr (Dim == 1) {
    predict_line(u, along_x);
    for (std::size_t i = 0; i < ubs; ++i) fold(i, all[i], inner[i], magnitude[i], u + ug, along_x[i], true);
  } else {
    for (std::size_t z = 0; z < (Dim == 3 ? uw : 1); ++z) {
      if (Dim == 3 && !even_line(z)) continue;
      for (std::size_t y = 0; y < uw; ++y)
        if (even_line(y)) predict_line(u + (z * uw + y) * uw, along_x + (z * uw + y) * ubs);
    }
    // The prediction along axis a at index j, lanes m_begin..m_end of the previous stage's lines
    // (`from`: array index 0 along that axis, `stride` values apart), a group of V's lanes at a
    // time (V: one double, or Lanes) handed to sink(m, value) as it is computed: the last axis
    // folds them straight into the maxima (storing a line of them to fold it would stall on
    // reading it back). Each lane's sum is the scalar one, term for term.
    auto predict_across = [&]<class V>(std::size_t a, const double* from, std::size_t j, std::size_t stride,
                                       std::size_t m_begin, std::size_t m_end, auto&& sink) {
      constexpr std::size_t kLanes = sizeof(V) / sizeof(double);
      if (!rows.centred[a][j]) {
        const AxisStencil& st = rows.axis[a][j];
        for (std::size_t m = m_begin; m < m_end; m += kLanes) {
          V sum{};
          for (int k = 0; k < st.size; ++k)
            sum += st.w[static_cast<std::size_t>(k)] *
                   load<V>(from + static_cast<std::size_t>(st.at[static_cast<std::size_t>(k)]) * stride + m);
          sink(m, sum);
        }
        return;
      }
      if (j % 2 == 0) {
        const double* src = from + (j + ug) * stride;
        for (std::size_t m = m_begin; m < m_end; m += kLanes) sink(m, load<V>(src + m) + 0.0);
        return;
      }
      const double* src = from + (first + j) * stride;
      for (std::size_t m = m_begin; m < m_end; m += kLanes) {
        V sum{};
        for (std::size_t k = 0; k < w.size(); ++k) sum += w[k] * load<V>(src + 2 * k * stride + m);
        sink(m, sum);
      }
    };
    auto stages = [&]<class V>() {
      constexpr std::size_t kLanes = sizeof(V) / sizeof(double);
      if constexpr (Dim == 2) {
        // A group's maxima stay in registers over all its lines.
        for (std::size_t m0 = 0; m0 < ubs; m0 += kLanes) {
          V top{}, top_near{}, top_u{};
          for (std::size_t j = 0; j < ubs; ++j) {
            const double* u_line = u + (j + ug) * uw + ug;
            predict_across.template operator()<V>(1, along_x, j, ubs, m0, m0 + kLanes, [&](std::size_t m, const V& p) {
              fold(m, top, top_near, top_u, u_line, p, near[1][j]);
            });
          }
          store(all.data() + m0, top);
          store(inner.data() + m0, top_near);
          store(magnitude.data() + m0, top_u);
        }
      } else {
        // Along y on the x-predicted lines of even z (planes of bs^2 after `last`'s first bs^2),
        // then along z line by line into the maxima (a group over a whole plane reads too far
        // apart: slower on 32^3 blocks).
        double* along_y = last + ubs * ubs;
        for (std::size_t z = 0; z < uw; ++z) {
          if (!even_line(z)) continue;
          for (std::size_t j = 0; j < ubs; ++j) {
            double* to = along_y + (z * ubs + j) * ubs;
            predict_across.template operator()<V>(1, along_x + z * uw * ubs, j, ubs, 0, ubs,
                                                  [&](std::size_t m, const V& p) { store(to + m, p); });
          }
        }
        for (std::size_t k = 0; k < ubs; ++k)
          for (std::size_t j = 0; j < ubs; ++j) {
            const double* u_line = u + ((k + ug) * uw + j + ug) * uw + ug;
            const bool near_line = near[1][j] && near[2][k];
            predict_across.template operator()<V>(2, along_y + j * ubs, k, ubs * ubs, 0, ubs, [&](std::size_t m, const V& p) {
              V top = load<V>(all.data() + m), top_near = load<V>(inner.data() + m), top_u = load<V>(magnitude.data() + m);
              fold(m, top, top_near, top_u, u_line, p, near_line);
              store(all.data() + m, top);
              store(inner.data() + m, top_near);
              store(magnitude.data() + m, top_u);
            });
          }
      }
    };
    if (Dim == 2 && ubs % 8 == 0 && ubs >= 16 && cpu_has_avx512f()) stages.template operator()<WideLanes>();
    else if (ubs % 4 == 0) stages.template operator()<Lanes>();
    else stages.template operator()<double>();
  }
  DetailMaxima found;
  for (std::size_t i = 0; i < ubs; ++i) {
    found.largest = std::max(found.largest, all[i]);
    found.largest_near = std::max(found.largest_near, inner[i]);
    found.magnitude = std::max(found.magnitude, magnitude[i]);
  }
  return found;
}

}  // namespace

namespace {

/// Smallest and largest of u[0 .. n), NaNs passed over (the selects `v < lo ? v : lo` keep lo
/// where v is NaN), starting from u[0] (a NaN there stays). Four groups of lanes, four
/// independent chains of selects (one group waited on each select's latency), the last group of
/// a length not a multiple of four overlapping the one before (a value met twice changes no
/// extreme). Named groups: kept in an array, the lanes went through the stack (see Lanes).
std::pair<double, double> range_in_lanes(const double* u, std::size_t n) {
  const Lanes first = {u[0], u[0], u[0], u[0]};
  Lanes lo0 = first, lo1 = first, lo2 = first, lo3 = first, hi0 = first, hi1 = first, hi2 = first, hi3 = first;
  auto take = [](const double* at, Lanes& lo, Lanes& hi) {
    const auto v = load<Lanes>(at);
    lo = v < lo ? v : lo;
    hi = v > hi ? v : hi;
  };
  std::size_t k = 0;
  for (; k + 16 <= n; k += 16) {
    take(u + k, lo0, hi0);
    take(u + k + 4, lo1, hi1);
    take(u + k + 8, lo2, hi2);
    take(u + k + 12, lo3, hi3);
  }
  if (k + 4 <= n) take(u + k, lo0, hi0), k += 4;
  if (k + 4 <= n) take(u + k, lo1, hi1), k += 4;
  if (k + 4 <= n) take(u + k, lo2, hi2), k += 4;
  if (k < n && n >= 4) take(u + n - 4, lo3, hi3), k = n;
  for (; k < n; ++k) {  // fewer than four values in all
    lo0[0] = u[k] < lo0[0] ? u[k] : lo0[0];
    hi0[0] = u[k] > hi0[0] ? u[k] : hi0[0];
  }
  double low = u[0], high = u[0];
  for (int l = 0; l < 4; ++l) {
    low = std::min({low, lo0[l], lo1[l], lo2[l], lo3[l]});  // a NaN low (u[0]) stays: nothing is below it
    high = std::max({high, hi0[l], hi1[l], hi2[l], hi3[l]});
  }
  return {low, high};
}

}  // namespace

GRAINWAVE_CLONES_AVX2 std::pair<double, double> value_range(const double* u, std::size_t n) {
  return range_in_lanes(u, n);
}

namespace {

/// interior_largest_magnitude for block size kBlockSize (0: any, see with_block_size).
template <int kBlockSize>
double largest_magnitude(const double* u, int dim, int bs, int g) {
  const auto ubs = kBlockSize > 0 ? static_cast<std::size_t>(kBlockSize) : static_cast<std::size_t>(bs);
  const auto ug = static_cast<std::size_t>(g), uw = ubs + 2 * ug;
  const std::size_t planes = dim == 3 ? ubs : 1, lines = dim >= 2 ? ubs : 1;
  // Two groups of lanes, two independent chains of selects (NaN lanes keep the old value).
  Lanes top0 = {0, 0, 0, 0}, top1 = top0;
  double largest = 0;
  for (std::size_t k = 0; k < planes; ++k)
    for (std::size_t j = 0; j < lines; ++j) {
      const double* row = u + ((dim == 3 ? (k + ug) * uw : 0) + (dim >= 2 ? j + ug : 0)) * uw + ug;
      std::size_t i = 0;
      for (; i + 8 <= ubs; i += 8) {
        const Lanes a = magnitude_of(load<Lanes>(row + i)), b = magnitude_of(load<Lanes>(row + i + 4));
        top0 = a > top0 ? a : top0;
        top1 = b > top1 ? b : top1;
      }
      for (; i + 4 <= ubs; i += 4) {
        const Lanes a = magnitude_of(load<Lanes>(row + i));
        top0 = a > top0 ? a : top0;
      }
      for (; i < ubs; ++i) {
        const double v = std::abs(row[i]);
        largest = v > largest ? v : largest;
      }
    }
  for (int l = 0; l < 4; ++l) largest = std::max({largest, top0[l], top1[l]});
  return largest;
}

}  // namespace

GRAINWAVE_CLONES_AVX2 double interior_largest_magnitude(const double* u, int dim, int bs, int g) {
  // The same comparisons in the same order whichever is compiled: the same maximum.
  return with_block_size<8, 16, 32>(bs, [&](auto size) { return largest_magnitude<decltype(size)::value>(u, dim, bs, g); });
}

namespace {

/// block_extent for block size kBlockSize (0: any): the range over the whole array, which is
/// contiguous, as value_range takes it, then largest_magnitude over the interior, just read (in
/// cache up to 16^3-point arrays). Minimum, maximum and the largest magnitude are exact whatever
/// the order, so they are those of the two functions (of +0 and -0 the range keeps whichever
/// came first).
template <int kBlockSize>
BlockExtent extent(const double* u, int dim, int bs, int g) {
  const auto ubs = kBlockSize > 0 ? static_cast<std::size_t>(kBlockSize) : static_cast<std::size_t>(bs);
  const auto ug = static_cast<std::size_t>(g), uw = ubs + 2 * ug;
  std::size_t n = uw;
  for (int a = 1; a < dim; ++a) n *= uw;
  const auto [low, high] = range_in_lanes(u, n);
  const double largest = largest_magnitude<kBlockSize>(u, dim, bs, g);
  return {low, high, largest};
}

}  // namespace

GRAINWAVE_CLONES_AVX2 BlockExtent block_extent(const double* u, int dim, int bs, int g) {
  return with_block_size<8, 16, 32>(bs, [&](auto size) { return extent<decltype(size)::value>(u, dim, bs, g); });
}

namespace {

/// The kernel for the block size and order at hand: the common block sizes compiled for their
/// size, the others for any. (Not 8: compiled for it, the 2D maxima took 30% more instructions
/// on the 8^2 blocks of two_cylinders.toml than the general loop.)
template <int Dim>
DetailMaxima dispatch(const double* u, const DetailRows<Dim>& rows, double* along_x, double* last) {
  return with_block_size<16, 32>(rows.block_size, [&](auto size) {
    constexpr int kSize = decltype(size)::value;
    return rows.order == 4 ? maxima<Dim, 4, kSize>(u, rows, along_x, last) : maxima<Dim, 6, kSize>(u, rows, along_x, last);
  });
}

}  // namespace

GRAINWAVE_CLONES_AVX2 DetailMaxima block_detail_maxima(const double* u, const DetailRows<1>& rows,
                                                                      double* along_x, double* last) {
  return dispatch<1>(u, rows, along_x, last);
}

GRAINWAVE_CLONES_AVX512 DetailMaxima block_detail_maxima(const double* u, const DetailRows<2>& rows,
                                                                      double* along_x, double* last) {
  return dispatch<2>(u, rows, along_x, last);
}

GRAINWAVE_CLONES_AVX2 DetailMaxima block_detail_maxima(const double* u, const DetailRows<3>& rows,
                                                                      double* along_x, double* last) {
  return dispatch<3>(u, rows, along_x, last);
}

}  // namespace grainwave::wavelet
