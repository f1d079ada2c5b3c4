#include "core/Progress.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "core/Mpi.hpp"

namespace grainwave {

ProgressReporter::ProgressReporter(double t_start, double t_end, double interval_s, bool enabled)
    : t_start_(t_start),
      t_end_(t_end),
      interval_s_(interval_s),
      enabled_(enabled && mpi::is_root()),
      on_terminal_(::isatty(STDERR_FILENO) != 0) {}

std::string ProgressReporter::format_duration(double s) {
  if (!std::isfinite(s)) return "?";
  if (s < 60) return fmt::format("{:.1f}s", s);
  if (s < 3600) return fmt::format("{}m{:02d}s", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  return fmt::format("{}h{:02d}m", static_cast<int>(s / 3600), static_cast<int>(s / 60) % 60);
}

std::string ProgressReporter::line(long step, double t, double dt, const std::string& note) const {
  const double wall = wall_.seconds();
  const double done = (t - t_start_) / (t_end_ - t_start_);
  const double eta = done > 0 ? wall * (1 - done) / done : NAN;
  return fmt::format("step {:>8}  t {:<11.5g} dt {:<10.3e} wall {:>7}  ETA {:>7}  {:3.0f}%{}{}",
                     step, t, dt, format_duration(wall), format_duration(eta), 100 * done,
                     note.empty() ? "" : "  ", note);
}

bool ProgressReporter::due() const {
  return enabled_ && wall_.seconds() - last_print_ >= (on_terminal_ ? 0.2 : interval_s_);
}

void ProgressReporter::update(long step, double t, double dt, const std::string& note) {
  if (!due()) return;
  last_print_ = wall_.seconds();
  if (on_terminal_) {
    std::fprintf(stderr, "\r%s\033[K", line(step, t, dt, note).c_str());
    std::fflush(stderr);
    line_open_ = true;
  } else {
    spdlog::info("{}", line(step, t, dt, note));
  }
}

void ProgressReporter::finish() {
  if (line_open_) std::fprintf(stderr, "\n");
  line_open_ = false;
}

}  // namespace grainwave
