#pragma once
// Logging for a run: rank 0 writes to the terminal (stderr) at the chosen verbosity and, once the
// output folder exists, to its log file at full detail. Other ranks log warnings and errors only,
// prefixed with their rank, so a failure on any rank is seen.
#include <spdlog/spdlog.h>

#include <filesystem>

namespace grainwave::log {

enum class Verbosity { kQuiet, kNormal, kVerbose };

/// Sets up the console logger (call once, after MPI is initialised).
void init(Verbosity verbosity);
/// Adds the run's log file (rank 0). Written as `<path>.partial` while the run goes and renamed
/// to `<path>` when the run ends, so an interrupted run's log is visibly incomplete. A restarted
/// run appends to the log it continues (`append`).
void open_file(const std::filesystem::path& path, bool append = false);
/// Flushes and renames the log file to its final name.
void close_file();

}  // namespace grainwave::log
