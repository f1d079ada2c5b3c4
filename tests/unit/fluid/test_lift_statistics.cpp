// The lift statistics behind Cl_amplitude and St (fluid/LiftStatistics.hpp): a shedding body's
// lift on an adaptive grid is a sinusoid plus step-to-step jitter, and the jitter must neither
// add periods nor inflate the amplitude.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "fluid/LiftStatistics.hpp"

namespace gf = grainwave::fluid;

namespace {

struct Signal {
  std::vector<double> t, lift;
};

/// A cos(2 pi t / period) + offset, sampled every dt over [0, duration], plus uniform jitter
/// of half-width `jitter`.
Signal shedding(double amplitude, double period, double offset, double jitter, double dt, double duration) {
  Signal s;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> noise(-jitter, jitter);
  for (double t = 0; t <= duration; t += dt) {
    s.t.push_back(t);
    s.lift.push_back(offset + amplitude * std::cos(2 * std::numbers::pi * t / period) + noise(rng));
  }
  return s;
}

}  // namespace

TEST(LiftStatistics, CleanSinusoidGivesItsPeriodAndAmplitude) {
  const Signal s = shedding(0.33, 6.1, 0.02, 0.0, 0.01, 61.0);
  const gf::LiftStatistics stats = gf::lift_statistics(s.t, s.lift, 1e-3);
  ASSERT_TRUE(stats.period.has_value());
  EXPECT_NEAR(*stats.period, 6.1, 1e-4);
  EXPECT_EQ(stats.periods, 9);  // crossings at 4.575 + k 6.1 within [0, 61]: ten
  EXPECT_NEAR(stats.amplitude, 0.33, 1e-3);
  EXPECT_NEAR(stats.mean, 0.02, 1e-3);
}

TEST(LiftStatistics, JitterAddsNoPeriodsAndLittleAmplitude) {
  // Jitter of 15% of the amplitude sampled 600 times a period: the plain zero-crossing count
  // sees many extra crossings near each true one; the hysteresis does not.
  const Signal s = shedding(0.33, 62.5, 0.0, 0.05, 0.1, 625.0);
  const gf::LiftStatistics stats = gf::lift_statistics(s.t, s.lift, 1e-3);
  long plain_crossings = 0;
  for (std::size_t i = 1; i < s.lift.size(); ++i) plain_crossings += s.lift[i - 1] < 0 && s.lift[i] >= 0;
  EXPECT_GT(plain_crossings, 20);  // the failure this guards against: ten true crossings
  ASSERT_TRUE(stats.period.has_value());
  EXPECT_EQ(stats.periods, 9);
  EXPECT_NEAR(*stats.period, 62.5, 0.5);
  EXPECT_GT(stats.half_range, 0.36);  // the half range carries the jitter
  EXPECT_NEAR(stats.amplitude, 0.33, 0.01);
}

TEST(LiftStatistics, SteadyLiftHasNoPeriod) {
  const Signal s = shedding(0.0, 1.0, 0.01, 1e-6, 0.01, 50.0);
  const gf::LiftStatistics stats = gf::lift_statistics(s.t, s.lift, 1e-3);
  EXPECT_LT(stats.amplitude, 1e-5);
  EXPECT_FALSE(stats.period.has_value());  // the jitter alone crosses the mean often
  // The same jitter counted with no amplitude floor does give "periods": the floor is what
  // keeps a steady body from reporting a Strouhal number.
  EXPECT_TRUE(gf::lift_statistics(s.t, s.lift, 0.0).period.has_value());
  const gf::LiftStatistics empty = gf::lift_statistics({}, {}, 1e-3);
  EXPECT_FALSE(empty.period.has_value());
  EXPECT_EQ(empty.amplitude, 0.0);
}
