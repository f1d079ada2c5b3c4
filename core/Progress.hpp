#pragma once
// Progress of a run: on a terminal, one line rewritten in place (step, simulated time, time step,
// wall time, ETA); otherwise (CI, batch jobs, pipes) a plain log line every `interval_s` seconds.
#include <string>

#include "core/Timers.hpp"

namespace grainwave {

class ProgressReporter {
 public:
  /// `t_start`/`t_end`: simulated time span, for the ETA.
  ProgressReporter(double t_start, double t_end, double interval_s, bool enabled);
  /// Called after every step; prints when due. `note` is a short system-specific summary.
  void update(long step, double t, double dt, const std::string& note = {});
  /// Whether the next update() will print: a caller whose note costs something to make (a count
  /// over the particles) makes it only then.
  bool due() const;
  /// Ends the in-place line (if any) so following output starts on a fresh line.
  void finish();
  static std::string format_duration(double seconds);

 private:
  std::string line(long step, double t, double dt, const std::string& note) const;
  double t_start_, t_end_, interval_s_;
  bool enabled_, on_terminal_;
  bool line_open_ = false;
  Stopwatch wall_;
  double last_print_ = -1e300;
};

}  // namespace grainwave
