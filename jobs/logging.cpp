#include "jobs/logging.h"

#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "kernels/errors.h"

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

bool stderr_is_terminal() { return isatty(STDERR_FILENO) == 1; }

}  // namespace gimforge::jobs
