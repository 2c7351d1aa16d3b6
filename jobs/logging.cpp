#include "jobs/logging.h"

#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>
#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "io/printable.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

/// `%*`: the message with control characters and invalid UTF-8 escaped (io::printable). Every log line
/// names files and items that come from outside (file names, archive and job-file names); a name holding
/// a newline or a terminal escape must not forge a log line or drive the terminal.
class EscapedMessage final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    const std::string text = io::printable(std::string_view(msg.payload.data(), msg.payload.size()));
    dest.append(text.data(), text.data() + text.size());
  }
  [[nodiscard]] std::unique_ptr<custom_flag_formatter> clone() const override {
    return std::make_unique<EscapedMessage>();
  }
};

/// `pattern` (spdlog syntax, `%*` for the escaped message) as a formatter.
std::unique_ptr<spdlog::formatter> escaping_formatter(const std::string& pattern) {
  auto formatter = std::make_unique<spdlog::pattern_formatter>();
  formatter->add_flag<EscapedMessage>('*').set_pattern(pattern);
  return formatter;
}

}  // namespace

void setup_logging(const std::string& level) {
  const auto lvl = spdlog::level::from_str(level == "warn" ? "warning" : level);
  if (lvl == spdlog::level::off && level != "off")
    throw InvalidInput(fmt::format("unknown log level '{}' (use trace, debug, info, warn, error or off)", level));
  auto logger = spdlog::stderr_logger_mt("gimforge");
  // On a terminal a line first clears the progress line (TerminalProgress) it would otherwise follow; the
  // progress is drawn again at its next update.
  logger->set_formatter(escaping_formatter(stderr_is_terminal() ? "\r\033[Kgimforge: %l: %*" : "gimforge: %l: %*"));
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
  sink->set_formatter(escaping_formatter(fmt::format("%Y-%m-%d %H:%M:%S.%e rank {} %l: %*", rank)));
  // The file gets debug lines (one per item) while the terminal keeps its level.
  const auto logger = spdlog::default_logger();
  for (const auto& existing : logger->sinks()) existing->set_level(logger->level());
  sink->set_level(std::min(logger->level(), spdlog::level::debug));
  logger->set_level(std::min(logger->level(), spdlog::level::debug));
  logger->sinks().push_back(std::move(sink));
}

namespace {
int g_stderr_terminal = -1;  ///< set_stderr_is_terminal's answer; -1: ask isatty
}  // namespace

bool stderr_is_terminal() { return g_stderr_terminal >= 0 ? g_stderr_terminal == 1 : isatty(STDERR_FILENO) == 1; }

void set_stderr_is_terminal(bool terminal) { g_stderr_terminal = terminal ? 1 : 0; }

}  // namespace gimforge::jobs
