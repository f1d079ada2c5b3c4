#include "app/Simulation.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <limits>

#include "core/Error.hpp"
#include "core/Log.hpp"
#include "core/Mpi.hpp"
#include "core/Progress.hpp"
#include "io/AtomicFile.hpp"
#include "io/Hdf5.hpp"
#include "io/Json.hpp"

namespace grainwave::app {

namespace fs = std::filesystem;

namespace {
volatile std::sig_atomic_t g_stop_requested = 0;
void request_stop(int) { g_stop_requested = 1; }

constexpr const char* kCheckpointPrefix = "checkpoint_";
}  // namespace

void Simulation::declare(SceneSchema& schema) {
  auto& scene = schema.section("scene", "Name and description of the scene.");
  scene.text("name", "", "scene name (default: the file name without .toml)");
  scene.text("description", "", "one line saying what the scene is");

  auto& run = schema.section("run", "Time stepping and run control.");
  run.real("t_end", std::nullopt, "simulated time at which the run ends").above(0);
  run.real("dt", 0.0, "fixed time step; 0 lets the physics choose (CFL, collision time)")
      .at_least(0);
  run.integer("max_steps", 0, "stop after this many steps; 0 for no limit").at_least(0);
  run.real("progress_interval_s", 10.0,
           "wall seconds between progress lines when not on a terminal")
      .above(0);

  auto& out = schema.section("output", "Output files, time series and checkpoints.");
  out.text("folder", "", "output folder; empty: out/<scene name> (--out overrides)");
  out.real("interval", 0.0,
           "simulated time between output files; 0: only the initial and final states")
      .at_least(0);
  out.integer("checkpoint_every_steps", 0, "steps between checkpoints; 0: only at the end")
      .at_least(0);
  out.integer("checkpoints_kept", 2, "how many of the newest checkpoints to keep").at_least(1);

  auto& debug = schema.section("debug", "Testing aids: deliberately kill the run.");
  debug.integer("kill_at_step", -1, "send SIGKILL to this process at this step; -1: never")
      .at_least(-1);
  debug.text("kill_during", "step",
             "where: at the start of the step, or in the middle of writing its output or "
             "checkpoint file")
      .one_of({"step", "output", "checkpoint"});
}

Simulation::Simulation(const Scene& scene, std::unique_ptr<io::System> system, RunOptions options)
    : scene_(scene), system_(std::move(system)) {
  const auto& run = scene.section("run");
  t_end_ = run.real("t_end");
  fixed_dt_ = run.real("dt");
  max_steps_ = static_cast<long>(run.integer("max_steps"));
  progress_interval_ = run.real("progress_interval_s");
  output_interval_ = 0;
  checkpoint_every_ = 0;
  checkpoints_kept_ = 2;
  std::string folder;
  if (scene.has("output")) {
    const auto& out = scene.section("output");
    output_interval_ = out.real("interval");
    checkpoint_every_ = static_cast<long>(out.integer("checkpoint_every_steps"));
    checkpoints_kept_ = static_cast<long>(out.integer("checkpoints_kept"));
    folder = out.text("folder");
  }
  if (scene.has("debug")) {
    debug_kill_step_ = static_cast<long>(scene.section("debug").integer("kill_at_step"));
    debug_kill_during_ = scene.section("debug").text("kill_during");
  }
  if (options.restart) restarted_from_ = resolve_checkpoint(*options.restart);
  if (!options.output_folder.empty()) folder_ = options.output_folder;
  else if (!folder.empty()) folder_ = folder;
  else if (restarted_from_) folder_ = restarted_from_->parent_path();
  else folder_ = fs::path("out") / scene.name();
  if (folder_.empty()) folder_ = ".";

  // The time-step source must be known before anything runs: a system that sets no limit of
  // its own (free flight) needs run.dt.
  if (fixed_dt_ == 0 && !std::isfinite(system_->max_stable_dt()))
    run.fail("dt", "this scene's physics sets no time-step limit of its own",
             "give run.dt > 0");
  clock_.next_output = output_interval_ > 0 ? std::min(output_interval_, t_end_) : t_end_;
}

Simulation::~Simulation() = default;

double Simulation::next_output_after(double t) const {
  if (!(output_interval_ > 0)) return t_end_;
  // Outputs fall on the multiples of the interval (the 1e-9 absorbs t = k interval rounded down).
  const double k = std::floor(t / output_interval_ + 1e-9) + 1;
  const double next = std::min(t_end_, output_interval_ * k);
  return next > t ? next : t_end_;
}

fs::path resolve_checkpoint(const fs::path& path) {
  if (fs::is_directory(path)) {
    fs::path newest;
    for (const auto& entry : fs::directory_iterator(path)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind(kCheckpointPrefix, 0) == 0 && entry.path().extension() == ".h5" &&
          name > newest.filename().string())
        newest = entry.path();
    }
    if (newest.empty())
      throw InputError({path.string(), 0}, "--restart", "no checkpoint_*.h5 in this folder");
    return newest;
  }
  if (!fs::exists(path)) throw InputError({path.string(), 0}, "--restart", "no such checkpoint");
  return path;
}

