// The pointwise split-form convection and shock-dissipation kernels on a periodic 1D line, and
// the boundary ghosts: discrete conservation, 4th-order accuracy against the exact flux
// divergence, dissipation switched off in smooth flow, wall/outflow/inflow ghosts.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "fluid/FluidBoundaries.hpp"
#include "fluid/IdealGas.hpp"
#include "fluid/SplitConvection.hpp"

namespace gf = grainwave::fluid;

namespace {

constexpr double kGamma = 1.4;
constexpr int kGhosts = gf::kStencilReach;

/// A periodic 1D line of n points (plus ghosts as periodic images) of a smooth or stepped state.
struct Line {
  int n;
  double h;
  std::vector<double> rho, u, p, e, q0, q1, q2, wave, psi;
  std::vector<double> rhs0, rhs1, rhs2;

  Line(int points, double amplitude, bool step = false) : n(points), h(1.0 / points) {
    const auto total = static_cast<std::size_t>(n + 2 * kGhosts);
    for (auto* v : {&rho, &u, &p, &e, &q0, &q1, &q2, &wave, &psi, &rhs0, &rhs1, &rhs2}) v->assign(total, 0.0);
    for (int j = -kGhosts; j < n + kGhosts; ++j) {
      const int i = ((j % n) + n) % n;
      const double x = i * h, s = std::sin(2 * std::numbers::pi * x);
      gf::Primitive<1> w;
      w.rho = step ? (x < 0.5 ? 1.0 : 0.125) : 1 + amplitude * s;
      w.u[0] = 0.3 + amplitude * std::cos(2 * std::numbers::pi * x);
      w.p = step ? (x < 0.5 ? 1.0 : 0.1) : 1 / kGamma + amplitude * 0.5 * s * s;
      const auto q = gf::to_conserved(w, kGamma);
      const auto at = static_cast<std::size_t>(j + kGhosts);
      rho[at] = w.rho, u[at] = w.u[0], p[at] = w.p, e[at] = q[2] / w.rho;
      q0[at] = q[0], q1[at] = q[1], q2[at] = q[2];
      wave[at] = std::abs(w.u[0]) + gf::sound_speed(w.rho, w.p, kGamma);
    }
    for (std::size_t at = 1; at + 1 < total; ++at)
      psi[at] = std::max(gf::second_difference_sensor(p.data(), static_cast<std::ptrdiff_t>(at), 1),
                         gf::second_difference_sensor(rho.data(), static_cast<std::ptrdiff_t>(at), 1));
  }
  void convection() {
    const gf::BlockPrimitives<1> w{rho.data(), {u.data()}, p.data(), e.data()};
    for (int i = 0; i < n; ++i) {
      double out[3] = {0, 0, 0};
      gf::add_split_convection<1>(w, i + kGhosts, 1, 0, 1 / h, out);
      rhs0[static_cast<std::size_t>(i)] = out[0], rhs1[static_cast<std::size_t>(i)] = out[1],
      rhs2[static_cast<std::size_t>(i)] = out[2];
    }
  }
  void dissipation(double threshold) {
    const std::array<const double*, 3> q = {q0.data(), q1.data(), q2.data()};
    for (int i = 0; i < n; ++i) {
      double out[3] = {0, 0, 0};
      gf::add_shock_dissipation<1>(q, psi.data(), wave.data(), i + kGhosts, 1, 1.2, threshold, 1 / h, out);
      rhs0[static_cast<std::size_t>(i)] = out[0], rhs1[static_cast<std::size_t>(i)] = out[1],
      rhs2[static_cast<std::size_t>(i)] = out[2];
    }
  }
};

double sum(const std::vector<double>& v, int n) {
  double s = 0;
  for (int i = 0; i < n; ++i) s += v[static_cast<std::size_t>(i)];
  return s;
}

}  // namespace

TEST(SplitConvection, ConservesMassMomentumEnergyOnAPeriodicLine) {
  Line line(64, 0.3);
  line.convection();
  double scale = 0;
  for (int i = 0; i < 64; ++i) scale = std::max(scale, std::abs(line.rhs2[static_cast<std::size_t>(i)]));
  ASSERT_GT(scale, 1e-2);  // the state is far from uniform
  EXPECT_NEAR(sum(line.rhs0, 64), 0, 1e-13 * 64 * scale);
  EXPECT_NEAR(sum(line.rhs1, 64), 0, 1e-13 * 64 * scale);
  EXPECT_NEAR(sum(line.rhs2, 64), 0, 1e-13 * 64 * scale);
}

