#include "wavelet/InterpolatingWavelet.hpp"

#include <stdexcept>
#include <string>

namespace grainwave::wavelet {

void lagrange_weights(std::span<const double> nodes, double x, std::span<double> weights) {
  if (weights.size() != nodes.size()) throw std::invalid_argument("lagrange_weights: size mismatch");
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    double num = 1.0;
    double den = 1.0;
    for (std::size_t m = 0; m < nodes.size(); ++m) {
      if (m == k) continue;
      num *= x - nodes[m];
      den *= nodes[k] - nodes[m];
    }
    weights[k] = num / den;
  }
}

PredictStencil deslauriers_dubuc_stencil(int order, int odd, int n_local, bool periodic) {
  if (order < 2 || order > kMaxPredictOrder || order % 2 != 0)
    throw std::invalid_argument("Deslauriers-Dubuc order must be 2, 4 or 6, got " + std::to_string(order));
  if (odd % 2 != 1 || odd < 0 || odd >= n_local) throw std::invalid_argument("odd index out of range");
  const int n_even = periodic ? n_local / 2 : (n_local + 1) / 2;
  if (periodic && n_local % 2 != 0) throw std::invalid_argument("periodic line needs an even sample count");
  if (n_even < order)
    throw std::invalid_argument("line has " + std::to_string(n_even) + " coarse samples, order " +
                                std::to_string(order) + " needs at least that many");
  int k_first = (odd + 1) / 2 - order / 2;  // centred: order/2 evens on each side of the odd
  // One-sided near the ends; past the last even (even-length line) this extrapolates.
  if (!periodic) k_first = std::clamp(k_first, 0, n_even - order);

  PredictStencil s;
  s.size = order;
  std::array<double, kMaxPredictOrder> nodes{};
  for (int m = 0; m < order; ++m) {
    const int k = k_first + m;
    nodes[static_cast<std::size_t>(m)] = static_cast<double>(2 * k - odd);  // relative: exact dyadics
    s.even[static_cast<std::size_t>(m)] = 2 * (((k % n_even) + n_even) % n_even);
  }
  lagrange_weights(std::span<const double>(nodes.data(), static_cast<std::size_t>(order)), 0.0,
                   std::span<double>(s.weight.data(), static_cast<std::size_t>(order)));
  return s;
}

template <int Dim>
LiftingTransform<Dim>::LiftingTransform(std::array<int, Dim> extent, std::array<bool, Dim> periodic,
                                        LiftingConfig config)
    : shape_{extent}, periodic_(periodic), config_(config) {
  if (config.levels < 0) throw std::invalid_argument("LiftingTransform: negative number of levels");
  tables_.resize(static_cast<std::size_t>(config.levels * Dim));
  for (int a = 0; a < Dim; ++a) {
    const int n = extent[static_cast<std::size_t>(a)];
    const bool per = periodic[static_cast<std::size_t>(a)];
    if (n < 1 || (per && n % (1 << config.levels) != 0))
      throw std::invalid_argument("LiftingTransform: periodic extent " + std::to_string(n) + " along axis " +
                                  std::to_string(a) + " is not a multiple of 2^" + std::to_string(config.levels));
    for (int t = 0; t < config.levels; ++t) {
      LineStencils& table = tables_[static_cast<std::size_t>(t * Dim + a)];
      table.n_local = per ? n >> t : ((n - 1) >> t) + 1;
      table.order = config.order;
      const int n_odd = table.n_local / 2;
      table.even.resize(static_cast<std::size_t>(n_odd * config.order));
      table.weight.resize(table.even.size());
      for (int q = 0; q < n_odd; ++q) {
        const PredictStencil s = deslauriers_dubuc_stencil(config.order, 2 * q + 1, table.n_local, per);
        for (int m = 0; m < config.order; ++m) {
          const auto at = static_cast<std::size_t>(q * config.order + m);
          table.even[at] = s.even[static_cast<std::size_t>(m)];
          table.weight[at] = s.weight[static_cast<std::size_t>(m)];
        }
      }
    }
  }
}

template <int Dim>
template <class LineOp>
void LiftingTransform<Dim>::for_each_line(int axis, int step, LineOp&& op) const {
  // Lines along `axis` through every point of step t's grid (other coords multiples of 2^t).
  std::array<int, Dim> count{};
  std::size_t lines = 1;
  for (int b = 0; b < Dim; ++b) {
    count[static_cast<std::size_t>(b)] = b == axis ? 1 : stencils(b, step).n_local;
    lines *= static_cast<std::size_t>(count[static_cast<std::size_t>(b)]);
  }
  const int s = 1 << step;
  for (std::size_t line = 0; line < lines; ++line) {
    std::size_t rest = line;
    std::ptrdiff_t offset = 0;
    for (int b = 0; b < Dim; ++b) {
      const auto nb = static_cast<std::size_t>(count[static_cast<std::size_t>(b)]);
      offset += static_cast<std::ptrdiff_t>(rest % nb) * s * shape_.stride(b);
      rest /= nb;
    }
    op(offset);
  }
}

