// The flux-form split convection, shock dissipation and positivity limiter on a periodic 1D line,
// and the boundary ghosts: discrete conservation, 4th-order accuracy against the exact flux
// divergence, equality with the pointwise Kennedy-Gruber split, dissipation switched off in smooth
// flow, the background dissipation's rate on the grid-scale mode and its order in smooth flow, a
// blast kept positive, wall/outflow/inflow ghosts.
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
  std::vector<double> rho, u, p, e, q0, q1, q2;
  std::vector<double> rhs0, rhs1, rhs2;

  Line(int points, double amplitude, bool step = false) : n(points), h(1.0 / points) {
    const auto total = static_cast<std::size_t>(n + 2 * kGhosts);
    for (auto* v : {&rho, &u, &p, &e, &q0, &q1, &q2, &rhs0, &rhs1, &rhs2}) v->assign(total, 0.0);
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
    }
  }
  /// Flux-form RHS of the line: convection, plus the dissipation when threshold >= 0, plus the
  /// positivity limiter when sigma = 2 dt / h > 0. Returns the faces the limiter changed.
  long rhs(double threshold, double sigma, bool convection = true, double background = 0) {
    const gf::BlockPrimitives<1> w{rho.data(), {u.data()}, p.data(), e.data()};
    const std::array<const double*, 3> q = {q0.data(), q1.data(), q2.data()};
    const grainwave::wavelet::ArrayShape<1> shape{{n + 2 * kGhosts}};
    gf::InviscidSettings settings;
    settings.gamma = kGamma;
    settings.capturing = threshold >= 0;
    settings.coefficient = 1.2;
    settings.threshold = threshold;
    settings.limiter_dt = 0.5 * sigma * h;
    settings.background = background;
    gf::BlockScratch<1> scratch(shape.size());
    std::vector<double> out(3 * static_cast<std::size_t>(n), 0.0);
    const long limited = gf::add_block_inviscid<1>(shape, kGhosts, n, w, q, {h}, settings, scratch, out.data());
    if (!convection) {  // the dissipation alone: subtract the convection
      std::vector<double> central(out.size(), 0.0);
      gf::add_block_inviscid<1>(shape, kGhosts, n, w, q, {h}, gf::InviscidSettings{kGamma}, scratch, central.data());
      for (std::size_t k = 0; k < out.size(); ++k) out[k] -= central[k];
    }
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i)
      rhs0[i] = out[i], rhs1[i] = out[static_cast<std::size_t>(n) + i], rhs2[i] = out[2 * static_cast<std::size_t>(n) + i];
    return limited;
  }
  void convection() { rhs(-1, 0); }
  void dissipation(double threshold, double background = 0) { rhs(threshold, 0, false, background); }
};

/// The split form as Kennedy & Gruber write it, pointwise: -(1/h) [1/2 (D(rho u) + u D rho + rho D u),
/// 1/4 (D(rho u phi) + u D(rho phi) + rho D(u phi) + phi D(rho u) + rho u D phi + rho phi D u
/// + u phi D rho) + D p (momentum along the axis) + 1/2 (D(p u) + u D p + p D u) (energy)], on a
/// 2D block line along x: the reference the flux form must reproduce.
std::array<double, 4> pointwise_split(const gf::BlockPrimitives<2>& w, std::ptrdiff_t i, double inv_h) {
  auto D = [&](auto&& f) {
    return inv_h * (gf::kCentral1 * (f(i + 1) - f(i - 1)) + gf::kCentral2 * (f(i + 2) - f(i - 2)));
  };
  auto rho = [&](std::ptrdiff_t j) { return w.rho[j]; };
  auto u = [&](std::ptrdiff_t j) { return w.u[0][j]; };
  auto p = [&](std::ptrdiff_t j) { return w.p[j]; };
  std::array<double, 4> out{};
  out[0] = -0.5 * (D([&](auto j) { return rho(j) * u(j); }) + u(i) * D(rho) + rho(i) * D(u));
  for (int k = 0; k < 3; ++k) {
    auto phi = [&](std::ptrdiff_t j) { return k < 2 ? w.u[static_cast<std::size_t>(k)][j] : w.e[j]; };
    double d = 0.25 * (D([&](auto j) { return rho(j) * u(j) * phi(j); }) + u(i) * D([&](auto j) { return rho(j) * phi(j); }) +
                       rho(i) * D([&](auto j) { return u(j) * phi(j); }) + phi(i) * D([&](auto j) { return rho(j) * u(j); }) +
                       rho(i) * u(i) * D(phi) + rho(i) * phi(i) * D(u) + u(i) * phi(i) * D(rho));
    if (k == 0) d += D(p);
    if (k == 2) d += 0.5 * (D([&](auto j) { return p(j) * u(j); }) + u(i) * D(p) + p(i) * D(u));
    out[static_cast<std::size_t>(k) + 1] = -d;
  }
  return out;
}

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