TEST(SplitConvection, IsFourthOrderAgainstTheExactFluxDivergence) {
  // d(rho u)/dx of rho = 1 + a sin(2 pi x), u = 0.3 + a cos(2 pi x), exactly.
  auto error = [](int n) {
    const double a = 0.2;
    Line line(n, a);
    line.convection();
    double err = 0;
    for (int i = 0; i < n; ++i) {
      const double x = static_cast<double>(i) / n, k = 2 * std::numbers::pi;
      const double rho = 1 + a * std::sin(k * x), u = 0.3 + a * std::cos(k * x);
      const double exact = -(a * k * std::cos(k * x) * u - rho * a * k * std::sin(k * x));
      err = std::max(err, std::abs(line.rhs0[static_cast<std::size_t>(i)] - exact));
    }
    return err;
  };
  const double order = std::log2(error(32) / error(64));
  EXPECT_GT(order, 3.8) << error(32) << " " << error(64);
}

TEST(ShockDissipation, IsOffInSmoothFlowAndConservativeAtAJump) {
  Line smooth(128, 0.05);
  smooth.dissipation(1e-3);
  for (int i = 0; i < 128; ++i) EXPECT_EQ(smooth.rhs0[static_cast<std::size_t>(i)], 0.0);
  Line jump(64, 0, true);
  jump.dissipation(1e-3);
  double largest = 0;
  for (int i = 0; i < 64; ++i) largest = std::max(largest, std::abs(jump.rhs0[static_cast<std::size_t>(i)]));
  EXPECT_GT(largest, 1.0);  // acts at the jumps
  EXPECT_NEAR(sum(jump.rhs0, 64), 0, 1e-12 * largest);
  EXPECT_NEAR(sum(jump.rhs2, 64), 0, 1e-12 * largest);
  EXPECT_EQ(jump.rhs0[16], 0.0);  // far from both jumps (x = 0 and 0.5)
}

TEST(FluidBoundaries, SlipWallMirrorsAndReversesNormalMomentumOutflowCopiesInflowHolds) {
  grainwave::wavelet::ArrayShape<2> shape{{8 + 2 * kGhosts, 8 + 2 * kGhosts}};
  std::vector<std::vector<double>> q(4, std::vector<double>(shape.size()));
  for (std::size_t f = 0; f < 4; ++f)
    for (std::size_t at = 0; at < shape.size(); ++at) q[f][at] = static_cast<double>(f * 1000 + at);
  std::vector<double*> fields = {q[0].data(), q[1].data(), q[2].data(), q[3].data()};
  const std::vector<double> inflow = {1, 2, 3, 4};
  gf::fill_edge_ghosts<2>(fields, shape, 8, kGhosts, 0, false, gf::BoundaryKind::kSlipWall, inflow);
  gf::fill_edge_ghosts<2>(fields, shape, 8, kGhosts, 1, true, gf::BoundaryKind::kOutflow, inflow);
  gf::fill_edge_ghosts<2>(fields, shape, 8, kGhosts, 0, true, gf::BoundaryKind::kInflow, inflow);
  const int g = kGhosts, last = g + 7;
  for (int k = 1; k <= g; ++k) {
    const auto ghost = shape.index({g - k, g + 2}), mirror = shape.index({g + k, g + 2});
    EXPECT_EQ(q[0][static_cast<std::size_t>(ghost)], q[0][static_cast<std::size_t>(mirror)]);
    EXPECT_EQ(q[1][static_cast<std::size_t>(ghost)], -q[1][static_cast<std::size_t>(mirror)]);  // normal
    EXPECT_EQ(q[2][static_cast<std::size_t>(ghost)], q[2][static_cast<std::size_t>(mirror)]);   // tangential
    EXPECT_EQ(q[3][static_cast<std::size_t>(shape.index({g + 3, last + k}))],
              q[3][static_cast<std::size_t>(shape.index({g + 3, last}))]);
    EXPECT_EQ(q[2][static_cast<std::size_t>(shape.index({last + k, g + 1}))], 3.0);
  }
}