std::pair<double, std::string> Simulation::first_step() const {
  const double stable = system_->max_stable_dt();
  if (fixed_dt_ > 0) return {fixed_dt_, "run.dt"};
  return {stable, "physics (stable step)"};
}

double Simulation::choose_dt(bool& hits_output) const {
  double dt = fixed_dt_ > 0 ? fixed_dt_ : system_->max_stable_dt();
  if (fixed_dt_ > 0) dt = std::min(dt, system_->max_stable_dt());
  hits_output = false;
  const double to_output = clock_.next_output - clock_.t;
  // Land exactly on output times; stretch by up to 1e-9 rather than take a sliver step.
  if (to_output <= dt * (1 + 1e-9)) {
    dt = to_output;
    hits_output = true;
  }
  return dt;
}

void Simulation::write_output() {
  const std::string name = fmt::format("output_{:06d}.h5", clock_.output_index);
  auto file = io::Hdf5File::create(folder_ / name);
  auto& root = file.root();
  root.set_attribute("grainwave_kind", std::string("output"));
  root.set_attribute("version", std::string(GRAINWAVE_VERSION));
  root.set_attribute("scene", scene_.name());
  root.set_attribute("time", clock_.t);
  root.set_attribute("step", static_cast<std::int64_t>(clock_.step));
  const auto grids = system_->write_output(file, name);
  if (debug_kill_during_ == "output" && clock_.step == debug_kill_step_) std::raise(SIGKILL);
  file.commit();
  for (const auto& [series_name, grid] : grids) {
    auto it = std::find_if(series_.begin(), series_.end(), [&](const auto& s) {
      return s.path().filename() == series_name + ".xmf";
    });
    if (it == series_.end()) {
      series_.emplace_back(folder_ / (series_name + ".xmf"));
      it = series_.end() - 1;
    }
    it->add(clock_.t, grid);
    if (mpi::is_root()) it->write();
  }
  ++clock_.output_index;
  spdlog::debug("wrote {} (t = {})", (folder_ / name).string(), clock_.t);
}

void Simulation::write_checkpoint(const std::string& reason) {
  ScopedTimer timer(system_->timers(), "checkpoint");
  const fs::path path = folder_ / fmt::format("{}{:08d}.h5", kCheckpointPrefix, clock_.step);
  auto file = io::Hdf5File::create(path);
  auto& root = file.root();
  root.set_attribute("grainwave_kind", std::string("checkpoint"));
  root.set_attribute("version", std::string(GRAINWAVE_VERSION));
  root.set_attribute("scene", scene_.name());
  root.set_attribute("scene_sha256", scene_.sha256());
  root.write_text("scene_text", scene_.text());
  root.set_attribute("reason", reason);
  root.set_attribute("step", static_cast<std::int64_t>(clock_.step));
  root.set_attribute("time", clock_.t);
  root.set_attribute("output_index", static_cast<std::int64_t>(clock_.output_index));
  root.set_attribute("next_output", clock_.next_output);
  root.set_attribute("wall_s", clock_.wall_before + wall_);
  root.set_attribute("step_wall_s", clock_.step_wall_before + step_wall_);
  root.set_attribute("ranks", static_cast<std::int64_t>(mpi::size()));
  for (const auto& s : series_) root.write_text("series_" + s.path().stem().string(), s.serialise());
  {
    auto g = root.create_group("system");
    system_->write_checkpoint(g);
  }  // every object must be closed before the file is (commit checks this)
  if (debug_kill_during_ == "checkpoint" && clock_.step == debug_kill_step_) std::raise(SIGKILL);
  file.commit();
  if (std::find(checkpoints_.begin(), checkpoints_.end(), path) == checkpoints_.end())
    checkpoints_.push_back(path);
  prune_checkpoints();
  spdlog::info("checkpoint {} (step {}, t = {:.6g})", path.string(), clock_.step, clock_.t);
}

