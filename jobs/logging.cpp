#include "jobs/logging.h"

#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "kernels/core/errors.h"

namespace gimforge::jobs {

void setup_logging(const std::string& level) {
  const auto lvl = spdlog::level::from_str(level == "warn" ? "warning" : level);
  if (lvl == spdlog::level::off && level != "off")
    throw InvalidInput(fmt::format("unknown log level '{}' (use trace, debug, info, warn, error or off)", level));
  auto logger = spdlog::stderr_logger_mt("gimforge");
  logger->set_pattern("gimforge: %l: %v");
  logger->set_level(lvl);
  logger->flush_on(spdlog::level::trace);
  spdlog::set_default_logger(logger);
}

void add_log_file(const std::string& path, int rank) {
  std::shared_ptr<spdlog::sinks::basic_file_sink_mt> sink;
  try {
    sink = std::make_shared<spdlog::sinks::basic_file_sink_mt>(path, false);
  } catch (const spdlog::spdlog_ex& e) {
    throw IoError(fmt::format("{}: cannot open the log file: {}", path, e.what()));
  }
  sink->set_pattern(fmt::format("%Y-%m-%d %H:%M:%S.%e rank {} %l: %v", rank));
  // The file gets debug lines (one per item) while the terminal keeps its level.
  const auto logger = spdlog::default_logger();
  for (const auto& existing : logger->sinks()) existing->set_level(logger->level());
  sink->set_level(std::min(logger->level(), spdlog::level::debug));
  logger->set_level(std::min(logger->level(), spdlog::level::debug));
  logger->sinks().push_back(std::move(sink));
}

bool stderr_is_terminal() { return isatty(STDERR_FILENO) == 1; }

}  // namespace gimforge::jobs
