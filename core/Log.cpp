#include "core/Log.hpp"

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include "core/Mpi.hpp"

namespace grainwave::log {

namespace {
std::filesystem::path g_file_path;
std::shared_ptr<spdlog::sinks::basic_file_sink_mt> g_file_sink;
}  // namespace

void init(Verbosity verbosity) {
  const int rank = mpi::rank();
  auto console = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  if (rank == 0) {
    console->set_pattern("%^%v%$");
    console->set_level(verbosity == Verbosity::kQuiet     ? spdlog::level::warn
                       : verbosity == Verbosity::kVerbose ? spdlog::level::debug
                                                          : spdlog::level::info);
  } else {
    console->set_pattern(fmt::format("[rank {}] %^%v%$", rank));
    console->set_level(spdlog::level::warn);
  }
  auto logger = std::make_shared<spdlog::logger>("grainwave", console);
  logger->set_level(spdlog::level::debug);
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
}

void open_file(const std::filesystem::path& path, bool append) {
  if (mpi::rank() != 0) return;
  g_file_path = path;
  std::filesystem::path partial = path;
  partial += ".partial";
  std::error_code ec;
  if (append && !std::filesystem::exists(partial) && std::filesystem::exists(path))
    std::filesystem::rename(path, partial, ec);
  g_file_sink = std::make_shared<spdlog::sinks::basic_file_sink_mt>(partial.string(), !append);
  g_file_sink->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
  g_file_sink->set_level(spdlog::level::debug);
  spdlog::default_logger()->sinks().push_back(g_file_sink);
}

void close_file() {
  if (!g_file_sink) return;
  g_file_sink->flush();
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), g_file_sink), sinks.end());
  g_file_sink.reset();
  std::filesystem::path partial = g_file_path;
  partial += ".partial";
  std::error_code ec;
  std::filesystem::rename(partial, g_file_path, ec);
}

}  // namespace grainwave::log