TEST(SplitConvection, FluxFormEqualsThePointwiseKennedyGruberSplit) {
  // A 2D block, fields varying along x only (so the y fluxes cancel exactly), both velocity
  // components nonzero: every row must equal the pointwise split along x.
  const int n = 16, total = n + 2 * kGhosts;
  const grainwave::wavelet::ArrayShape<2> shape{{total, total}};
  const std::size_t volume = shape.size();
  std::vector<double> rho(volume), u(volume), v(volume), p(volume), e(volume);
  std::array<std::vector<double>, 4> q;
  for (auto& f : q) f.resize(volume);
  for (std::size_t at = 0; at < volume; ++at) {
    const double x = 0.37 * shape.coords(static_cast<std::ptrdiff_t>(at))[0];
    const gf::Primitive<2> w{1 + 0.3 * std::sin(x), {0.4 * std::cos(1.3 * x), -0.2 + 0.3 * std::sin(0.7 * x)},
                             0.7 + 0.2 * std::cos(0.9 * x)};
    const auto c = gf::to_conserved(w, kGamma);
    rho[at] = w.rho, u[at] = w.u[0], v[at] = w.u[1], p[at] = w.p, e[at] = c[3] / w.rho;
    for (std::size_t f = 0; f < 4; ++f) q[f][at] = c[f];
  }
  const gf::BlockPrimitives<2> w{rho.data(), {u.data(), v.data()}, p.data(), e.data()};
  gf::BlockScratch<2> scratch(volume);
  const std::size_t per_block = static_cast<std::size_t>(n * n);
  std::vector<double> out(4 * per_block, 0.0);
  const double h = 0.1;
  gf::add_block_inviscid<2>(shape, kGhosts, n, w, {q[0].data(), q[1].data(), q[2].data(), q[3].data()}, {h, h},
                            gf::InviscidSettings{kGamma}, scratch, out.data());
  for (int y = 0; y < n; y += 5)
    for (int i = 0; i < n; ++i) {
      const auto reference = pointwise_split(w, shape.index({i + kGhosts, y + kGhosts}), 1 / h);
      for (std::size_t f = 0; f < 4; ++f)
        EXPECT_NEAR(out[f * per_block + static_cast<std::size_t>(y * n + i)], reference[f], 1e-13 / h)
            << "field " << f << " point " << i << " row " << y;
    }
}

