// The narrow variable-coefficient diffusion operator of the viscous terms (fluid/ViscousTerms.hpp)
// on a periodic 1D line: 4th-order accuracy, discrete conservation, and the damping of the
// odd-even mode that nested first derivatives leave untouched; and the whole 2D block of viscous
// terms (add_block_viscous) against the exact stress divergence and its work.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "fluid/ViscousTerms.hpp"

namespace gf = grainwave::fluid;

namespace {

constexpr int kGhosts = 2;
constexpr double kTwoPi = 2 * std::numbers::pi;

/// Values of g at the n points of a periodic unit line, with kGhosts periodic images each side.
template <class G>
std::vector<double> periodic_line(int n, G g) {
  std::vector<double> v(static_cast<std::size_t>(n + 2 * kGhosts));
  for (int i = -kGhosts; i < n + kGhosts; ++i)
    v[static_cast<std::size_t>(i + kGhosts)] = g(((i % n + n) % n) / double(n));
  return v;
}

/// Largest error of d/dx(mu df/dx) against the exact one on n points.
double max_error(int n) {
  auto mu = [](double x) { return 1 + 0.5 * std::sin(kTwoPi * x + 1); };
  auto f = [](double x) { return std::cos(2 * kTwoPi * x); };
  auto exact = [](double x) {
    const double m = 1 + 0.5 * std::sin(kTwoPi * x + 1),
                 dm = 0.5 * kTwoPi * std::cos(kTwoPi * x + 1);
    const double df = -2 * kTwoPi * std::sin(2 * kTwoPi * x),
                 d2f = -4 * kTwoPi * kTwoPi * std::cos(2 * kTwoPi * x);
    return dm * df + m * d2f;
  };
  const auto m = periodic_line(n, mu), v = periodic_line(n, f);
  double error = 0;
  for (int i = 0; i < n; ++i)
    error = std::max(
        error, std::abs(gf::narrow_diffusion(m.data(), v.data(), i + kGhosts, 1, double(n) * n) -
                        exact(i / double(n))));
  return error;
}

}  // namespace

TEST(ViscousTerms, NarrowDiffusionIsFourthOrder) {
  const double e32 = max_error(32), e64 = max_error(64), e128 = max_error(128);
  EXPECT_GT(std::log2(e32 / e64), 3.8);
  EXPECT_GT(std::log2(e64 / e128), 3.9);
}

TEST(ViscousTerms, NarrowDiffusionDampsTheOddEvenMode) {
  // f = (-1)^i with constant mu: the 5-point 4th-order second derivative gives -16/3 f / h^2,
  // where nested 4th-order first derivatives give exactly 0.
  const int n = 16;
  const auto mu = periodic_line(n, [](double) { return 2.0; });
  std::vector<double> f(static_cast<std::size_t>(n + 2 * kGhosts));
  for (std::size_t i = 0; i < f.size(); ++i) f[i] = i % 2 == 0 ? 1.0 : -1.0;
  for (int i = 0; i < n; ++i)
    EXPECT_NEAR(gf::narrow_diffusion(mu.data(), f.data(), i + kGhosts, 1, 1.0) /
                    f[static_cast<std::size_t>(i + kGhosts)],
                -2.0 * 16.0 / 3.0, 1e-12);
}

TEST(ViscousTerms, NarrowDiffusionConservesOnAPeriodicLine) {
  // Its matrix is symmetric with zero row sums, so the column sums vanish too: sum_i L_i = 0 for
  // any positive mu and any f.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> positive(0.5, 2.0), any(-1.0, 1.0);
  const int n = 40;
  std::vector<double> mu(static_cast<std::size_t>(n)), f(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    mu[static_cast<std::size_t>(i)] = positive(random);
    f[static_cast<std::size_t>(i)] = any(random);
  }
  auto periodic = [&](const std::vector<double>& v) {
    return periodic_line(n,
                         [&](double x) { return v[static_cast<std::size_t>(std::lround(x * n))]; });
  };
  const auto m = periodic(mu), g = periodic(f);
  double sum = 0, scale = 0;
  for (int i = 0; i < n; ++i) {
    const double value = gf::narrow_diffusion(m.data(), g.data(), i + kGhosts, 1, 1.0);
    sum += value;
    scale += std::abs(value);
  }
  EXPECT_LE(std::abs(sum), 1e-14 * scale);
}