TEST(FluidBoundaries, ThermodynamicSpongeRelaxesDensityAndPressureAndLeavesTheVelocity) {
  const double gamma = 1.4, sigma = 0.7;
  const auto face = gf::to_conserved<2>({1.0, {0.2, 0.0}, 1 / gamma}, gamma);
  // A wake point: slower, turning, at the face's density and pressure: no source at all.
  const auto wake = gf::to_conserved<2>({1.0, {0.12, -0.03}, 1 / gamma}, gamma);
  gf::Conserved<2> source{};
  gf::add_sponge_source<2>(wake, face, sigma, true, source);
  for (const double s : source) EXPECT_EQ(s, 0.0);
  // The whole-state sponge forces the same point towards the free stream.
  gf::add_sponge_source<2>(wake, face, sigma, false, source);
  EXPECT_NEAR(source[1], -sigma * (wake[1] - face[1]), 1e-15);
  EXPECT_GT(source[1], 0.0);

  // An acoustic disturbance (p', rho', u'): along the source, u stays, rho and p relax at sigma.
  const gf::Primitive<2> w{1.02, {0.21, 0.01}, 1.03 / gamma};
  const auto q = gf::to_conserved<2>(w, gamma);
  source = {};
  gf::add_sponge_source<2>(q, face, sigma, true, source);
  const double dt = 1e-7;
  gf::Conserved<2> next{};
  for (std::size_t f = 0; f < q.size(); ++f) next[f] = q[f] + dt * source[f];
  const auto after = gf::to_primitive<2>(next, gamma);
  EXPECT_NEAR((after.u[0] - w.u[0]) / dt, 0.0, 1e-6);
  EXPECT_NEAR((after.u[1] - w.u[1]) / dt, 0.0, 1e-6);
  EXPECT_NEAR((after.rho - w.rho) / dt, -sigma * (w.rho - 1.0), 1e-6);
  EXPECT_NEAR((after.p - w.p) / dt, -sigma * (w.p - 1 / gamma), 1e-6);
}

TEST(FluidBoundaries, CharacteristicGhostsExtrapolateOutgoingAndImposeIncomingWaves) {
  const double gamma = 1.4;
  gf::EdgeGas gas;
  gas.gamma = gamma;
  gas.length = 1;
  gas.spacing = 0.01;
  const gf::Primitive<2> far{1.0, {0.2, 0.0}, 1 / gamma};
  // The far state itself passes unchanged through either kind of edge.
  for (const bool inflow_edge : {false, true}) {
    const auto ghost = gf::characteristic_ghost<2>(far, far, far, 0, inflow_edge ? -1 : 1, 2, inflow_edge, gas);
    EXPECT_NEAR(ghost.rho, far.rho, 1e-14);
    EXPECT_NEAR(ghost.u[0], far.u[0], 1e-14);
    EXPECT_NEAR(ghost.u[1], far.u[1], 1e-14);
    EXPECT_NEAR(ghost.p, far.p, 1e-14);
  }
  // Supersonic outflow: every characteristic leaves, so each primitive is extrapolated linearly.
  const gf::Primitive<2> edge{1.1, {2.0, 0.3}, 0.8}, inner{1.0, {1.9, 0.2}, 0.75};
  const auto ghost = gf::characteristic_ghost<2>(edge, inner, far, 0, 1, 2, false, gas);
  EXPECT_NEAR(ghost.rho, 1.3, 1e-12);
  EXPECT_NEAR(ghost.u[0], 2.2, 1e-12);
  EXPECT_NEAR(ghost.u[1], 0.5, 1e-12);
  EXPECT_NEAR(ghost.p, 0.9, 1e-12);
  // Subsonic inflow from the low edge: the ghost carries the far field's incoming characteristics
  // (p - Z u_n outward = p + Z u, entropy, tangential velocity) and the edge's outgoing one.
  const gf::Primitive<2> at_edge{1.02, {0.21, 0.01}, 0.72};
  const auto in = gf::characteristic_ghost<2>(at_edge, at_edge, far, 0, -1, 1, true, gas);
  const double c = std::sqrt(gamma * at_edge.p / at_edge.rho), z = at_edge.rho * c;
  EXPECT_NEAR(in.p + z * in.u[0], far.p + z * far.u[0], 1e-12);           // incoming acoustic: far
  EXPECT_NEAR(in.p - z * in.u[0], at_edge.p - z * at_edge.u[0], 1e-12);   // outgoing: the edge's
  EXPECT_NEAR(in.rho - in.p / (c * c), far.rho - far.p / (c * c), 1e-12);  // entropy: far
  EXPECT_NEAR(in.u[1], far.u[1], 1e-12);
}
