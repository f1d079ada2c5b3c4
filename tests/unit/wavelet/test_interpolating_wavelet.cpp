// Lifting transform: exact Deslauriers-Dubuc weights, perfect reconstruction, vanishing details
// for polynomials (edges included) and the 2^(-p) decay of details of smooth data per level.
#include "wavelet/InterpolatingWavelet.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

namespace gw = grainwave::wavelet;

namespace {

TEST(DeslauriersDubuc, InteriorWeightsAreTheClassicalDyadicRationals) {
  const auto s4 = gw::deslauriers_dubuc_stencil(4, 9, 33, /*periodic=*/false);
  const double w4[] = {-1.0 / 16, 9.0 / 16, 9.0 / 16, -1.0 / 16};
  const int e4[] = {6, 8, 10, 12};
  for (int m = 0; m < 4; ++m) {
    EXPECT_EQ(s4.weight[m], w4[m]);  // exact: the weights are dyadic rationals
    EXPECT_EQ(s4.even[m], e4[m]);
  }
  const auto s6 = gw::deslauriers_dubuc_stencil(6, 15, 33, false);
  const double w6[] = {3.0 / 256, -25.0 / 256, 150.0 / 256, 150.0 / 256, -25.0 / 256, 3.0 / 256};
  for (int m = 0; m < 6; ++m) {
    EXPECT_EQ(s6.weight[m], w6[m]);
    EXPECT_EQ(s6.even[m], 10 + 2 * m);
  }
}

TEST(DeslauriersDubuc, PeriodicStencilWrapsAroundTheLine) {
  const auto s = gw::deslauriers_dubuc_stencil(4, 1, 16, /*periodic=*/true);
  const int expect[] = {14, 0, 2, 4};
  for (int m = 0; m < 4; ++m) EXPECT_EQ(s.even[m], expect[m]);
  EXPECT_EQ(s.weight[0], -1.0 / 16);
}

TEST(DeslauriersDubuc, OneSidedStencilsReproducePolynomialsBelowTheOrder) {
  for (int order : {4, 6}) {
    const int n_local = 2 * order + 1;  // every odd touches an edge-adapted or central stencil
    for (int odd = 1; odd < n_local; odd += 2) {
      const auto s = gw::deslauriers_dubuc_stencil(order, odd, n_local, false);
      for (int deg = 0; deg < order; ++deg) {
        double value = 0.0;
        for (int m = 0; m < order; ++m) value += s.weight[m] * std::pow(s.even[m], deg);
        EXPECT_NEAR(value, std::pow(odd, deg), 1e-12 * std::pow(n_local, deg))
            << "order " << order << " odd " << odd << " degree " << deg;
      }
      // The one-sided stencil is genuinely shifted at the first odd: all evens lie inside the line.
      if (odd == 1) {
        EXPECT_EQ(s.even[0], 0);
      }
    }
  }
}

struct Case {
  int order;
  bool update;
  bool periodic;
};

std::vector<Case> all_cases() {
  std::vector<Case> cases;
  for (int order : {4, 6})
    for (bool update : {false, true})
      for (bool periodic : {false, true}) cases.push_back({order, update, periodic});
  return cases;
}

template <int Dim>
gw::LiftingTransform<Dim> make_transform(const Case& c, int coarse, int levels, int extra) {
  std::array<int, Dim> extent{};
  std::array<bool, Dim> periodic{};
  for (int a = 0; a < Dim; ++a) {
    // Mix periodic and non-periodic axes in multi-D so both code paths meet in one array.
    const bool per = (a % 2 == 0) ? c.periodic : !c.periodic;
    periodic[a] = per;
    extent[a] = coarse * (1 << levels) + (per ? 0 : extra);
  }
  return gw::LiftingTransform<Dim>(extent, periodic, {c.order, c.update, levels});
}

template <int Dim>
void check_perfect_reconstruction(int coarse, int levels) {
  std::mt19937 rng(1234 + Dim);
  std::uniform_real_distribution<double> dist(-1.0, 1.0);
  // extra = 1: redundant non-periodic grid (end points on every level); 2, 3: the last odd points
  // of some steps are extrapolated.
  for (const Case& c : all_cases())
    for (int extra : {1, 2, 3}) {
    const auto transform = make_transform<Dim>(c, coarse, levels, extra);
    std::vector<double> original(transform.shape().size());
    for (double& v : original) v = dist(rng);
    std::vector<double> data = original;
    transform.forward(data);
    double changed = 0.0;
    for (std::size_t i = 0; i < data.size(); ++i) changed = std::max(changed, std::abs(data[i] - original[i]));
    EXPECT_GT(changed, 0.1) << "forward left random data unchanged";
    transform.inverse(data);
    double error = 0.0;
    for (std::size_t i = 0; i < data.size(); ++i) error = std::max(error, std::abs(data[i] - original[i]));
    EXPECT_LT(error, 1e-13) << Dim << "D order " << c.order << " update " << c.update << " periodic "
                            << c.periodic << " extra " << extra;
  }
}

TEST(LiftingTransform, PerfectReconstruction1D) { check_perfect_reconstruction<1>(8, 4); }
TEST(LiftingTransform, PerfectReconstruction2D) { check_perfect_reconstruction<2>(8, 2); }
TEST(LiftingTransform, PerfectReconstruction3D) { check_perfect_reconstruction<3>(8, 1); }

TEST(LiftingTransform, RejectsExtentsThatDoNotCoarsen) {
  using T = gw::LiftingTransform<1>;
  EXPECT_THROW(T({30}, {true}, {4, false, 2}), std::invalid_argument);   // 30 not a multiple of 4
  EXPECT_THROW(T({17}, {false}, {6, false, 2}), std::invalid_argument);  // only 5 coarse points
  EXPECT_NO_THROW(T({32}, {false}, {4, false, 2}));  // non-periodic: any extent with enough evens
}

// Tensor-product polynomial of degree order-1 per axis (non-periodic axes only: a polynomial is
// not periodic). Every detail, including those next to the edges, must vanish to round-off.
template <int Dim>
void check_polynomial_details_vanish() {
  for (int order : {4, 6})
    for (bool update : {false, true})
      for (int extra : {1, 2}) {  // odd extent (redundant grid) and even extent (extrapolated end)
      const int levels = 2;
      std::array<int, Dim> extent{};
      std::array<bool, Dim> periodic{};
      extent.fill(8 * (1 << levels) + extra);
      const gw::LiftingTransform<Dim> transform(extent, periodic, {order, update, levels});
      const auto& shape = transform.shape();
      std::vector<double> data(shape.size());
      std::vector<double> original(shape.size());
      const double h = 1.0 / (extent[0] - 1);
      for (std::size_t idx = 0; idx < data.size(); ++idx) {
        const auto i = shape.coords(static_cast<std::ptrdiff_t>(idx));
        double value = 0.5;
        for (int a = 0; a < Dim; ++a) {
          const double x = i[a] * h - 0.3 * a;
          value += std::pow(x, order - 1) * (1.0 + a) - 2.0 * x * x + std::pow(x, order - 1 - a);
        }
        data[idx] = original[idx] = value;
      }
      transform.forward(data);
      double max_detail = 0.0;
      int n_details = 0;
      for (std::size_t idx = 0; idx < data.size(); ++idx) {
        const auto i = shape.coords(static_cast<std::ptrdiff_t>(idx));
        if (transform.detail_step(i) == levels) {
          // Zero details mean the update step changes nothing: coarse values are the samples.
          EXPECT_NEAR(data[idx], original[idx], 1e-12);
          continue;
        }
        max_detail = std::max(max_detail, std::abs(data[idx]));
        ++n_details;
      }
      EXPECT_GT(n_details, 0);
      EXPECT_LT(max_detail, 1e-12) << Dim << "D order " << order << " update " << update << " extent "
                                   << extent[0];
    }
}

TEST(LiftingTransform, PolynomialDetailsVanish1D) { check_polynomial_details_vanish<1>(); }
TEST(LiftingTransform, PolynomialDetailsVanish2D) { check_polynomial_details_vanish<2>(); }
TEST(LiftingTransform, PolynomialDetailsVanish3D) { check_polynomial_details_vanish<3>(); }

// Details of a smooth function at step t scale as (2^t h)^p: the largest detail grows by 2^p per
// coarser step. The measured order is log2(max|d_{t+1}| / max|d_t|).
template <int Dim>
std::vector<double> max_detail_per_step(int order, bool update, bool periodic, int n_fine, int levels) {
  std::array<int, Dim> extent{};
  std::array<bool, Dim> per{};
  extent.fill(n_fine + (periodic ? 0 : 1));
  per.fill(periodic);
  const gw::LiftingTransform<Dim> transform(extent, per, {order, update, levels});
  const auto& shape = transform.shape();
  std::vector<double> data(shape.size());
  const double h = 1.0 / n_fine;
  for (std::size_t idx = 0; idx < data.size(); ++idx) {
    const auto i = shape.coords(static_cast<std::ptrdiff_t>(idx));
    double arg = 0.0;
    for (int a = 0; a < Dim; ++a) arg += i[a] * h;
    data[idx] = std::exp(std::sin(2.0 * std::numbers::pi * arg));
  }
  transform.forward(data);
  std::vector<double> max_detail(static_cast<std::size_t>(levels), 0.0);
  for (std::size_t idx = 0; idx < data.size(); ++idx) {
    const int t = transform.detail_step(shape.coords(static_cast<std::ptrdiff_t>(idx)));
    if (t < levels) max_detail[t] = std::max(max_detail[t], std::abs(data[idx]));
  }
  return max_detail;
}

template <int Dim>
void check_detail_decay(int n_fine, int levels, int steps_checked) {
  for (int order : {4, 6})
    for (bool update : {false, true})
      for (bool periodic : {true, false}) {
        const auto d = max_detail_per_step<Dim>(order, update, periodic, n_fine, levels);
        for (int t = 0; t < steps_checked; ++t) {
          const double measured = std::log2(d[t + 1] / d[t]);
          std::printf("  %dD p=%d update=%d periodic=%d step %d->%d: order %.3f\n", Dim, order, update,
                      periodic, t, t + 1, measured);
          EXPECT_NEAR(measured, order, 0.2) << Dim << "D order " << order << " update " << update
                                            << " periodic " << periodic << " step " << t << ": "
                                            << d[t] << " -> " << d[t + 1];
        }
      }
}

TEST(LiftingTransform, SmoothDetailsDecayAtTheOrder1D) { check_detail_decay<1>(1024, 5, 3); }
TEST(LiftingTransform, SmoothDetailsDecayAtTheOrder2D) { check_detail_decay<2>(512, 4, 2); }

}  // namespace