namespace {

/// The 2D viscous terms of one periodic block (n interior points per axis on [0, 2 pi)^2, T = 1 so
/// mu = 1, Re 1) against the exact ones for u = a sin x cos y, v = b cos x sin 2y:
///     momentum x: 4/3 u_xx + u_yy + 1/3 v_xy,   momentum y: v_xx + 4/3 v_yy + 1/3 u_xy,
///     energy: u (div tau)_x + v (div tau)_y + tau_ij d_j u_i.
/// The array has one ghost layer more than kViscousReach, filled with NaN: a stencil reaching
/// further than the header says would turn the result into NaN. Returns the largest error.
double block_viscous_error(int n) {
  constexpr int kDim = 2;
  const int g = gf::kViscousReach + 1, w = n + 2 * g;
  grainwave::wavelet::ArrayShape<kDim> shape;
  shape.extent = {w, w};
  const std::size_t volume = shape.size();
  const double h = kTwoPi / n, a = 0.3, b = 0.2, gamma = 1.4;
  std::vector<double> rho(volume, 1.0), p(volume, 1 / gamma), u(volume), v(volume);
  for (int j = 0; j < w; ++j)
    for (int i = 0; i < w; ++i) {
      const auto at = static_cast<std::size_t>(shape.index({i, j}));
      const bool outside = i == 0 || j == 0 || i == w - 1 || j == w - 1;
      const double x = (i - g) * h, y = (j - g) * h;
      u[at] = outside ? std::nan("") : a * std::sin(x) * std::cos(y);
      v[at] = outside ? std::nan("") : b * std::cos(x) * std::sin(2 * y);
    }
  std::array<std::array<std::vector<double>, kDim>, kDim> gradient;
  std::vector<double> temperature(volume), mu(volume), kinetic(volume);
  std::array<std::vector<double>, kDim + 1> flux;
  gf::ViscousBlock<kDim> block;
  block.u = {u.data(), v.data()};
  block.rho = rho.data();
  block.p = p.data();
  for (std::size_t i = 0; i < kDim; ++i)
    for (std::size_t d = 0; d < kDim; ++d) {
      gradient[i][d].assign(volume, 0.0);
      block.gradient[i][d] = gradient[i][d].data();
    }
  block.temperature = temperature.data();
  block.mu = mu.data();
  block.kinetic = kinetic.data();
  for (std::size_t f = 0; f <= kDim; ++f) {
    flux[f].assign(volume, 0.0);
    block.flux[f] = flux[f].data();
  }
  gf::ViscousSettings settings;
  settings.gamma = gamma;
  settings.reynolds = 1;
  const auto per_block = static_cast<std::size_t>(n * n);
  std::vector<double> out((kDim + 2) * per_block, 0.0);
  gf::add_block_viscous<kDim>(shape, g, n, {h, h}, settings, block, out.data());
  double error = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = i * h, y = j * h;
      const double ux = a * std::cos(x) * std::cos(y), uy = -a * std::sin(x) * std::sin(y);
      const double uxx = -a * std::sin(x) * std::cos(y), uyy = uxx, uxy = -a * std::cos(x) * std::sin(y);
      const double vx = -b * std::sin(x) * std::sin(2 * y), vy = 2 * b * std::cos(x) * std::cos(2 * y);
      const double vxx = -b * std::cos(x) * std::sin(2 * y), vyy = -4 * b * std::cos(x) * std::sin(2 * y);
      const double vxy = -2 * b * std::sin(x) * std::cos(2 * y);
      const double div_x = 4.0 / 3.0 * uxx + uyy + vxy / 3, div_y = vxx + 4.0 / 3.0 * vyy + uxy / 3;
      const double txx = 4.0 / 3.0 * ux - 2.0 / 3.0 * vy, tyy = 4.0 / 3.0 * vy - 2.0 / 3.0 * ux, txy = uy + vx;
      const double uu = a * std::sin(x) * std::cos(y), vv = b * std::cos(x) * std::sin(2 * y);
      const double energy = uu * div_x + vv * div_y + txx * ux + txy * (uy + vx) + tyy * vy;
      const auto point = static_cast<std::size_t>(j * n + i);
      const std::array<double, 3> computed{out[per_block + point], out[2 * per_block + point], out[3 * per_block + point]};
      const std::array<double, 3> exact{div_x, div_y, energy};
      for (std::size_t k = 0; k < 3; ++k) {
        if (!std::isfinite(computed[k])) return std::numeric_limits<double>::infinity();
        error = std::max(error, std::abs(computed[k] - exact[k]));
      }
    }
  return error;
}

}  // namespace

TEST(ViscousTerms, BlockTermsAreFourthOrderAndReachNoFurtherThanDeclared) {
  const double coarse = block_viscous_error(16), fine = block_viscous_error(32);
  ASSERT_TRUE(std::isfinite(coarse)) << "a stencil read the NaN layer beyond kViscousReach";
  const double order = std::log2(coarse / fine);
  EXPECT_GT(order, 3.7) << "errors " << coarse << " -> " << fine;
  // Below 1% of the velocity amplitude a = 0.3 at 32 points per 2 pi (measured 1.25e-3).
  EXPECT_LT(fine, 0.01 * 0.3) << "errors " << coarse << " -> " << fine << ", order " << order;
}
