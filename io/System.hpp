#pragma once
// What a simulated system provides to the run driver (app/Simulation): stepping, a state check,
// a copy of the last good state, output, checkpoints and its lines of the summary.
// A scene composes one System (particles alone, a fluid, a coupled fluid-particle system...); the
// driver owns time, output cadence, checkpoints, progress, failure handling and summary.json.
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/Timers.hpp"
#include "io/Hdf5.hpp"
#include "io/Json.hpp"

namespace grainwave::io {

/// One XDMF time series a system writes into: series name ("particles") and the grid XML of
/// this step.
using OutputGrid = std::pair<std::string, std::string>;

class System {
 public:
  virtual ~System() = default;

  /// One line for the start-up log and `grainwave check`.
  virtual std::string describe() const = 0;
  /// Largest step the physics allows from the current state (+inf if it sets none).
  virtual double max_stable_dt() const = 0;
  /// Advances the state from t to t + dt.
  virtual void advance(double t, double dt) = 0;
  /// Checks this rank's state; returns "what at where" if it is not physical (NaN, overlap...).
  virtual std::optional<std::string> check_state() const = 0;
  /// Keeps a copy of the current state / puts it back (used to write the last good state).
  virtual void save_good_state() = 0;
  virtual void restore_good_state() = 0;

  /// Collective: writes the state into `file` (named `file_name` for XDMF references) and returns
  /// the grids to append to the time series.
  virtual std::vector<OutputGrid> write_output(Hdf5File& file, const std::string& file_name) = 0;
  /// Collective: writes/reads everything needed to continue bit-for-bit.
  virtual void write_checkpoint(Hdf5Group& group) = 0;
  virtual void read_checkpoint(const Hdf5Group& group) = 0;

  /// Fills summary.json `counts` and `metrics` (collective). `step_wall_s` is the wall time
  /// spent stepping, for throughput.
  virtual void report(Json& counts, Json& metrics, double step_wall_s, long steps) const = 0;
  /// Bytes of state held on this rank (for memory estimates).
  virtual std::size_t memory_bytes() const = 0;
  /// A few words for the progress line ("N 1372, 210 collisions").
  virtual std::string progress_note() const { return {}; }

  StageTimers& timers() { return timers_; }
  const StageTimers& timers() const { return timers_; }

 protected:
  StageTimers timers_;
};

}  // namespace grainwave::io