void Simulation::prune_checkpoints() {
  while (static_cast<long>(checkpoints_.size()) > checkpoints_kept_) {
    if (mpi::is_root()) {
      std::error_code ec;
      fs::remove(checkpoints_.front(), ec);
    }
    checkpoints_.erase(checkpoints_.begin());
  }
}

void Simulation::read_checkpoint(const fs::path& path) {
  auto file = io::Hdf5File::open_read(path);
  const auto& root = file.root();
  if (!root.has_attribute("grainwave_kind") ||
      root.text_attribute("grainwave_kind") != "checkpoint")
    throw InputError({path.string(), 0}, "--restart", "not a grainwave checkpoint");
  if (root.text_attribute("scene_sha256") != scene_.sha256())
    spdlog::warn("restarting from {} written by a different version of the scene file",
                 path.string());
  clock_.step = static_cast<long>(root.integer_attribute("step"));
  clock_.t = root.real_attribute("time");
  clock_.output_index = static_cast<long>(root.integer_attribute("output_index"));
  // Not the stored next_output: the restart may change output.interval or continue a finished
  // run to a later t_end (whose last output was at the old end).
  clock_.next_output = next_output_after(clock_.t);
  clock_.wall_before = root.real_attribute("wall_s");
  clock_.step_wall_before = root.real_attribute("step_wall_s");
  for (const auto& attr : {std::string("particles"), std::string("fields")}) {
    if (!root.has("series_" + attr)) continue;
    series_.emplace_back(folder_ / (attr + ".xmf"));
    series_.back().restore(root.read_text("series_" + attr));
  }
  system_->read_checkpoint(root.open_group("system"));
  checkpoints_.push_back(path);
}

void Simulation::write_summary(const std::string& status, const std::string& failure) {
  io::Json counts = io::Json::object(), metrics = io::Json::object();
  system_->report(counts, metrics, clock_.step_wall_before + step_wall_, clock_.step);
  io::Json timings = io::Json::object();
  for (const auto& [stage, seconds] : system_->timers().totals())
    timings.set(stage, mpi::max(seconds));
  if (!mpi::is_root()) return;
  io::Json summary = io::Json::object();
  summary.set("scene", scene_.name());
  summary.set("scene_file", scene_.file());
  summary.set("scene_sha256", scene_.sha256());
  summary.set("version", GRAINWAVE_VERSION);
  summary.set("status", status);
  if (!failure.empty()) summary.set("failure", failure);
  summary.set("ranks", mpi::size());
  summary.set("steps", clock_.step);
  summary.set("t_final", clock_.t);
  summary.set("wall_s", clock_.wall_before + wall_);
  if (restarted_from_) summary.set("restarted_from", restarted_from_->string());
  io::Json::Array list;
  for (const auto& o : scene_.overrides()) list.emplace_back(o);
  summary.set("overrides", io::Json(list));
  summary.set("counts", counts);
  summary.set("timings_s", timings);
  summary.set("metrics", metrics);
  io::write_text_atomically(folder_ / "summary.json", summary.dump() + "\n");
}

