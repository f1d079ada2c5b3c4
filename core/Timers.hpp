#pragma once
// Named, accumulated wall-clock timers for the stages of a step (collisions, output, rhs...).
// The run summary prints them and writes them to summary.json `timings_s`.
#include <chrono>
#include <map>
#include <string>

namespace grainwave {

class StageTimers {
 public:
  void add(const std::string& stage, double seconds) { seconds_[stage] += seconds; }
  const std::map<std::string, double>& totals() const { return seconds_; }
  void clear() { seconds_.clear(); }

 private:
  std::map<std::string, double> seconds_;
};

/// Adds the time between construction and destruction to one stage.
class ScopedTimer {
 public:
  ScopedTimer(StageTimers& timers, const char* stage)
      : timers_(timers), stage_(stage), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    timers_.add(stage_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_)
                            .count());
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  StageTimers& timers_;
  const char* stage_;
  std::chrono::steady_clock::time_point start_;
};

/// Seconds since construction.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace grainwave
