// The event calendar against an ordered set of (time, particle): same earliest particle after
// every change, whatever the times do (steady stream, jumps far ahead, ties, +inf, a system that
// slows down a thousandfold so the bucket width must be chosen again).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "particles/hardsphere/EventCalendar.hpp"

namespace hs = grainwave::particles::hardsphere;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// The reference queue: (time, particle), ordered as the calendar promises (ties to the lower
/// index); +inf times are never returned.
class Reference {
 public:
  explicit Reference(const std::vector<double>& times) : time_(times) {
    for (int i = 0; i < static_cast<int>(times.size()); ++i) set_.insert({times[static_cast<std::size_t>(i)], i});
  }
  void update(int i, double t) {
    set_.erase({time_[static_cast<std::size_t>(i)], i});
    time_[static_cast<std::size_t>(i)] = t;
    set_.insert({t, i});
  }
  int top() const { return set_.empty() || !std::isfinite(set_.begin()->first) ? -1 : set_.begin()->second; }

 private:
  std::vector<double> time_;
  std::set<std::pair<double, int>> set_;
};

/// Pops `events` times: the earliest particle gets a new time now + an exponential gap of the
/// given mean (scaled per event by `slowdown`), and a random other particle too, as a collision
/// re-predicts both partners. Checks the calendar's choice against the reference every time;
/// returns how often the calendar chose its bucket width again.
long run_stream(int n, long events, double mean_gap, double slowdown, unsigned seed, double inf_fraction = 0.0) {
  std::mt19937_64 rng(seed);
  std::exponential_distribution<double> gap(1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<double> times(static_cast<std::size_t>(n));
  for (auto& t : times) t = uniform(rng) < inf_fraction ? kInf : mean_gap * gap(rng);
  hs::EventCalendar calendar;
  calendar.reset(times);
  Reference reference(times);
  double scale = mean_gap;
  for (long e = 0; e < events; ++e) {
    const int expected = reference.top();
    const int got = calendar.top();
    EXPECT_EQ(got, expected) << "event " << e;
    if (got != expected) return -1;
    if (got < 0) break;
    const double now = calendar.time(got);
    scale *= slowdown;
    const double t = uniform(rng) < inf_fraction ? kInf : now + scale * gap(rng);
    calendar.update(got, t);
    reference.update(got, t);
    const int other = pick(rng);
    if (other == got) continue;
    const double t_other = now + scale * gap(rng);
    calendar.update(other, t_other);
    reference.update(other, t_other);
  }
  return calendar.rebuilds();
}

TEST(EventCalendar, SteadyStreamMatchesOrderedSet) {
  // The width chosen at set-up suits a steady stream for good.
  EXPECT_EQ(run_stream(1000, 200000, 0.13, 1.0, 1), 0);
}

TEST(EventCalendar, SmallQueues) {
  EXPECT_GE(run_stream(1, 1000, 1.0, 1.0, 2), 0);
  EXPECT_GE(run_stream(2, 1000, 1.0, 1.0, 3), 0);
  EXPECT_GE(run_stream(7, 5000, 1.0, 1.0, 4), 0);
}

TEST(EventCalendar, SlowingAndSpeedingSystemsChooseTheWidthAgain) {
  // 200 000 events, each gap 1.00005 times the last: the gaps grow by e^10 over the run.
  EXPECT_GT(run_stream(500, 200000, 1e-3, 1.00005, 5), 0);
  EXPECT_GT(run_stream(500, 200000, 1e3, 1.0 / 1.00005, 6), 0);
}

TEST(EventCalendar, InfiniteTimesAreNeverReturned) {
  EXPECT_GE(run_stream(300, 50000, 0.5, 1.0, 7, 0.3), 0);
  std::vector<double> never(10, kInf);
  hs::EventCalendar calendar;
  calendar.reset(never);
  EXPECT_EQ(calendar.top(), -1);
  calendar.update(3, 2.0);
  EXPECT_EQ(calendar.top(), 3);
  calendar.update(3, kInf);
  EXPECT_EQ(calendar.top(), -1);
}

TEST(EventCalendar, TiesGoToTheLowerIndexAndJumpsAheadAreFound) {
  std::vector<double> times{5.0, 1.0, 1.0, 3.0, 1.0};
  hs::EventCalendar calendar;
  calendar.reset(times);
  EXPECT_EQ(calendar.top(), 1);
  calendar.update(1, 1e9);  // far beyond every revolution: the overflow
  EXPECT_EQ(calendar.top(), 2);
  calendar.update(2, 1.0);  // unchanged time, still first among the ties
  EXPECT_EQ(calendar.top(), 2);
  calendar.update(2, 1e9);
  EXPECT_EQ(calendar.top(), 4);
  calendar.update(4, 1e9);
  EXPECT_EQ(calendar.top(), 3);
  calendar.update(3, 1e9);
  EXPECT_EQ(calendar.top(), 0);
  calendar.update(0, 1e9);
  for (int expected : {0, 1, 2, 3, 4}) {  // five equal times after a jump of 1e9
    EXPECT_EQ(calendar.top(), expected);
    calendar.update(expected, kInf);
  }
  EXPECT_EQ(calendar.top(), -1);
}

}  // namespace