int Simulation::run() {
  // The output folder must be usable before anything is computed or written.
  std::string folder_error;
  if (mpi::is_root()) {
    try {
      io::ensure_writable_directory(folder_, "--out");
    } catch (const InputError& e) {
      folder_error = e.message();
    }
  }
  folder_error = mpi::broadcast(folder_error);
  if (!folder_error.empty()) throw InputError({"command line", 0}, "--out", folder_error);
  MPI_Barrier(MPI_COMM_WORLD);
  log::open_file(folder_ / "log.txt", restarted_from_.has_value());

  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);

  Stopwatch wall;
  spdlog::info("grainwave {} | scene {} ({}) | {} rank{}", GRAINWAVE_VERSION, scene_.name(),
               scene_.file(), mpi::size(), mpi::size() > 1 ? "s" : "");
  for (const auto& o : scene_.overrides()) spdlog::info("  --set {}", o);
  spdlog::info("  {}", system_->describe());
  spdlog::info("  output: {}", folder_.string());

  if (restarted_from_) {
    read_checkpoint(*restarted_from_);
    spdlog::info("  restarted from {} at step {}, t = {:.9g}", restarted_from_->string(),
                 clock_.step, clock_.t);
  } else {
    write_output();
  }

  ProgressReporter progress(clock_.t, t_end_, progress_interval_, true);
  std::string status = "completed", failure;
  bool just_wrote_output = true;
  const double t_tolerance = 1e-12 * std::max(1.0, std::abs(t_end_));
  while (t_end_ - clock_.t > t_tolerance && (max_steps_ == 0 || clock_.step < max_steps_)) {
    if (debug_kill_during_ == "step" && clock_.step == debug_kill_step_) std::raise(SIGKILL);
    bool hits_output = false;
    // Each part of a step is timed (summary.json's timings_s), so that they add up to the wall
    // time: the step choice (the stable dt, a reduction over the state), the copy kept for a
    // failure, the step itself (its modules' own timers) and the state check.
    double dt = 0;
    {
      ScopedTimer timer(system_->timers(), "step size");
      dt = choose_dt(hits_output);
    }
    {
      ScopedTimer timer(system_->timers(), "last good state");
      system_->save_good_state();  // also before a refused step: the failure path restores it
    }
    if (!(dt > 0) || !std::isfinite(dt)) {
      failure = fmt::format("time step {} is not positive and finite", dt);
    } else {
      Stopwatch step_clock;
      try {
        system_->advance(clock_.t, dt);
      } catch (const NumericalFailure& e) {  // a module that detects its own failure mid-step
        failure = e.what_failed() + (e.where().empty() ? "" : " at " + e.where());
      }
      step_wall_ += step_clock.seconds();
      if (failure.empty()) {
        ScopedTimer timer(system_->timers(), "state check");
        if (auto bad = system_->check_state()) failure = *bad;
      }
    }
    // All ranks agree on failure or an interrupt before anything is written.
    const int local_flags = (failure.empty() ? 0 : 1) | (g_stop_requested ? 2 : 0);
    int flags = 0;
    MPI_Allreduce(&local_flags, &flags, 1, MPI_INT, MPI_BOR, MPI_COMM_WORLD);
    if (flags & 1) {
      for (const auto& f : mpi::all_gather(failure))
        if (!f.empty()) {
          failure = f;
          break;
        }
      failure = NumericalFailure(failure, "step " + std::to_string(clock_.step + 1),
                                 clock_.t + dt, clock_.step + 1)
                    .what();
      progress.finish();
      spdlog::error("{}", failure);
      system_->restore_good_state();
      spdlog::error("writing the last good state (step {}, t = {:.9g})", clock_.step, clock_.t);
      write_output();
      write_checkpoint("last good state before a numerical failure");
      status = "failed";
      break;
    }
    ++clock_.step;
    clock_.t = hits_output ? clock_.next_output : clock_.t + dt;
    just_wrote_output = false;
    if (hits_output) {
      write_output();
      just_wrote_output = true;
      clock_.next_output = next_output_after(clock_.t);
    }
    wall_ = wall.seconds();
    if (checkpoint_every_ > 0 && clock_.step % checkpoint_every_ == 0)
      write_checkpoint("periodic");
    if (progress.due()) progress.update(clock_.step, clock_.t, dt, system_->progress_note());
    if (flags & 2) {
      progress.finish();
      spdlog::warn("interrupted: stopping after step {}", clock_.step);
      status = "interrupted";
      break;
    }
  }
  progress.finish();
  wall_ = wall.seconds();
  if (status != "failed") {
    if (!just_wrote_output) write_output();
    const bool have_this_step = !checkpoints_.empty() &&
        checkpoints_.back().filename() == fmt::format("{}{:08d}.h5", kCheckpointPrefix, clock_.step);
    if (!have_this_step) write_checkpoint(status == "completed" ? "end of run" : "interrupted");
  }
  wall_ = wall.seconds();
  write_summary(status, failure);
  const auto& timings = system_->timers().totals();
  spdlog::info("{} {} steps to t = {:.6g} in {} ({} output files)", status, clock_.step,
               clock_.t, ProgressReporter::format_duration(clock_.wall_before + wall_),
               clock_.output_index);
  for (const auto& [stage, seconds] : timings)
    spdlog::info("  {:<16} {:>10.3f} s", stage, seconds);
  spdlog::info("output in {}/ (open {}/{} in ParaView)", folder_.string(), folder_.string(),
               series_.empty() ? std::string("output_000000.h5")
                               : series_.front().path().filename().string());
  log::close_file();
  if (status == "failed") return kExitNumericalFailure;
  return status == "interrupted" ? 130 : 0;
}

}  // namespace grainwave::app
