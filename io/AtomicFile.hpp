#pragma once
// Every output file is written under a temporary name and renamed when complete, so a run killed
// at any instant never leaves a truncated file under a final name (rename is atomic on POSIX).
#include <filesystem>
#include <string>

namespace grainwave::io {

/// The temporary name a file is written under before it is renamed to `final_path`.
std::filesystem::path temporary_path(const std::filesystem::path& final_path);

/// Renames the temporary file onto `final_path` (replacing any older version).
void commit_temporary(const std::filesystem::path& final_path);

/// Writes `text` to `final_path` through a temporary file (flushed and synced before rename).
void write_text_atomically(const std::filesystem::path& final_path, const std::string& text);

/// Creates `dir` (and parents) and checks a file can be written there; throws InputError naming
/// `what` (e.g. "--out") if not.
void ensure_writable_directory(const std::filesystem::path& dir, const std::string& what);

}  // namespace grainwave::io
