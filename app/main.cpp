// The grainwave command line: run, check, info, reference.
//
// Exit codes: 0 success; 2 bad input (scene, command line, files), nothing written;
// 3 numerical failure (last good state written); 130 interrupted (checkpoint written);
// 1 unexpected internal error.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>

#include "app/Compose.hpp"
#include "app/Simulation.hpp"
#include "core/Error.hpp"
#include "core/Log.hpp"
#include "core/Mpi.hpp"
#include "io/Hdf5.hpp"
#include "io/Inspect.hpp"

namespace gw = grainwave;

namespace {

void print_on_root(const std::string& text) {
  if (gw::mpi::is_root()) std::cout << text << std::flush;
}

std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) {
    b /= 1024;
    ++u;
  }
  return fmt::format("{:.1f} {}", b, units[u]);
}

int check_scene(const gw::Scene& scene) {
  auto system = gw::app::compose_system(scene);
  gw::app::Simulation sim(scene, std::move(system), {});
  (void)sim;  // construction validates the time stepping; nothing runs
  auto again = gw::app::compose_system(scene);
  const auto [dt, source] = [&] {
    const auto& run = scene.section("run");
    const double fixed = run.real("dt");
    const double stable = again->max_stable_dt();
    if (fixed > 0) return std::pair{std::min(fixed, stable), std::string("run.dt")};
    return std::pair{stable, std::string("stable step of the physics")};
  }();
  const double t_end = scene.section("run").real("t_end");
  const double memory = gw::mpi::sum(static_cast<double>(again->memory_bytes()));
  std::string out;
  out += fmt::format("scene      {} ({})\n", scene.name(), scene.file());
  out += fmt::format("sha256     {}\n", scene.sha256());
  out += "builds\n";
  for (const auto& line : gw::app::modules_built(scene)) out += "  " + line + "\n";
  out += fmt::format("system     {}\n", again->describe());
  out += fmt::format("time step  {:.6g} from {} -> about {:.0f} steps to t_end = {}\n", dt, source,
                     std::ceil(t_end / dt), t_end);
  out += fmt::format("memory     {} of state on {} rank(s)\n", human_bytes(memory),
                     gw::mpi::size());
  out += "\nresolved parameters (defaults filled in):\n\n";
  out += scene.resolved_toml(gw::app::scene_schema());
  print_on_root(out);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  gw::mpi::Session mpi_session(&argc, &argv);
  gw::io::silence_hdf5_errors();

  CLI::App app{"grainwave: particle-resolved simulation of compressible gas-particle flows"};
  app.set_version_flag("--version", std::string("grainwave ") + GRAINWAVE_VERSION);
  app.require_subcommand(1);
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "print only warnings and errors");
  app.add_flag("-v,--verbose", verbose, "print debugging detail");

  std::string scene_path, out_dir, restart, h5_path;
  std::vector<std::string> overrides;
  auto add_scene_options = [&](CLI::App* sub) {
    sub->add_option("scene", scene_path, "scene file (TOML)")->required();
    sub->add_option("--set", overrides, "override a scene key: section.key=value (repeatable)")
        ->allow_extra_args(false);
  };
  app.fallthrough();  // -q/-v also after the verb: grainwave run scene.toml -q
  auto* run = app.add_subcommand("run", "run a scene");
  add_scene_options(run);
  run->add_option("--out", out_dir, "output folder (default: [output] folder or out/<scene>)");
  run->add_option("--restart", restart, "continue from a checkpoint file or a run's folder");
  auto* check = app.add_subcommand(
      "check", "validate a scene and print the resolved parameters, time step and memory; runs nothing");
  add_scene_options(check);
  auto* info = app.add_subcommand("info", "describe a grainwave HDF5 file (output, checkpoint, curtain state)");
  info->add_option("file", h5_path, "HDF5 file")->required();
  auto* reference = app.add_subcommand("reference", "print the scene file reference (Markdown)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    if (gw::mpi::is_root()) app.exit(e);
    return 0;
  } catch (const CLI::CallForAllHelp& e) {
    if (gw::mpi::is_root()) app.exit(e);
    return 0;
  } catch (const CLI::CallForVersion& e) {
    if (gw::mpi::is_root()) app.exit(e);
    return 0;
  } catch (const CLI::ParseError& e) {
    if (gw::mpi::is_root()) {
      app.exit(e);
    }
    return gw::kExitInputError;
  }

  gw::log::init(quiet ? gw::log::Verbosity::kQuiet
                      : verbose ? gw::log::Verbosity::kVerbose : gw::log::Verbosity::kNormal);
  try {
    if (*reference) {
      print_on_root(gw::app::scene_schema().reference_markdown());
      return 0;
    }
    if (*info) {
      print_on_root(gw::io::describe_hdf5_file(h5_path));
      return 0;
    }
    const auto scene = gw::Scene::load(scene_path, overrides, gw::app::scene_schema());
    if (*check) return check_scene(scene);
    gw::app::RunOptions options;
    options.output_folder = out_dir;
    if (!restart.empty()) options.restart = restart;
    gw::app::Simulation sim(scene, gw::app::compose_system(scene), options);
    return sim.run();
  } catch (const gw::InputError& e) {
    if (gw::mpi::is_root()) std::fprintf(stderr, "error: %s\n", e.what());
    return gw::kExitInputError;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "internal error [rank %d]: %s\n", gw::mpi::rank(), e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
    return 1;
  }
}