namespace {

// Kernels on a bundle of `width` parallel lines that sit next to each other in memory (line j
// starts at base + j). A bundle of one is a plain line; along axes > 0 at the finest step the
// bundle is a whole contiguous slab, so the j loop runs over contiguous memory and vectorises.
template <int P>
void predict_bundle(double* base, std::ptrdiff_t stride, std::ptrdiff_t width, int n_odd, const int* even,
                    const double* weight, double sign) {
  for (int q = 0; q < n_odd; ++q) {
    const int* e = even + q * P;
    const double* w = weight + q * P;
    double* detail = base + (2 * q + 1) * stride;
    std::array<const double*, P> src;
    for (int m = 0; m < P; ++m) src[static_cast<std::size_t>(m)] = base + e[m] * stride;
    for (std::ptrdiff_t j = 0; j < width; ++j) {
      double prediction = 0.0;
      for (int m = 0; m < P; ++m) prediction += w[m] * src[static_cast<std::size_t>(m)][j];
      detail[j] += sign * prediction;
    }
  }
}

template <int P>
void update_bundle(double* base, std::ptrdiff_t stride, std::ptrdiff_t width, int n_odd, const int* even,
                   const double* weight, double sign) {
  for (int q = 0; q < n_odd; ++q) {
    const int* e = even + q * P;
    const double* w = weight + q * P;
    const double* detail = base + (2 * q + 1) * stride;
    for (int m = 0; m < P; ++m) {
      double* dst = base + e[m] * stride;
      const double half_w = 0.5 * sign * w[m];
      for (std::ptrdiff_t j = 0; j < width; ++j) dst[j] += half_w * detail[j];
    }
  }
}

template <bool Predict>
void run_bundle(int order, double* base, std::ptrdiff_t stride, std::ptrdiff_t width, int n_odd, const int* even,
                const double* weight, double sign) {
  // Dispatch once per bundle so the stencil loop has a compile-time length.
  switch (order) {
    case 2: return Predict ? predict_bundle<2>(base, stride, width, n_odd, even, weight, sign)
                           : update_bundle<2>(base, stride, width, n_odd, even, weight, sign);
    case 4: return Predict ? predict_bundle<4>(base, stride, width, n_odd, even, weight, sign)
                           : update_bundle<4>(base, stride, width, n_odd, even, weight, sign);
    default: return Predict ? predict_bundle<6>(base, stride, width, n_odd, even, weight, sign)
                            : update_bundle<6>(base, stride, width, n_odd, even, weight, sign);
  }
}

}  // namespace

template <int Dim>
template <bool Predict>
void LiftingTransform<Dim>::sweep(std::span<double> data, int axis, int step, double sign) const {
  const LineStencils& s = stencils(axis, step);
  const std::ptrdiff_t stride = (std::ptrdiff_t{1} << step) * shape_.stride(axis);
  // The update skips a last odd that has no even to its right: its prediction is an
  // extrapolation with large weights, and spreading its detail would only amplify round-off.
  const int n_odd = Predict ? s.n_local / 2 : (s.n_local - 1) / 2;
  if (step == 0 && axis > 0) {
    // Every line of the finest grid: the lines through one slab of axes < axis are contiguous.
    const std::ptrdiff_t width = shape_.stride(axis);
    const std::ptrdiff_t slab = width * shape_.extent[static_cast<std::size_t>(axis)];
    const auto slabs = static_cast<std::ptrdiff_t>(shape_.size()) / slab;
    for (std::ptrdiff_t k = 0; k < slabs; ++k)
      run_bundle<Predict>(config_.order, data.data() + k * slab, stride, width, n_odd, s.even.data(),
                          s.weight.data(), sign);
    return;
  }
  for_each_line(axis, step, [&](std::ptrdiff_t offset) {
    run_bundle<Predict>(config_.order, data.data() + offset, stride, 1, n_odd, s.even.data(), s.weight.data(), sign);
  });
}

template <int Dim>
void LiftingTransform<Dim>::forward_step(std::span<double> data, int step) const {
  if (data.size() != shape_.size()) throw std::invalid_argument("LiftingTransform: data size mismatch");
  // Predict then update per axis: the update of axis a must see axis a's details only.
  for (int a = 0; a < Dim; ++a) {
    sweep<true>(data, a, step, -1.0);
    if (config_.update) sweep<false>(data, a, step, +1.0);
  }
}

template <int Dim>
void LiftingTransform<Dim>::inverse_step(std::span<double> data, int step) const {
  if (data.size() != shape_.size()) throw std::invalid_argument("LiftingTransform: data size mismatch");
  for (int a = Dim - 1; a >= 0; --a) {
    if (config_.update) sweep<false>(data, a, step, -1.0);
    sweep<true>(data, a, step, +1.0);
  }
}

template <int Dim>
void LiftingTransform<Dim>::forward(std::span<double> data) const {
  for (int t = 0; t < config_.levels; ++t) forward_step(data, t);
}

template <int Dim>
void LiftingTransform<Dim>::inverse(std::span<double> data) const {
  for (int t = config_.levels - 1; t >= 0; --t) inverse_step(data, t);
}

template class LiftingTransform<1>;
template class LiftingTransform<2>;
template class LiftingTransform<3>;

}  // namespace grainwave::wavelet
