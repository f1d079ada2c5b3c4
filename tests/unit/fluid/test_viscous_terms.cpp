// The narrow variable-coefficient diffusion operator of the viscous terms (fluid/ViscousTerms.hpp)
// on a periodic 1D line: 4th-order accuracy, discrete conservation, and the damping of the
// odd-even mode that nested first derivatives leave untouched.
#include <gtest/gtest.h>

#include <cmath>
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
