// Derivative stencils: classical central weights, and measured convergence orders (32 -> 256
// points) of first, second and mixed derivatives, closure rows included, in 1D, 2D and 3D.
#include "wavelet/Stencils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace gw = grainwave::wavelet;

namespace {

TEST(FiniteDifferenceWeights, CentralRowsMatchTheClassicalWeights) {
  const double nodes4[] = {-2, -1, 0, 1, 2};
  double w[5];
  gw::finite_difference_weights(nodes4, 0.0, 1, w);
  const double d1_o4[] = {1.0 / 12, -2.0 / 3, 0.0, 2.0 / 3, -1.0 / 12};
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(w[k], d1_o4[k], 1e-15);
  gw::finite_difference_weights(nodes4, 0.0, 2, w);
  const double d2_o4[] = {-1.0 / 12, 4.0 / 3, -5.0 / 2, 4.0 / 3, -1.0 / 12};
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(w[k], d2_o4[k], 1e-15);
  const double nodes6[] = {-3, -2, -1, 0, 1, 2, 3};
  double w6[7];
  gw::finite_difference_weights(nodes6, 0.0, 2, w6);
  const double d2_o6[] = {1.0 / 90, -3.0 / 20, 3.0 / 2, -49.0 / 18, 3.0 / 2, -3.0 / 20, 1.0 / 90};
  for (int k = 0; k < 7; ++k) EXPECT_NEAR(w6[k], d2_o6[k], 1e-14);
}

TEST(FiniteDifferenceWeights, OneSidedRowIsExactForPolynomialsOfItsDegree) {
  const double nodes[] = {0, 1, 2, 3, 4, 5, 6, 7};  // 6th-order second derivative at the edge
  double w[8];
  gw::finite_difference_weights(nodes, 0.0, 2, w);
  for (int degree = 0; degree < 8; ++degree) {
    double value = 0.0;
    for (int k = 0; k < 8; ++k) value += w[k] * std::pow(nodes[k], degree);
    EXPECT_NEAR(value, degree == 2 ? 2.0 : 0.0, 1e-9 * std::pow(7.0, degree)) << "degree " << degree;
  }
}

// Smooth test field sin(w x + 0.8) sin(w y + 0.8) sin(w z + 0.8) and its derivatives. w = 6 keeps
// the 6th-order errors on fine grids above round-off (~1e-16 / h^2) while 32 points are already
// in the asymptotic range; the phase keeps every derivative away from zero at both edges (no
// accidental cancellation of the leading error term in the closure rows).
constexpr double kOmega = 6.0;
constexpr double kPhase = 0.8;
double wave(double x, int derivative) {
  const double t = kOmega * x + kPhase;
  switch (derivative) {
    case 0: return std::sin(t);
    case 1: return kOmega * std::cos(t);
    default: return -kOmega * kOmega * std::sin(t);
  }
}
double field(double x, double y, double z) { return wave(x, 0) * wave(y, 0) * wave(z, 0); }

enum class Quantity { kFirstX, kSecondX, kFirstY, kSecondY, kFirstZ, kMixedXY, kMixedXZ };

double exact(Quantity q, double x, double y, double z) {
  switch (q) {
    case Quantity::kFirstX: return wave(x, 1) * wave(y, 0) * wave(z, 0);
    case Quantity::kSecondX: return wave(x, 2) * wave(y, 0) * wave(z, 0);
    case Quantity::kFirstY: return wave(x, 0) * wave(y, 1) * wave(z, 0);
    case Quantity::kSecondY: return wave(x, 0) * wave(y, 2) * wave(z, 0);
    case Quantity::kFirstZ: return wave(x, 0) * wave(y, 0) * wave(z, 1);
    case Quantity::kMixedXY: return wave(x, 1) * wave(y, 1) * wave(z, 0);
    case Quantity::kMixedXZ: return wave(x, 1) * wave(y, 0) * wave(z, 1);
  }
  return 0.0;
}

struct Errors {
  double all = 0.0;      // every interior point
  double closure = 0.0;  // points within accuracy/2 of a one-sided edge
};

// Block of n^Dim points on [0,1]^Dim. Ghosts on one-sided sides hold NaN: a closure row that
// reached into them would poison the error.
template <int Dim>
Errors block_error(int n, int accuracy, const gw::DerivativeConfig& base, Quantity q) {
  gw::DerivativeConfig config = base;
  config.accuracy = accuracy;
  gw::BlockLayout<Dim> layout;
  layout.interior.fill(n);
  layout.ghosts = 3;
  const double h = 1.0 / (n - 1);
  std::array<double, Dim> spacing;
  spacing.fill(h);
  const gw::DerivativeOperator<Dim> op(layout, spacing, config);
  const auto shape = layout.shape();
  std::vector<double> u(shape.size()), out(shape.size(), 0.0);
  for (std::size_t idx = 0; idx < u.size(); ++idx) {
    const auto c = shape.coords(static_cast<std::ptrdiff_t>(idx));
    std::array<double, 3> x{};
    bool nan_ghost = false;
    for (int a = 0; a < Dim; ++a) {
      const int i = c[a] - layout.ghosts;
      x[a] = i * h;
      if ((i < 0 && config.one_sided[a][0]) || (i >= n && config.one_sided[a][1])) nan_ghost = true;
    }
    u[idx] = nan_ghost ? std::numeric_limits<double>::quiet_NaN() : field(x[0], x[1], x[2]);
  }
  switch (q) {
    case Quantity::kFirstX: op.first(u, out, 0); break;
    case Quantity::kSecondX: op.second(u, out, 0); break;
    case Quantity::kFirstY: op.first(u, out, 1); break;
    case Quantity::kSecondY: op.second(u, out, 1); break;
    case Quantity::kFirstZ: op.first(u, out, 2); break;
    case Quantity::kMixedXY: op.mixed(u, out, 0, 1); break;
    case Quantity::kMixedXZ: op.mixed(u, out, 0, 2); break;
  }
  Errors e;
  const int r = accuracy / 2;
  const gw::ArrayShape<Dim> interior{layout.interior};
  for (std::size_t p = 0; p < interior.size(); ++p) {
    const auto i = interior.coords(static_cast<std::ptrdiff_t>(p));
    std::array<double, 3> x{};
    bool near_edge = false;
    for (int a = 0; a < Dim; ++a) {
      x[a] = i[a] * h;
      near_edge |= (i[a] < r && config.one_sided[a][0]) || (i[a] >= n - r && config.one_sided[a][1]);
    }
    const double err = std::abs(out[static_cast<std::size_t>(layout.index(i))] - exact(q, x[0], x[1], x[2]));
    e.all = std::max(e.all, std::isnan(err) ? 1e300 : err);
    if (near_edge) e.closure = std::max(e.closure, std::isnan(err) ? 1e300 : err);
  }
  return e;
}

// Round-off floor of a derivative: eps * max|u| * sum|w| / h^m for the widest (one-sided) row.
double round_off_floor(int derivative, int accuracy, double h) {
  std::vector<double> nodes(static_cast<std::size_t>(accuracy + derivative)), w(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) nodes[k] = static_cast<double>(k);
  gw::finite_difference_weights(nodes, 0.0, derivative, w);
  double sum = 0.0;
  for (double v : w) sum += std::abs(v);
  return std::numeric_limits<double>::epsilon() * std::exp(0.5) * sum / std::pow(h, derivative);
}

// Orders between successive grids, for all points and for the closure rows alone. Pairs whose
// finer error is under 10x the round-off floor (the 6th-order rows on 256 points: eps / h^2 times
// sum|w| ~ 200) are printed, not asserted. Of the remaining pairs, the finest must be within 0.2
// of the scheme's order. Coarser pairs need only be >= order - 1: on 32 points (w h ~ 0.19) the
// one-sided rows are not yet asymptotic; their O(w h) correction to the leading error term halves
// per refinement, which the finest-pair check then sees (e.g. 5.13 -> 5.73 -> 5.88 for a 6th-order
// first derivative on the low edge). A closure one order too low fails the finest-pair check.
template <int Dim>
void check_convergence(const char* name, const gw::DerivativeConfig& config, Quantity q, int derivative,
                       std::vector<int> sizes, bool has_closure) {
  for (int accuracy : {2, 4, 6}) {
    std::vector<Errors> errors;
    for (int n : sizes) errors.push_back(block_error<Dim>(n, accuracy, config, q));
    std::vector<std::array<double, 2>> asserted;  // (order all, order closure) above round-off
    for (std::size_t k = 0; k + 1 < sizes.size(); ++k) {
      const double ratio = std::log2(static_cast<double>(sizes[k + 1] - 1) / (sizes[k] - 1));
      const double order_all = std::log2(errors[k].all / errors[k + 1].all) / ratio;
      const double order_closure =
          has_closure ? std::log2(errors[k].closure / errors[k + 1].closure) / ratio : order_all;
      const double floor = round_off_floor(derivative, accuracy, 1.0 / (sizes[k + 1] - 1));
      const bool above_round_off = errors[k + 1].all > 10.0 * floor &&
                                   (!has_closure || errors[k + 1].closure > 10.0 * floor);
      std::printf("  %s acc %d n %d->%d: error %.3e order %.3f", name, accuracy, sizes[k] - 1,
                  sizes[k + 1] - 1, errors[k + 1].all, order_all);
      if (has_closure) std::printf(" | closure rows %.3f", order_closure);
      std::printf("%s\n", above_round_off ? "" : "  (round-off limited, not asserted)");
      if (above_round_off) asserted.push_back({order_all, order_closure});
    }
    ASSERT_FALSE(asserted.empty()) << name << " accuracy " << accuracy << ": every pair round-off limited";
    for (const auto& [order_all, order_closure] : asserted) {
      EXPECT_GE(order_all, accuracy - 1.0) << name << " accuracy " << accuracy;
      EXPECT_GE(order_closure, accuracy - 1.0) << name << " closure, accuracy " << accuracy;
    }
    EXPECT_NEAR(asserted.back()[0], accuracy, 0.2) << name << " accuracy " << accuracy << ", finest pair";
    EXPECT_NEAR(asserted.back()[1], accuracy, 0.2) << name << " closure, accuracy " << accuracy << ", finest pair";
  }
}

gw::DerivativeConfig one_sided_on(std::initializer_list<std::pair<int, int>> sides) {
  gw::DerivativeConfig c;
  for (auto [axis, side] : sides) c.one_sided[axis][side] = true;
  return c;
}

const std::vector<int> kSizes{33, 65, 129, 257};  // 32 -> 256 intervals

TEST(DerivativeConvergence, FirstDerivative1DWithClosures) {
  check_convergence<1>("d/dx 1D", one_sided_on({{0, 0}, {0, 1}}), Quantity::kFirstX, 1, kSizes, true);
}
TEST(DerivativeConvergence, SecondDerivative1DWithClosures) {
  check_convergence<1>("d2/dx2 1D", one_sided_on({{0, 0}, {0, 1}}), Quantity::kSecondX, 2, kSizes, true);
}
TEST(DerivativeConvergence, CentralRowsWithGhosts1D) {
  check_convergence<1>("d/dx ghosts", {}, Quantity::kFirstX, 1, kSizes, false);
  check_convergence<1>("d2/dx2 ghosts", {}, Quantity::kSecondX, 2, kSizes, false);
}
TEST(DerivativeConvergence, Derivatives2DAlongY) {
  const auto config = one_sided_on({{1, 0}});
  check_convergence<2>("d/dy 2D", config, Quantity::kFirstY, 1, kSizes, true);
  check_convergence<2>("d2/dy2 2D", config, Quantity::kSecondY, 2, kSizes, true);
}
TEST(DerivativeConvergence, Mixed2DWithClosureCorner) {
  // Low-x and high-y edges one-sided: the corner rows combine two one-sided rows.
  check_convergence<2>("d2/dxdy 2D", one_sided_on({{0, 0}, {1, 1}}), Quantity::kMixedXY, 2, kSizes, true);
}
TEST(DerivativeConvergence, Derivatives3D) {
  const std::vector<int> sizes{17, 33, 65, 129};  // 3D arrays of 257^3 would cost 140 MB
  check_convergence<3>("d/dz 3D", one_sided_on({{2, 1}}), Quantity::kFirstZ, 1, sizes, true);
  check_convergence<3>("d2/dxdz 3D", one_sided_on({{0, 1}, {2, 0}}), Quantity::kMixedXZ, 2, sizes, true);
}

TEST(DerivativeOperator, RejectsTooFewGhostsForCentralRows) {
  gw::BlockLayout<1> layout{{16}, 2};
  gw::DerivativeConfig config;
  config.accuracy = 6;
  EXPECT_THROW(gw::DerivativeOperator<1>(layout, {0.1}, config), std::invalid_argument);
  config.one_sided[0] = {true, true};  // no ghosts are read at all
  EXPECT_NO_THROW(gw::DerivativeOperator<1>(layout, {0.1}, config));
}

}  // namespace
