#pragma once
// The run driver: owns simulated time, the step loop, output cadence, checkpoints, progress,
// failure handling and summary.json. The physics is a composed io::System (app/Compose).
//
// Per step: dt = min(run.dt or the system's stable step, time to the next output, time to
// t_end) -> keep the good state -> advance -> check (all ranks agree) -> output/checkpoint
// when due. A failed check puts the last good state back, writes it (output + checkpoint) and
// stops with exit code 3.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"
#include "io/Xdmf.hpp"

namespace grainwave::app {

struct RunOptions {
  std::filesystem::path output_folder;      ///< empty: [output] folder, else out/<scene name>
  std::optional<std::filesystem::path> restart;  ///< checkpoint file or a run's output folder
};

class Simulation {
 public:
  static void declare(SceneSchema& schema);
  Simulation(const Scene& scene, std::unique_ptr<io::System> system, RunOptions options);
  ~Simulation();

  /// Runs to t_end; returns the process exit code (0, or kExitNumericalFailure).
  int run();

  /// The step the first iteration would take and where its limit comes from (for `check`).
  std::pair<double, std::string> first_step() const;
  const std::filesystem::path& output_folder() const { return folder_; }

 private:
  struct Clock {
    long step = 0;
    double t = 0;
    long output_index = 0;      ///< number of outputs written
    double next_output = 0;     ///< simulated time of the next output
    double wall_before = 0;     ///< wall seconds of earlier (pre-restart) invocations
    double step_wall_before = 0;
  };

  double choose_dt(bool& hits_output) const;
  /// The first multiple of output.interval after t (t_end if none comes before it).
  double next_output_after(double t) const;
  void write_output();
  void write_checkpoint(const std::string& reason);
  void read_checkpoint(const std::filesystem::path& file);
  void write_summary(const std::string& status, const std::string& failure);
  void prune_checkpoints();

  const Scene& scene_;
  std::unique_ptr<io::System> system_;
  std::filesystem::path folder_;
  std::optional<std::filesystem::path> restarted_from_;
  Clock clock_;
  double t_end_, fixed_dt_, output_interval_, progress_interval_;
  long max_steps_, checkpoint_every_, checkpoints_kept_;
  long debug_kill_step_ = -1;
  std::string debug_kill_during_;
  std::vector<io::XdmfTimeSeries> series_;
  std::vector<std::filesystem::path> checkpoints_;
  double wall_ = 0, step_wall_ = 0;
};

/// Resolves `--restart PATH`: a checkpoint file, or a folder whose newest checkpoint is used.
std::filesystem::path resolve_checkpoint(const std::filesystem::path& path);

}  // namespace grainwave::app