TEST(PositivityLimiter, KeepsAStrongBlastPositiveAndLeavesSmoothFlowAlone) {
  // p 1000 | 0.01 (the Woodward-Colella blast's left interface) at rest: a forward-Euler step of
  // CFL 0.4 with the unlimited split flux makes the pressure negative next to the jump.
  const int n = 64;
  Line blast(n, 0, true);
  for (std::size_t at = 0; at < blast.rho.size(); ++at) {
    const bool high = blast.p[at] > 0.5;
    blast.rho[at] = 1, blast.u[at] = 0, blast.p[at] = high ? 1000 : 0.01;
    const auto c = gf::to_conserved<1>({1.0, {0.0}, blast.p[at]}, kGamma);
    blast.q0[at] = c[0], blast.q1[at] = c[1], blast.q2[at] = c[2], blast.e[at] = c[2];
  }
  const double dt = 0.4 * blast.h / gf::sound_speed(1.0, 1000, kGamma), sigma = 2 * dt / blast.h;
  auto smallest_pressure = [&] {
    double smallest = 1e300;
    for (int i = 0; i < n; ++i) {
      const auto at = static_cast<std::size_t>(i + kGhosts), k = static_cast<std::size_t>(i);
      const gf::Conserved<1> next{blast.q0[at] + dt * blast.rhs0[k], blast.q1[at] + dt * blast.rhs1[k],
                                  blast.q2[at] + dt * blast.rhs2[k]};
      smallest = std::min(smallest, gf::to_primitive<1>(next, kGamma).p);
    }
    return smallest;
  };
  EXPECT_EQ(blast.rhs(1e-3, 0), 0L);
  EXPECT_LT(smallest_pressure(), 0.0);
  EXPECT_GT(blast.rhs(1e-3, sigma), 0L);
  EXPECT_GT(smallest_pressure(), 0.0);
  const double mass_before = sum(blast.rhs0, n), energy = sum(blast.rhs2, n);
  EXPECT_NEAR(mass_before, 0, 1e-9);  // still conservative: limited faces are shared
  EXPECT_NEAR(energy, 0, 1e-9 * 1000);

  Line smooth(64, 0.3);
  EXPECT_EQ(smooth.rhs(1e-3, 0.6), 0L);  // sigma = 2 dt / h at CFL 0.4, waves up to 1.3
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

TEST(BackgroundDissipation, DampsTheGridScaleModeAtItsRateAndSmoothFlowByOrderFive) {
  // The grid-scale mode on a uniform state: q_0 = 1 + a (-1)^j. The sixth difference gives
  // d rho_j / dt = -64 kappa_6 lambda / h (rho_j - 1), lambda = |u| + c of the state (a small).
  const double kappa = 1.0 / 256, a = 1e-8;
  Line mode(64, 0);
  for (int j = -kGhosts; j < mode.n + kGhosts; ++j) {
    const auto at = static_cast<std::size_t>(j + kGhosts);
    const double sign = (((j % 2) + 2) % 2) == 0 ? 1.0 : -1.0;
    mode.rho[at] = 1 + a * sign;
    mode.q0[at] = mode.rho[at];
    mode.q1[at] = mode.rho[at] * mode.u[at];
    mode.q2[at] = mode.p[at] / (kGamma - 1) + 0.5 * mode.rho[at] * mode.u[at] * mode.u[at];
    mode.e[at] = mode.q2[at] / mode.rho[at];
  }
  // A threshold above any sensor value: the second-difference term stays off, the background
  // term alone acts.
  mode.dissipation(1.0, kappa);
  const double lambda = 0.3 + std::sqrt(kGamma * (1 / kGamma) / 1.0);
  for (int i = 0; i < mode.n; ++i) {
    const auto at = static_cast<std::size_t>(i);
    const double deviation = mode.q0[at + kGhosts] - 1;
    EXPECT_NEAR(mode.rhs0[at], -64 * kappa * lambda / mode.h * deviation, 1e-6 * 64 * kappa * lambda / mode.h * a);
  }
  // Smooth flow: the term is O(h^5) (a fifth difference divided by h), so halving h divides it
  // by about 32; the mass sum stays zero (flux form).
  std::array<double, 2> largest{};
  for (int k = 0; k < 2; ++k) {
    Line smooth(64 << k, 0.05);
    smooth.dissipation(1.0, kappa);
    for (int i = 0; i < smooth.n; ++i)
      largest[static_cast<std::size_t>(k)] = std::max(largest[static_cast<std::size_t>(k)], std::abs(smooth.rhs0[static_cast<std::size_t>(i)]));
    EXPECT_NEAR(sum(smooth.rhs0, smooth.n), 0, 1e-12);
  }
  EXPECT_GT(largest[0], 0.0);
  EXPECT_GT(std::log2(largest[0] / largest[1]), 4.8) << largest[0] << " " << largest[1];
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
